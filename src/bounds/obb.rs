//! Oriented bounding boxes and a tight fit to a point set; the method is on [`fit_obb`].

use super::hull::{Hull3, SolidHull, convex_hull_2d, convex_hull_3d, min_area_rect};
use glam::{Affine3A, DMat3, DVec2, DVec3, Mat3, Vec3};

/// An oriented bounding box: a center, three orthonormal axes and the half extent along each.
///
/// Corner `i` (see [`corners`](Self::corners)) is `center + Σₖ ±half_extents[k] · axes.col(k)`,
/// with the `+` sign where bit `k` of `i` is set. The projected-area table
/// ([`silhouette`](crate::budget::silhouette)) uses the same numbering.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Obb {
    /// The box's center.
    pub center: Vec3,
    /// The box's axes as orthonormal columns (right-handed for boxes made by this module).
    pub axes: Mat3,
    /// Half the box's size along each axis. Never negative; zero for a flat box.
    pub half_extents: Vec3,
}

impl Obb {
    /// Creates a box from its parts. The axes must be orthonormal and the half extents
    /// non-negative; nothing is checked.
    #[inline]
    #[must_use]
    pub const fn new(center: Vec3, axes: Mat3, half_extents: Vec3) -> Self {
        Self {
            center,
            axes,
            half_extents,
        }
    }

    /// The axis-aligned box from `min` to `max`. A `min` above `max` on some axis is swapped
    /// rather than giving a negative extent.
    #[inline]
    #[must_use]
    pub fn from_aabb(min: Vec3, max: Vec3) -> Self {
        let (lo, hi) = (min.min(max), min.max(max));
        Self {
            center: (lo + hi) * 0.5,
            axes: Mat3::IDENTITY,
            half_extents: (hi - lo) * 0.5,
        }
    }

    /// The box's volume, `8 · hx · hy · hz`.
    #[inline]
    #[must_use]
    pub fn volume(&self) -> f32 {
        8.0 * self.half_extents.x * self.half_extents.y * self.half_extents.z
    }

    /// The box's projected area averaged over all view directions: a quarter of its
    /// surface (Cauchy's formula for convex bodies), `2 · (hx·hy + hy·hz + hz·hx)`.
    ///
    /// ```
    /// use bevy_aslod::bounds::Obb;
    /// use glam::Vec3;
    /// // A unit cube: surface 6, seen from anywhere 1.5 on average.
    /// let cube = Obb::from_aabb(Vec3::ZERO, Vec3::ONE);
    /// assert!((cube.mean_projected_area() - 1.5).abs() < 1e-6);
    /// ```
    #[inline]
    #[must_use]
    pub fn mean_projected_area(&self) -> f32 {
        let h = self.half_extents;
        2.0 * (h.x * h.y + h.y * h.z + h.z * h.x)
    }

    /// Corner `i` for `i` in `0..8`: bit `k` of `i` selects the `+` side of axis `k`.
    ///
    /// Indices above 7 use their low three bits.
    #[inline]
    #[must_use]
    pub fn corner(&self, i: usize) -> Vec3 {
        let sign = |bit: usize| if (i >> bit) & 1 == 1 { 1.0 } else { -1.0 };
        self.center
            + self.axes.x_axis * (sign(0) * self.half_extents.x)
            + self.axes.y_axis * (sign(1) * self.half_extents.y)
            + self.axes.z_axis * (sign(2) * self.half_extents.z)
    }

    /// The eight corners, numbered as in [`corner`](Self::corner).
    #[inline]
    #[must_use]
    pub fn corners(&self) -> [Vec3; 8] {
        std::array::from_fn(|i| self.corner(i))
    }

    /// Whether `point` lies in the box grown by `tolerance` on every side.
    #[inline]
    #[must_use]
    pub fn contains_point(&self, point: Vec3, tolerance: f32) -> bool {
        let local = self.axes.transpose() * (point - self.center);
        local.abs().cmple(self.half_extents + tolerance).all()
    }

