//! Linear blend skinning of the vertices a polygon cache refers to (sections 5.3 and 5.4).

use super::{Influences, MAX_INFLUENCES};
use glam::{Mat3, Mat4, Vec3, Vec3A, Vec4};

/// The blended affine skinning matrix of one vertex, as four columns.
///
/// `rigid` takes the first (dominant) joint alone with weight 1, and so does a vertex with a
/// single influence (whose weight is exactly 1 after [`Influences`] normalised it).
/// Otherwise the matrices are summed weight by weight, stopping at the first weight that is
/// not positive (weights are sorted largest first). Joints without a matrix are skipped.
/// Every placement in this module goes through this one function, so a vertex gets
/// bit-for-bit the same result whichever entry point places it.
// `!(w > 0.0)` on purpose: one comparison that is also true for NaN.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn skin_matrix(
    matrices: &[Mat4],
    joints: [u16; MAX_INFLUENCES],
    weights: [f32; MAX_INFLUENCES],
    rigid: bool,
) -> [Vec4; 4] {
    let matrix = |k: usize| {
        let m = matrices.get(usize::from(joints[k]));
        debug_assert!(m.is_some(), "joint {} has no matrix", joints[k]);
        m
    };
    if rigid || !(weights[1] > 0.0) {
        return match matrix(0) {
            Some(m) => [m.x_axis, m.y_axis, m.z_axis, m.w_axis],
            None => [Vec4::ZERO; 4],
        };
    }
    // Two influences or more, unrolled: most skinned vertices have two. A joint without a
    // matrix is skipped, as in `accumulate`.
    let (w0, w1) = (weights[0], weights[1]);
    let mut c = match (matrix(0), matrix(1)) {
        (Some(a), Some(b)) => [
            a.x_axis * w0 + b.x_axis * w1,
            a.y_axis * w0 + b.y_axis * w1,
            a.z_axis * w0 + b.z_axis * w1,
            a.w_axis * w0 + b.w_axis * w1,
        ],
        (a, b) => {
            let mut c = [Vec4::ZERO; 4];
            accumulate(&mut c, a, w0);
            accumulate(&mut c, b, w1);
            c
        }
    };
    // A third and a fourth influence, when the vertex has them (weights sorted largest
    // first, so a zero ends the list).
    if weights[2] > 0.0 {
        accumulate(&mut c, matrix(2), weights[2]);
        if weights[3] > 0.0 {
            accumulate(&mut c, matrix(3), weights[3]);
        }
    }
    c
}

/// `c += w m`, for a joint that has a matrix.
#[inline(always)]
fn accumulate(c: &mut [Vec4; 4], m: Option<&Mat4>, w: f32) {
    if let Some(m) = m {
        c[0] += m.x_axis * w;
        c[1] += m.y_axis * w;
        c[2] += m.z_axis * w;
        c[3] += m.w_axis * w;
    }
}

#[inline(always)]
fn apply_point(c: &[Vec4; 4], p: Vec3) -> Vec3 {
    (c[0] * p.x + c[1] * p.y + c[2] * p.z + c[3]).truncate()
}

/// The blended upper 3x3 applied to a direction in the surface (a tangent), not normalised.
#[inline(always)]
fn apply_linear(c: &[Vec4; 4], v: Vec3) -> Vec3 {
    (c[0] * v.x + c[1] * v.y + c[2] * v.z).truncate()
}

/// The inverse transpose of the blended upper 3x3 applied to a normal, as Bevy's skinning
/// shader turns normals (`skin_normals`), up to a positive factor: its cofactor matrix
/// (three cross products, no division), sign-corrected for a mirroring matrix. Not
/// normalised (see [`blend`]). A singular matrix turns the normal by itself.
#[inline(always)]
fn apply_normal(c: &[Vec4; 4], n: Vec3) -> Vec3 {
    // Vec3A: the cross products run on SIMD lanes.
    let (x, y, z) = (
        Vec3A::from_vec4(c[0]),
        Vec3A::from_vec4(c[1]),
        Vec3A::from_vec4(c[2]),
    );
    let (cx, cy, cz) = (y.cross(z), z.cross(x), x.cross(y));
    let det = z.dot(cz);
    let turned = cx * n.x + cy * n.y + cz * n.z;
    Vec3::from(if det > 0.0 {
        turned
    } else if det < 0.0 {
        -turned
    } else {
        x * n.x + y * n.y + z * n.z
    })
}

/// The matrix that turns normals as `linear` turns points, up to a positive factor: the
/// matrix of [`apply_normal`] (its cofactor matrix, sign-corrected for a mirroring matrix; a
/// singular `linear`, a joint scaled to zero, gives `linear` itself, so normals stay finite).
#[must_use]
#[cfg_attr(not(feature = "bevy"), allow(dead_code))]
pub(crate) fn normal_matrix(linear: Mat3) -> Mat3 {
    // `apply_normal` on the basis vectors: its columns.
    let c = [
        linear.x_axis.extend(0.0),
        linear.y_axis.extend(0.0),
        linear.z_axis.extend(0.0),
        Vec4::W,
    ];
    Mat3::from_cols(
        apply_normal(&c, Vec3::X),
        apply_normal(&c, Vec3::Y),
        apply_normal(&c, Vec3::Z),
    )
}

