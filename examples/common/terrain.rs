//! The Silvretta example's terrain (ASLOD Figure 8): a ridged multifractal (Musgrave) over
//! seeded value noise, the same on every run. Without Bevy, so the `coarse_fine` bench shares it.
#![allow(dead_code)]

use bevy_aslod::mesh::IndexedMesh;
use glam::Vec3;

/// Vertices along each side of the terrain: 260² quads, 135,200 triangles.
pub const SIDE: u32 = 261;
/// World units between neighbouring vertices.
pub const SPACING: f32 = 1.0;
/// Peak height of the ridges.
pub const HEIGHT: f32 = 45.0;
/// The noise seed: the same terrain on every run.
const SEED: u32 = 0x5117_2e77;

fn hash(x: i32, z: i32, seed: u32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x27d4_eb2d) ^ (z as u32).wrapping_mul(0x1656_67b1) ^ seed;
    h ^= h >> 15;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^= h >> 16;
    h as f32 / u32::MAX as f32
}

fn value_noise(x: f32, z: f32, seed: u32) -> f32 {
    let (x0, z0) = (x.floor(), z.floor());
    let (fx, fz) = (x - x0, z - z0);
    let (sx, sz) = (fx * fx * (3.0 - 2.0 * fx), fz * fz * (3.0 - 2.0 * fz));
    let (ix, iz) = (x0 as i32, z0 as i32);
    let a = hash(ix, iz, seed) + (hash(ix + 1, iz, seed) - hash(ix, iz, seed)) * sx;
    let b = hash(ix, iz + 1, seed) + (hash(ix + 1, iz + 1, seed) - hash(ix, iz + 1, seed)) * sx;
    a + (b - a) * sz
}

fn ridged(x: f32, z: f32) -> f32 {
    let (mut sum, mut freq, mut amp, mut weight) = (0.0, 1.0, 0.6, 1.0);
    for octave in 0..7 {
        let n = value_noise(x * freq, z * freq, SEED.wrapping_add(octave * 7919));
        let signal = (1.0 - (n * 2.0 - 1.0).abs()).powi(2) * weight;
        weight = (signal * 2.0).clamp(0.0, 1.0);
        sum += signal * amp;
        freq *= 2.03;
        amp *= 0.5;
    }
    sum
}

/// The terrain's height at `(x, z)`.
pub fn height(x: f32, z: f32) -> f32 {
    HEIGHT * ridged(x / 70.0 + 3.7, z / 70.0 + 1.3)
}

/// The terrain: `SIDE`² vertices centred on the origin, with normals.
pub fn terrain() -> IndexedMesh {
    terrain_middle(SIDE)
}

/// The terrain's middle `side`² vertices (all of it for [`SIDE`]), with normals.
pub fn terrain_middle(side: u32) -> IndexedMesh {
    let half = (side - 1) as f32 * SPACING * 0.5;
    let at = |i: u32, j: u32| {
        let (x, z) = (i as f32 * SPACING - half, j as f32 * SPACING - half);
        Vec3::new(x, height(x, z), z)
    };
    let mut positions = Vec::with_capacity((side * side) as usize);
    let mut normals = Vec::with_capacity(positions.capacity());
    for j in 0..side {
        for i in 0..side {
            positions.push(at(i, j));
            let dx = at((i + 1).min(side - 1), j) - at(i.saturating_sub(1), j);
            let dz = at(i, (j + 1).min(side - 1)) - at(i, j.saturating_sub(1));
            normals.push(dz.cross(dx).normalize_or(Vec3::Y));
        }
    }
    let mut indices = Vec::with_capacity(((side - 1) * (side - 1) * 6) as usize);
    for j in 0..side - 1 {
        for i in 0..side - 1 {
            let v = j * side + i;
            indices.extend_from_slice(&[v, v + side, v + 1, v + 1, v + side, v + side + 1]);
        }
    }
    let mut mesh = IndexedMesh::new(positions, indices);
    mesh.normals = Some(normals);
    mesh
}