    /// Whether every field is finite.
    #[inline]
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.center.is_finite() && self.axes.is_finite() && self.half_extents.is_finite()
    }

    /// The box after `transform`, e.g. a region's bind-pose box moved by its bone or an
    /// instance's `GlobalTransform`.
    ///
    /// Rotation, translation and uniform scale give the exact image. A non-uniform scale or
    /// shear turns the box into a parallelepiped; the result is then the box with the first
    /// transformed axis, the second made orthogonal to it (Gram–Schmidt), and half extents that
    /// just contain the parallelepiped, so it is conservative: it always contains the image. A
    /// scale along the box's own axes stays exact.
    #[must_use]
    pub fn transformed(&self, transform: &Affine3A) -> Self {
        let m = Mat3::from(transform.matrix3);
        let d = [
            m * self.axes.x_axis,
            m * self.axes.y_axis,
            m * self.axes.z_axis,
        ];
        let u0 = d[0]
            .try_normalize()
            .or_else(|| d[1].try_normalize())
            .or_else(|| d[2].try_normalize())
            .unwrap_or(Vec3::X);
        let u1 = [d[1], d[2], d[0]]
            .into_iter()
            .find_map(|v| (v - u0 * v.dot(u0)).try_normalize())
            .unwrap_or_else(|| u0.any_orthonormal_vector());
        let u2 = u0.cross(u1);
        let h = self.half_extents;
        let extent =
            |u: Vec3| h.x * u.dot(d[0]).abs() + h.y * u.dot(d[1]).abs() + h.z * u.dot(d[2]).abs();
        Self {
            center: transform.transform_point3(self.center),
            axes: Mat3::from_cols(u0, u1, u2),
            half_extents: Vec3::new(extent(u0), extent(u1), extent(u2)),
        }
    }
}

/// A tight oriented bounding box of `points`.
///
/// Returns `None` when `points` is empty or holds a non-finite coordinate. Coplanar points give
/// a flat box (zero half extent along the plane's normal, minimum-area rectangle in the plane);
/// collinear points a box of zero width and height; a single point a box of zero size.
///
/// # Method
///
/// PCA alone is not tight (and arbitrary for a cube). The minimum-volume box has two adjacent
/// faces that each contain an edge of the convex hull (O'Rourke 1985), and in practice it is
/// very often flush with a hull face (Chang, Gorissen & Melchior 2011 compare the methods), so
/// trying every hull face is the strong classic heuristic:
///
/// 1. the convex hull of the points (quickhull, in `f64`);
/// 2. for every distinct hull face normal `n`, the minimum-area rectangle (rotating calipers)
///    around the hull's silhouette along `n` gives the other two axes;
/// 3. the same around the PCA axes and the coordinate axes, so the result is never looser
///    than the PCA box or the AABB;
/// 4. the best box is polished by re-running the calipers around each of its own axes until
///    the volume stops shrinking.
///
/// A box (or anything with a face on its optimal box) comes back exactly. On the test meshes
/// (bunny, cow, fandisk, spot) the box is 3–17 % smaller than the AABB and 5–32 % smaller than
/// PCA's, and no larger than the best of 20,000 random orientations refined locally. The cost
/// is `O(F · (F + h log h))` for a hull of `F` faces and silhouettes of `h` vertices: a few
/// milliseconds for a region of a couple of thousand points, under a tenth of a second for a
/// whole 35k-vertex scan. It belongs in the offline bake; [`Obb::transformed`] is what runs
/// every frame.
///
/// See also [`fit_obb_pca`] (faster, looser) and [`fit_aabb`].
///
/// ```
/// use bevy_aslod::bounds::fit_obb;
/// use glam::{Quat, Vec3};
///
/// // The corners of a rotated 4 × 2 × 1 box come back as that box.
/// let rotation = Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.4);
/// let corners: Vec<Vec3> = (0..8)
///     .map(|i| {
///         let s = |b: usize| if (i >> b) & 1 == 1 { 1.0 } else { -1.0 };
///         rotation * Vec3::new(2.0 * s(0), 1.0 * s(1), 0.5 * s(2))
///     })
///     .collect();
/// let obb = fit_obb(&corners).expect("finite, non-empty input");
/// assert!((obb.volume() - 8.0).abs() < 1e-4);
/// ```
#[must_use]
pub fn fit_obb(points: &[Vec3]) -> Option<Obb> {
    let (origin, pts) = centered(points)?;
    let scale = pts.iter().fold(0.0f64, |m, p| m.max(p.abs().max_element()));
    let eps = scale * 1e-9;
    let pca = pca_axes(&pts);
    let axes = match convex_hull_3d(&pts, eps) {
        Hull3::Point => [DVec3::X, DVec3::Y, DVec3::Z],
        Hull3::Line { direction } => {
            let (u, v) = direction.any_orthonormal_pair();
            [direction, u, v]
        }
        Hull3::Flat { normal } => Fitter::new(&pts, &pts, None).flush(normal).1,
        Hull3::Solid(hull) => {
            let vertices: Vec<DVec3> = hull.vertices.iter().map(|&i| pts[i as usize]).collect();
            let normals = candidate_normals(hull.normals.clone());
            Fitter::new(&pts, &vertices, Some(&hull)).best(&pca, &normals)
        }
        Hull3::Failed => Fitter::new(&pts, &pts, None).best(&pca, &[]),
    };
    Some(finish(origin, &pts, axes))
}