/// Places one vertex the way [`blend_with_rigid`] does: a rigid vertex by its dominant
/// (first) joint alone, any other by full linear blend skinning,
/// `Σ w_k M_{j_k} p` over its non-zero weights.
///
/// `joints`/`weights` follow [`Influences`]' invariants (sorted largest first). A joint without
/// a matrix is skipped (and asserts in debug builds).
///
/// See also [`skin_normal`], [`blend`].
#[inline]
#[must_use]
pub fn skin_position(
    matrices: &[Mat4],
    position: Vec3,
    joints: [u16; MAX_INFLUENCES],
    weights: [f32; MAX_INFLUENCES],
    rigid: bool,
) -> Vec3 {
    apply_point(&skin_matrix(matrices, joints, weights, rigid), position)
}

/// Turns one normal the way [`blend_with_rigid`] does: the inverse transpose of the blended
/// matrix's upper 3x3 (up to a positive factor) applied to the normal, as Bevy's skinning
/// shader does, **not normalised** (see [`blend`] for why); call [`Vec3::normalize_or`] on it
/// when a unit vector is needed.
///
/// See also [`skin_position`], [`skin_tangent`].
#[inline]
#[must_use]
pub fn skin_normal(
    matrices: &[Mat4],
    normal: Vec3,
    joints: [u16; MAX_INFLUENCES],
    weights: [f32; MAX_INFLUENCES],
    rigid: bool,
) -> Vec3 {
    apply_normal(&skin_matrix(matrices, joints, weights, rigid), normal)
}

/// Turns one tangent (or any direction in the surface): the blended matrix's upper 3x3 itself
/// applied to it, as Bevy's shader turns tangents (`mesh_tangent_local_to_world`), **not
/// normalised**. With [`skin_normal`] it stays perpendicular to the normal.
#[inline]
#[must_use]
pub fn skin_tangent(
    matrices: &[Mat4],
    tangent: Vec3,
    joints: [u16; MAX_INFLUENCES],
    weights: [f32; MAX_INFLUENCES],
    rigid: bool,
) -> Vec3 {
    apply_linear(&skin_matrix(matrices, joints, weights, rigid), tangent)
}

/// Linear blend skinning of the listed vertices only (sections 5.3 and 5.4: a region's cache
/// deforms only the vertices its current level refers to).
///
/// `matrices[j]` is the skinning matrix of joint `j` (the joint's global transform times its
/// inverse bind matrix, in whatever space the caller wants the output). For each `i` in
/// `vertices`:
/// - `out_positions[i] = Σ_k w_k M_{j_k} positions[i]`, which is the blended matrix
///   `Σ_k w_k M_{j_k}` applied to the point (one matrix product per vertex, however many
///   influences);
/// - `out_normals[i]` = the inverse transpose of the blended matrix's upper 3x3 (its cofactor
///   matrix: the same direction, three cross products and no division) applied to
///   `normals[i]`, as Bevy's skinning shader turns normals, so a model skinned here shades
///   like the same model skinned by Bevy. It is **not normalised**: its length carries no
///   meaning. Renormalise before shading, as
///   every renderer of skinned normals does anyway: Bevy's vertex shader normalises each
///   normal (`mesh_normal_local_to_world`), so normalising here would pay for it twice,
///   and it is about half the cost of a one-influence vertex.
///
/// Every other entry of the outputs is left untouched, so a caller keeps one full-size
/// buffer per model and refreshes only what the cache draws. Normals are written only when
/// both `normals` and `out_normals` are given.
///
/// The weights must be sorted largest first ([`Influences`]' invariant): the sum stops at the
/// first zero weight. No allocation. Out-of-range vertex indices (in `positions`,
/// `influences` or an output) and joints without a matrix are skipped, and assert in debug
/// builds; they never panic in release builds.
///
/// See also [`blend_with_rigid`], which places rigid vertices by one bone.
pub fn blend(
    matrices: &[Mat4],
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    influences: &Influences,
    vertices: &[u32],
    out_positions: &mut [Vec3],
    out_normals: Option<&mut [Vec3]>,
) {
    blend_impl(
        matrices,
        positions,
        normals,
        influences,
        None,
        vertices,
        out_positions,
        out_normals,
        None,
    );
}

