//! Surface sampling: stratified area samples, vertex and edge-midpoint samples, in Morton order.

use super::{DistanceOptions, MeshRef, valid_triangles};
use glam::Vec3A;

/// Sample points of one mesh, each list in a spatially coherent order.
pub(super) struct Samples {
    /// The valid triangles `(triangle index, corners)`.
    pub(super) tris: Vec<(u32, [u32; 3])>,
    /// Area samples: they define the RMS.
    pub(super) area: Vec<Vec3A>,
    /// Entry of `tris` each area sample lies on.
    pub(super) area_tri: Vec<u32>,
    /// Vertex and edge-midpoint samples: they only count towards the maximum.
    pub(super) extra: Vec<Vec3A>,
    /// Entry of `tris` each extra sample lies on (one of them, for a shared vertex).
    pub(super) extra_tri: Vec<u32>,
}

pub(super) fn sample_surface(mesh: MeshRef, opts: &DistanceOptions) -> Samples {
    let tris = valid_triangles(mesh);
    let pos = |i: u32| Vec3A::from(mesh.positions[i as usize]);
    let corners = |t: &[u32; 3]| [pos(t[0]), pos(t[1]), pos(t[2])];

    // Systematic allocation of the area samples, in index-buffer order (so it depends only on the
    // mesh and the seed).
    let areas: Vec<f64> = tris
        .iter()
        .map(|(_, t)| {
            let [a, b, c] = corners(t);
            let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
            0.5 * (b - a).cross(c - a).length()
        })
        .collect();
    let total: f64 = areas.iter().sum();
    let mut counts = vec![0u32; tris.len()];
    let mut n_area = 0usize;
    if opts.samples > 0 && total.is_finite() && total > 0.0 {
        let scale = opts.samples as f64 / total;
        let offset = SplitMix64::new(opts.seed ^ 0x5851_F42D_4C95_7F2D).next_f64();
        let mut cumulative = 0.0f64;
        let mut previous = offset.floor();
        for (count, &area) in counts.iter_mut().zip(&areas) {
            cumulative += area;
            let next = (cumulative * scale + offset).floor();
            let k = (next - previous).max(0.0);
            previous = next;
            *count = k.min(u32::MAX as f64) as u32;
            n_area += *count as usize;
        }
    }

    // Visit triangles in Morton order of their centroids so that consecutive samples are close,
    // which lets each closest-point query start from its predecessor's answer.
    let order = morton_order(&tris, |(_, t)| {
        let [a, b, c] = corners(t);
        (a + b + c) * (1.0 / 3.0)
    });

    let mut area = Vec::with_capacity(n_area);
    let mut area_tri = Vec::with_capacity(n_area);
    let mut extra = Vec::new();
    let mut extra_tri = Vec::new();
    let vertex_count = if opts.include_vertices {
        mesh.positions.len()
    } else {
        0
    };
    let mut seen = vec![false; vertex_count];
    for &k in &order {
        let (t, ref idx) = tris[k as usize];
        let [a, b, c] = corners(idx);
        let count = counts[k as usize];
        if count > 0 {
            let (ab, ac) = (b - a, c - a);
            let mut rng = triangle_rng(opts.seed, t as usize);
            for _ in 0..count {
                let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                area.push(a + ab * u + ac * v);
                area_tri.push(k);
            }
        }
        if opts.include_vertices {
            for (&i, p) in idx.iter().zip([a, b, c]) {
                if !std::mem::replace(&mut seen[i as usize], true) {
                    extra.push(p);
                    extra_tri.push(k);
                }
            }
        }
        if opts.include_edge_midpoints {
            extra.extend([(a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5]);
            extra_tri.extend([k; 3]);
        }
    }
    Samples {
        tris,
        area,
        area_tri,
        extra,
        extra_tri,
    }
}

/// splitmix64 (Steele, Lea & Flood 2014): tiny, fast, and good enough for sample placement.
#[derive(Clone, Copy, Debug)]
pub(super) struct SplitMix64(u64);

impl SplitMix64 {
    pub(super) fn new(seed: u64) -> Self {
        Self(seed)
    }

    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` with 24 bits of resolution.
    fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in `[0, 1)` with 53 bits of resolution.
    fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Indices `0..items.len()` sorted by the 30-bit Morton code of `key(item)`, ties by index.
fn morton_order<T>(items: &[T], key: impl Fn(&T) -> Vec3A) -> Vec<u32> {
    let keys: Vec<Vec3A> = items.iter().map(key).collect();
    let (lo, hi) = keys.iter().fold(
        (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let extent = hi - lo;
    let scale = Vec3A::select(
        extent.cmpgt(Vec3A::ZERO),
        Vec3A::splat(1023.0) / extent,
        Vec3A::ZERO,
    );
    let mut coded: Vec<(u32, u32)> = keys
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            // `as u32` saturates (and maps NaN to 0), so this cannot overflow the 10 bits.
            let q = ((p - lo) * scale).min(Vec3A::splat(1023.0));
            let code = spread_bits(q.x as u32)
                | (spread_bits(q.y as u32) << 1)
                | (spread_bits(q.z as u32) << 2);
            (code, i as u32)
        })
        .collect();
    coded.sort_unstable();
    coded.into_iter().map(|(_, i)| i).collect()
}

/// Spreads the low 10 bits of `v` to every third bit.
fn spread_bits(v: u32) -> u32 {
    let mut x = v & 0x3FF;
    x = (x | (x << 16)) & 0x0300_00FF;
    x = (x | (x << 8)) & 0x0300_F00F;
    x = (x | (x << 4)) & 0x030C_30C3;
    x = (x | (x << 2)) & 0x0924_9249;
    x
}

/// The stream of triangle `tri` under `seed`: independent of the order triangles are visited in.
fn triangle_rng(seed: u64, tri: usize) -> SplitMix64 {
    let mut mix = SplitMix64::new(seed ^ (tri as u64).wrapping_mul(0xD1B5_4A32_D192_ED03));
    SplitMix64::new(mix.next_u64())
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use glam::Vec3;

    /// A random vector in `[-scale, scale)³`; the kernel's and the BVH's tests use it too.
    pub(in crate::distance) fn random_vec(rng: &mut SplitMix64, scale: f32) -> Vec3 {
        Vec3::new(
            rng.next_f32() * 2.0 - 1.0,
            rng.next_f32() * 2.0 - 1.0,
            rng.next_f32() * 2.0 - 1.0,
        ) * scale
    }

    #[test]
    fn systematic_allocation_is_exact() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(3.0, 0.0, 0.0)];
        let indices = [0, 1, 2, 1, 3, 2, 0, 0, 1];
        for samples in [0, 1, 7, 1000] {
            let opts = DistanceOptions {
                samples,
                seed: 3,
                ..DistanceOptions::default()
            };
            let s = sample_surface(MeshRef::new(&positions, &indices), &opts);
            assert_eq!(s.area.len(), samples);
            assert_eq!(s.extra.len(), 4);
        }
    }
}