/// The box along the principal axes of `points` (eigenvectors of their covariance), the classic
/// fast fit. Often 10–50 % larger than [`fit_obb`], and arbitrary for point sets with a
/// symmetric covariance (a cube's corners). `None` for empty or non-finite input.
///
/// See also [`fit_obb`], [`fit_aabb`].
#[must_use]
pub fn fit_obb_pca(points: &[Vec3]) -> Option<Obb> {
    let (origin, pts) = centered(points)?;
    Some(finish(origin, &pts, pca_axes(&pts)))
}

/// The axis-aligned box of `points`. `None` for empty or non-finite input.
///
/// See also [`fit_obb`], [`fit_obb_pca`].
#[must_use]
pub fn fit_aabb(points: &[Vec3]) -> Option<Obb> {
    let (first, rest) = points.split_first()?;
    let (lo, hi) = rest
        .iter()
        .fold((*first, *first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    (lo.is_finite() && hi.is_finite()).then(|| Obb::from_aabb(lo, hi))
}

/// The points in `f64`, moved so their bounding box is centred on the origin (better
/// conditioned), and the offset. `None` for empty or non-finite input.
fn centered(points: &[Vec3]) -> Option<(DVec3, Vec<DVec3>)> {
    let aabb = fit_aabb(points)?;
    let origin = aabb.center.as_dvec3();
    Some((
        origin,
        points.iter().map(|p| p.as_dvec3() - origin).collect(),
    ))
}

/// Canonical (sign-normalised), sorted and de-duplicated directions.
fn candidate_normals(mut normals: Vec<DVec3>) -> Vec<DVec3> {
    for n in &mut normals {
        let lead = if n.x != 0.0 {
            n.x
        } else if n.y != 0.0 {
            n.y
        } else {
            n.z
        };
        if lead < 0.0 {
            *n = -*n;
        }
    }
    normals.sort_unstable_by(|a, b| {
        a.x.total_cmp(&b.x)
            .then(a.y.total_cmp(&b.y))
            .then(a.z.total_cmp(&b.z))
    });
    normals.dedup_by(|a, b| a.distance_squared(*b) < 1e-18);
    normals
}

/// The candidate evaluation, with scratch space reused across directions.
struct Fitter<'a> {
    /// All points (the hull's faces index them).
    points: &'a [DVec3],
    /// The points that can touch the box: the hull's vertices, or all points.
    vertices: &'a [DVec3],
    /// The hull, whose silhouette along a direction is the outline of the projection: far
    /// fewer points than all vertices, and no sort over all of them.
    hull: Option<&'a SolidHull>,
    projected: Vec<DVec2>,
    outline: Vec<DVec2>,
    front: Vec<bool>,
    next: Vec<u32>,
    loop_vertices: Vec<u32>,
}

impl<'a> Fitter<'a> {
    fn new(points: &'a [DVec3], vertices: &'a [DVec3], hull: Option<&'a SolidHull>) -> Self {
        Self {
            points,
            vertices,
            hull,
            projected: Vec::new(),
            outline: Vec::new(),
            front: Vec::new(),
            next: Vec::new(),
            loop_vertices: Vec::new(),
        }
    }

    /// The smallest box with one axis along `n`: the calipers find the other two. Returns its
    /// volume and axes.
    fn flush(&mut self, n: DVec3) -> (f64, [DVec3; 3]) {
        let (u, v) = n.any_orthonormal_pair();
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &p in self.vertices {
            let h = n.dot(p);
            lo = lo.min(h);
            hi = hi.max(h);
        }
        self.projected.clear();
        let silhouette = self.hull.is_some_and(|hull| {
            hull.silhouette(n, &mut self.front, &mut self.next, &mut self.loop_vertices)
        });
        if silhouette {
            let points = self.points;
            self.projected.extend(self.loop_vertices.iter().map(|&i| {
                let p = points[i as usize];
                DVec2::new(u.dot(p), v.dot(p))
            }));
        } else {
            self.projected.extend(
                self.vertices
                    .iter()
                    .map(|&p| DVec2::new(u.dot(p), v.dot(p))),
            );
        }
        convex_hull_2d(&mut self.projected, &mut self.outline);
        let (_, d) = min_area_rect(&self.outline);
        let a0 = u * d.x + v * d.y;
        let a1 = n.cross(a0);
        // The volume measured on every vertex, not the outline's rectangle: a silhouette that
        // numerical noise made too small must not make a candidate look better than it is.
        let (mut lo0, mut hi0, mut lo1, mut hi1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &p in self.vertices {
            let (x, y) = (a0.dot(p), a1.dot(p));
            (lo0, hi0) = (lo0.min(x), hi0.max(x));
            (lo1, hi1) = (lo1.min(y), hi1.max(y));
        }
        ((hi0 - lo0) * (hi1 - lo1) * (hi - lo), [a0, a1, n])
    }

    /// The best of the hull-face, PCA and coordinate candidates, polished.
    fn best(&mut self, pca: &[DVec3; 3], normals: &[DVec3]) -> [DVec3; 3] {
        let mut best = (f64::INFINITY, [DVec3::X, DVec3::Y, DVec3::Z]);
        for &n in normals
            .iter()
            .chain(pca)
            .chain(&[DVec3::X, DVec3::Y, DVec3::Z])
        {
            let candidate = self.flush(n);
            if candidate.0 < best.0 {
                best = candidate;
            }
        }
        // Coordinate descent: each axis in turn stays, the calipers re-fit the other two.
        for _ in 0..8 {
            let mut improved = false;
            for k in 0..3 {
                let candidate = self.flush(best.1[k]);
                if candidate.0 < best.0 * (1.0 - 1e-9) {
                    best = candidate;
                    improved = true;
                }
            }
            if !improved {
                break;
            }
        }
        best.1
    }
}

/// The unit eigenvectors of the covariance of `pts` (columns), or the coordinate axes when it
/// cannot be computed.
fn pca_axes(pts: &[DVec3]) -> [DVec3; 3] {
    let n = pts.len() as f64;
    let mean = pts.iter().sum::<DVec3>() / n;
    let mut c = [[0.0f64; 3]; 3];
    for &p in pts {
        let d = p - mean;
        for (i, row) in c.iter_mut().enumerate() {
            for (j, value) in row.iter_mut().enumerate() {
                *value += d[i] * d[j];
            }
        }
    }
    let covariance = DMat3::from_cols_array_2d(&c) * (1.0 / n);
    let v = symmetric_eigenvectors(covariance);
    let axes = [v.x_axis, v.y_axis, v.z_axis];
    if axes.iter().all(|a| a.is_finite()) {
        axes
    } else {
        [DVec3::X, DVec3::Y, DVec3::Z]
    }
}

/// Eigenvectors (as columns) of a symmetric 3×3 matrix by cyclic Jacobi rotations.
fn symmetric_eigenvectors(mut a: DMat3) -> DMat3 {
    let mut v = DMat3::IDENTITY;
    for _sweep in 0..64 {
        let off = a.y_axis.x.powi(2) + a.z_axis.x.powi(2) + a.z_axis.y.powi(2);
        let diag = a.x_axis.x.powi(2) + a.y_axis.y.powi(2) + a.z_axis.z.powi(2);
        if off <= 1e-30 * diag || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            let apq = a.col(q)[p];
            if apq == 0.0 {
                continue;
            }
            let theta = (a.col(q)[q] - a.col(p)[p]) / (2.0 * apq);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // Rotation in the (p, q) plane: R[p][p] = R[q][q] = c, R[p][q] = s, R[q][p] = -s.
            let mut r = DMat3::IDENTITY;
            r.col_mut(p)[p] = c;
            r.col_mut(q)[q] = c;
            r.col_mut(q)[p] = s;
            r.col_mut(p)[q] = -s;
            a = r.transpose() * a * r;
            v *= r;
        }
    }
    v
}

/// The box with (nearly) orthonormal `axes` around `pts`, back in `f32` and world space. The
/// extents are measured along the `f32` axes and rounded outwards, so the box contains every
/// point.
fn finish(origin: DVec3, pts: &[DVec3], axes: [DVec3; 3]) -> Obb {
    // Orthonormalise and make right-handed before rounding to f32.
    let a0 = axes[0].normalize();
    let a1 = (axes[1] - a0 * axes[1].dot(a0)).normalize();
    let a2 = a0.cross(a1);
    let axes32 = Mat3::from_cols(a0.as_vec3(), a1.as_vec3(), a2.as_vec3());
    let a = [
        axes32.x_axis.as_dvec3(),
        axes32.y_axis.as_dvec3(),
        axes32.z_axis.as_dvec3(),
    ];
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for &p in pts {
        let q = DVec3::new(a[0].dot(p), a[1].dot(p), a[2].dot(p));
        lo = lo.min(q);
        hi = hi.max(q);
    }
    let mid = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let center64 = origin + a[0] * mid.x + a[1] * mid.y + a[2] * mid.z;
    let center = center64.as_vec3();
    let shift = center.as_dvec3() - center64;
    let grow = |k: usize, h: f64| {
        let h = h + a[k].dot(shift).abs();
        if h == 0.0 { 0.0 } else { (h as f32).next_up() }
    };
    Obb {
        center,
        axes: axes32,
        half_extents: Vec3::new(grow(0, half.x), grow(1, half.y), grow(2, half.z)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3A};

    #[test]
    fn jacobi_recovers_a_rotated_diagonal() {
        let r = DMat3::from_quat(glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.4, -1.2, 2.0));
        let m = r * DMat3::from_diagonal(DVec3::new(5.0, 2.0, 0.5)) * r.transpose();
        let v = symmetric_eigenvectors(m);
        let d = v.transpose() * m * v;
        for (i, j) in [(0, 1), (0, 2), (1, 2)] {
            assert!(d.col(j)[i].abs() < 1e-12, "off-diagonal {i}{j}: {d}");
        }
        let mut eig = [d.x_axis.x, d.y_axis.y, d.z_axis.z];
        eig.sort_by(f64::total_cmp);
        assert!((eig[0] - 0.5).abs() < 1e-12 && (eig[2] - 5.0).abs() < 1e-12);
    }

    #[test]
    fn transformed_by_rotation_and_uniform_scale_is_exact() {
        let obb = Obb::new(
            Vec3::new(1.0, 2.0, 3.0),
            Mat3::from_quat(Quat::from_rotation_y(0.7)),
            Vec3::new(1.0, 0.5, 0.25),
        );
        let t = Affine3A::from_scale_rotation_translation(
            Vec3::splat(2.0),
            Quat::from_rotation_x(-0.3),
            Vec3::new(5.0, 0.0, -1.0),
        );
        let moved = obb.transformed(&t);
        assert!((moved.volume() - obb.volume() * 8.0).abs() < 1e-4);
        for c in obb.corners() {
            assert!(moved.contains_point(t.transform_point3(c), 1e-4));
        }
    }

    #[test]
    fn transformed_by_shear_is_conservative() {
        let obb = Obb::new(
            Vec3::ZERO,
            Mat3::from_quat(Quat::from_rotation_z(0.3)),
            Vec3::new(1.0, 2.0, 0.0),
        );
        let t = Affine3A {
            matrix3: glam::Mat3A::from_cols(
                Vec3A::new(1.0, 0.5, 0.0),
                Vec3A::new(0.0, 3.0, 0.2),
                Vec3A::new(0.1, 0.0, 0.5),
            ),
            translation: Vec3A::new(0.0, 1.0, 0.0),
        };
        let moved = obb.transformed(&t);
        assert!((moved.axes.determinant() - 1.0).abs() < 1e-5);
        for c in obb.corners() {
            assert!(moved.contains_point(t.transform_point3(c), 1e-4));
        }
        // A singular transform still gives a finite box.
        let flat = obb.transformed(&Affine3A::from_scale(Vec3::new(0.0, 1.0, 1.0)));
        assert!(flat.is_finite());
    }
}
