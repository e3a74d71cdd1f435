//! Mesh generators and topology checks shared by the integration tests.
#![allow(dead_code)]

pub mod instancing;
pub mod reseal;

use bevy_aslod::mesh::{IndexedMesh, weld_positions};
use glam::{Vec2, Vec3};
use proptest::prelude::*;
use std::collections::HashMap;

/// A tiny xorshift generator: the same sequence on every run.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// Uniform in `0..n` (`0` when `n` is `0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    /// Uniform in `0.0..1.0`.
    pub fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Cases per property: `PROPTEST_CASES` when set (for long runs), else `default`.
pub fn cases(default: u32) -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// [`cases`], with a fixed seed unless `PROPTEST_RNG_SEED` is set, so that CI does not depend
/// on luck; long runs set both (`PROPTEST_CASES=20000 PROPTEST_RNG_SEED=1`, and other seeds).
pub fn config(default_cases: u32) -> ProptestConfig {
    let mut config = ProptestConfig::with_cases(cases(default_cases));
    if std::env::var("PROPTEST_RNG_SEED").is_err() {
        config.rng_seed = proptest::test_runner::RngSeed::Fixed(0x5eed_a51d);
    }
    config
}

/// A mesh of `../shared/testdata/meshes`, read in place.
pub fn testdata_mesh(name: &str) -> IndexedMesh {
    let path = format!(
        "{}/../shared/testdata/meshes/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    IndexedMesh::load(&path)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .0
}

/// Triangles as a sorted list of corner triples (corner order kept).
pub fn triangle_multiset(indices: &[u32]) -> Vec<[u32; 3]> {
    let mut tris: Vec<[u32; 3]> = indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    tris.sort_unstable();
    tris
}

/// Directed edge counts over positions welded by value.
pub fn welded_directed_edges(positions: &[Vec3], indices: &[u32]) -> HashMap<(u32, u32), u32> {
    let weld = weld_positions(positions);
    let mut edges = HashMap::new();
    for t in indices.chunks_exact(3) {
        for k in 0..3 {
            let a = weld.remap[t[k] as usize];
            let b = weld.remap[t[(k + 1) % 3] as usize];
            *edges.entry((a, b)).or_insert(0) += 1;
        }
    }
    edges
}

/// Every edge is used exactly once in each direction: closed, manifold, consistently wound.
pub fn assert_closed(positions: &[Vec3], indices: &[u32], context: &str) {
    let edges = welded_directed_edges(positions, indices);
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "{context}: edge {a}->{b} used {n} times");
        assert_eq!(
            edges.get(&(b, a)),
            Some(&1),
            "{context}: edge {a}->{b} has no opposite (a crack or a flip)"
        );
    }
}

pub fn normal(p: &[Vec3], t: &[u32]) -> Vec3 {
    let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
    (b - a).cross(c - a)
}

/// A closed UV sphere with radial noise; `seam` splits the vertices along longitude 0 into
/// two attribute vertices with different UVs, as a texture seam does.
pub fn sphere(rings: u32, segments: u32, noise: &[f32], seam: bool) -> IndexedMesh {
    let mut positions = vec![Vec3::Y];
    let mut uvs = vec![Vec2::new(0.5, 0.0)];
    let mut noise_at = noise.iter().cycle();
    let cols = if seam { segments + 1 } else { segments };
    for r in 1..rings {
        let phi = std::f32::consts::PI * r as f32 / rings as f32;
        let mut ring = Vec::new();
        for s in 0..segments {
            let theta = std::f32::consts::TAU * s as f32 / segments as f32;
            let radius = 1.0 + noise_at.next().copied().unwrap_or(0.0);
            ring.push(
                Vec3::new(phi.sin() * theta.cos(), phi.cos(), phi.sin() * theta.sin()) * radius,
            );
        }
        for s in 0..cols {
            positions.push(ring[(s % segments) as usize]);
            uvs.push(Vec2::new(
                s as f32 / segments as f32,
                r as f32 / rings as f32,
            ));
        }
    }
    positions.push(-Vec3::Y);
    uvs.push(Vec2::new(0.5, 1.0));
    let south = positions.len() as u32 - 1;
    let at = |r: u32, s: u32| 1 + (r - 1) * cols + if seam { s } else { s % segments };
    let mut indices = Vec::new();
    for s in 0..segments {
        indices.extend_from_slice(&[0, at(1, s + 1), at(1, s)]);
        indices.extend_from_slice(&[south, at(rings - 1, s), at(rings - 1, s + 1)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1));
            indices.extend_from_slice(&[a, b, c, b, d, c]);
        }
    }
    let mut mesh = IndexedMesh::new(positions, indices);
    mesh.uvs = Some(uvs);
    mesh
}

