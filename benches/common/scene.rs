//! The scene the plugin bench and the core-only frame bench share (no Bevy): a bumpy patch,
//! where the copies stand, and the camera's path over them. The plugin tests use the patch.

use bevy_aslod::mesh::IndexedMesh;
use glam::Vec3;

/// A bumpy `n`×`n`-vertex patch, 16 units wide.
pub fn patch(n: u32) -> IndexedMesh {
    let mut positions = Vec::new();
    for z in 0..n {
        for x in 0..n {
            let (fx, fz) = (x as f32, z as f32);
            let y = ((fx * 0.7).sin() * (fz * 0.9).cos() + (fx * 0.31 + fz * 0.17).sin()) * 0.6;
            let s = 16.0 / (n - 1) as f32;
            positions.push(Vec3::new(fx * s - 8.0, y, fz * s - 8.0));
        }
    }
    let mut indices = Vec::new();
    for z in 0..n - 1 {
        for x in 0..n - 1 {
            let i = z * n + x;
            indices.extend_from_slice(&[i, i + n, i + 1, i + 1, i + n, i + n + 1]);
        }
    }
    IndexedMesh::new(positions, indices)
}

/// Models per row of the square grid of `models` copies.
pub fn side(models: usize) -> usize {
    (models as f32).sqrt().ceil() as usize
}

/// Where copy `i` stands: 20 units apart, row by row.
pub fn model_position(i: usize, side: usize) -> Vec3 {
    Vec3::new((i % side) as f32 * 20.0, 0.0, (i / side) as f32 * 20.0)
}

/// The camera at `t` in `0..1`: sweeping along the front of the grid, high up, looking into
/// it. Returns the eye and the point it looks at.
pub fn camera(t: f32, side: usize) -> (Vec3, Vec3) {
    let extent = side as f32 * 20.0;
    let at = Vec3::new(t * extent, 120.0, -60.0 + (t * 6.0).sin() * 20.0);
    (at, at + Vec3::new(10.0, -60.0, 100.0))
}