/// [`blend`], with rigid vertices placed by their dominant (first) influence alone, with
/// weight 1.
///
/// `rigid[i]` is true for a vertex of a rigid region
/// ([`SkinDecomposition::rigid`](super::SkinDecomposition::rigid)); a vertex past the end of
/// `rigid` is not rigid. A rigid vertex on a region border is drawn by several regions'
/// caches; this way each of them places it bit-for-bit the same, and
/// [`skin_position`] agrees with all of them.
#[allow(clippy::too_many_arguments)]
pub fn blend_with_rigid(
    matrices: &[Mat4],
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    influences: &Influences,
    rigid: &[bool],
    vertices: &[u32],
    out_positions: &mut [Vec3],
    out_normals: Option<&mut [Vec3]>,
) {
    blend_impl(
        matrices,
        positions,
        normals,
        influences,
        Some(rigid),
        vertices,
        out_positions,
        out_normals,
        None,
    );
}

/// [`blend`] that also turns tangents (`xyz` by the blended matrix, as [`skin_tangent`];
/// `w`, the handedness, kept) from `tangents` into `out_tangents`, from the same blended
/// matrix as the vertex's position and normal. Tangents are written only where normals are
/// (both normal arrays given) and both tangent arrays hold the vertex.
#[allow(clippy::too_many_arguments)]
pub fn blend_with_tangents(
    matrices: &[Mat4],
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    tangents: &[Vec4],
    influences: &Influences,
    vertices: &[u32],
    out_positions: &mut [Vec3],
    out_normals: Option<&mut [Vec3]>,
    out_tangents: &mut [[f32; 4]],
) {
    blend_impl(
        matrices,
        positions,
        normals,
        influences,
        None,
        vertices,
        out_positions,
        out_normals,
        Some((tangents, out_tangents)),
    );
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn blend_impl(
    matrices: &[Mat4],
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    influences: &Influences,
    rigid: Option<&[bool]>,
    vertices: &[u32],
    out_positions: &mut [Vec3],
    out_normals: Option<&mut [Vec3]>,
    mut tangents: Option<(&[Vec4], &mut [[f32; 4]])>,
) {
    // Every array cut to one common length `n`: one `i < n` test per vertex then covers
    // every access (the optimiser drops the others).
    let n = positions
        .len()
        .min(influences.joints.len())
        .min(influences.weights.len())
        .min(out_positions.len());
    // Normals only when both arrays cover every vertex the positions do; otherwise the
    // positions are still written and the normals left alone.
    let out_normals = match (normals, out_normals) {
        (Some(normals), Some(out)) if normals.len() >= n && out.len() >= n => {
            Some((&normals[..n], &mut out[..n]))
        }
        (Some(_), Some(_)) => {
            debug_assert!(false, "normal arrays shorter than the positions");
            None
        }
        _ => None,
    };
    let positions = &positions[..n];
    let joints = &influences.joints[..n];
    let weights = &influences.weights[..n];
    let out_positions = &mut out_positions[..n];
    let is_rigid = |i: usize| rigid.is_some_and(|r| r.get(i).copied().unwrap_or(false));
    match out_normals {
        Some((normals, out_normals)) => {
            for &i in vertices {
                let i = i as usize;
                if i >= n {
                    debug_assert!(false, "vertex {i} is out of range");
                    continue;
                }
                let c = skin_matrix(matrices, joints[i], weights[i], is_rigid(i));
                out_positions[i] = apply_point(&c, positions[i]);
                out_normals[i] = apply_normal(&c, normals[i]);
                if let Some((from, to)) = &mut tangents
                    && let (Some(t), Some(out)) = (from.get(i), to.get_mut(i))
                {
                    let xyz = apply_linear(&c, t.truncate());
                    *out = [xyz.x, xyz.y, xyz.z, t.w];
                }
            }
        }
        None => {
            for &i in vertices {
                let i = i as usize;
                if i >= n {
                    debug_assert!(false, "vertex {i} is out of range");
                    continue;
                }
                let c = skin_matrix(matrices, joints[i], weights[i], is_rigid(i));
                out_positions[i] = apply_point(&c, positions[i]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_matrix_is_the_inverse_transpose_up_to_scale_and_finite_when_singular() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        for linear in [
            Mat3::from_diagonal(Vec3::new(2.0, 0.5, 3.0)),
            Mat3::from_diagonal(Vec3::new(-1.0, 2.0, 1.0)),
            Mat3::from_cols(Vec3::X, Vec3::new(0.4, 1.0, 0.0), Vec3::new(0.0, 0.3, 2.0)),
        ] {
            let expected = (linear.inverse().transpose() * n).normalize();
            let got = (normal_matrix(linear) * n).normalize();
            assert!(
                got.abs_diff_eq(expected, 1e-5),
                "{linear:?}: {got} vs {expected}"
            );
        }
        // A joint scaled to zero, or flat: the inverse is NaN, this stays finite.
        for singular in [Mat3::ZERO, Mat3::from_diagonal(Vec3::new(1.0, 1.0, 0.0))] {
            assert!(!(singular.inverse().transpose() * n).is_finite());
            assert!((normal_matrix(singular) * n).is_finite());
        }
    }
}