/// An open height field of `w x h` vertices.
pub fn grid(w: u32, h: u32, heights: &[f32]) -> IndexedMesh {
    let mut positions = Vec::new();
    let mut height = heights.iter().cycle();
    for y in 0..h {
        for x in 0..w {
            positions.push(Vec3::new(
                x as f32,
                height.next().copied().unwrap_or(0.0),
                y as f32,
            ));
        }
    }
    let mut indices = Vec::new();
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let i = y * w + x;
            indices.extend_from_slice(&[i, i + w, i + 1, i + 1, i + w, i + w + 1]);
        }
    }
    IndexedMesh::new(positions, indices)
}

/// Welded edges used in one direction only: the open border.
pub fn border_edges(positions: &[Vec3], indices: &[u32]) -> Vec<(u32, u32)> {
    let edges = welded_directed_edges(positions, indices);
    edges
        .keys()
        .filter(|&&(a, b)| !edges.contains_key(&(b, a)))
        .copied()
        .collect()
}

/// Random closed or open meshes for the property tests.
pub fn arb_mesh() -> impl Strategy<Value = (IndexedMesh, bool)> {
    prop_oneof![
        (
            4u32..10,
            4u32..12,
            prop::collection::vec(-0.2f32..0.2, 1..40),
            any::<bool>()
        )
            .prop_map(|(r, s, noise, seam)| (sphere(r, s, &noise, seam), true)),
        (2u32..9, 2u32..9, prop::collection::vec(-1.0f32..1.0, 1..30))
            .prop_map(|(w, h, heights)| (grid(w, h, &heights), false)),
    ]
}

/// Gives `mesh` tangents and further attributes of several formats, each vertex's values
/// distinct from its neighbours': a second UV set, RGBA colours, a half-float pair, four
/// integer bytes and a BGRA colour. Every level must carry them unchanged.
pub fn add_further_attributes(mesh: &mut IndexedMesh) {
    use bevy_aslod::mesh::{AttributeFormat, COLOR_ID, Scalar, UV_1_ID, VertexAttribute};
    let n = mesh.positions.len();
    mesh.tangents = Some(
        (0..n)
            .map(|i| {
                let a = i as f32 * 0.37;
                glam::Vec4::new(a.cos(), 0.0, a.sin(), if i % 3 == 0 { -1.0 } else { 1.0 })
            })
            .collect(),
    );
    let uv1: Vec<[f32; 2]> = (0..n).map(|i| [i as f32 / n as f32, 0.25]).collect();
    let colors: Vec<[f32; 4]> = (0..n)
        .map(|i| [(i % 7) as f32 / 7.0, (i % 5) as f32 / 5.0, 0.5, 1.0])
        .collect();
    // Byte attributes: name, id, format, and byte `k` of vertex `i`.
    let bytes = |name: &str, id: u64, scalar: Scalar, f: &dyn Fn(usize, usize) -> u8| {
        let format = AttributeFormat {
            scalar,
            components: if scalar == Scalar::F16 { 2 } else { 4 },
        };
        VertexAttribute {
            name: name.into(),
            id,
            format,
            data: (0..n)
                .flat_map(|i| (0..format.size()).map(move |k| f(i, k)))
                .collect(),
        }
    };
    // Finite half floats: exponent bits never all set.
    let wind = bytes("Vertex_Wind", 988_540_917, Scalar::F16, &|i, k| {
        if k % 2 == 1 {
            (i % 60) as u8
        } else {
            (i * 7 + k) as u8
        }
    });
    let material = bytes("Vertex_MaterialIds", 988_540_918, Scalar::U8, &|i, k| {
        (i * 13 + k) as u8
    });
    let tint = bytes("Vertex_Tint", 988_540_919, Scalar::Bgra8, &|i, k| {
        (i * 3 + k * 50) as u8
    });
    mesh.attributes = vec![
        VertexAttribute::from_f32("Vertex_Uv_1", UV_1_ID, &uv1),
        VertexAttribute::from_f32("Vertex_Color", COLOR_ID, &colors),
        wind,
        material,
        tint,
    ];
}

/// Packs JSON and a BIN chunk into a GLB container.
pub fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    out
}
