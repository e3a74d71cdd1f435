//! The `.mrm` file of a progressive mesh: round trips of every layout and attribute, and
//! damaged files (truncated anywhere, bits flipped, counts and lengths changed with the
//! checksums made to match, sections swapped or repeated) that must give an error naming a
//! section and never panic. `MRM_MUTATIONS=100000 cargo test --release --test mrm` runs the
//! long version.

mod common;

use bevy_aslod::mesh::{IndexedMesh, LoadLimits};
use bevy_aslod::mrm::{self, BakedMesh, BuildInfo, FORMAT_VERSION, MrmError, MrmFile, MrmKind};
use bevy_aslod::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
use bevy_aslod::refine::VariableMesh;
use bevy_aslod::regions::{Partition, RegionCaches};
use common::reseal::{containers, crc32, reseal, table};
use common::{Rng, grid, sphere, testdata_mesh};
use glam::Mat4;
use glam::Vec2;

fn build(mesh: &IndexedMesh, view: bool) -> ProgressiveMesh {
    let options = BuildOptions::default().with_view_dependent(view);
    ProgressiveMesh::build(mesh, &options).expect("test mesh builds")
}

/// A small sphere with normals, UVs, joints and weights (every optional section).
fn small() -> IndexedMesh {
    let mut mesh = sphere(8, 12, &[0.0, 0.02, -0.01], true);
    let n = mesh.positions.len();
    mesh.normals = Some(mesh.positions.iter().map(|p| p.normalize()).collect());
    mesh.uvs = Some(
        (0..n)
            .map(|i| Vec2::new(i as f32 / n as f32, 0.5))
            .collect(),
    );
    mesh.joints = Some((0..n).map(|i| [0, 1, (i % 3) as u16, 0]).collect());
    mesh.weights = Some(vec![[0.5, 0.25, 0.25, 0.0]; n]);
    mesh
}

/// [`small`] with tangents and further attributes of several formats (every section of
/// version 3).
fn full() -> IndexedMesh {
    let mut mesh = small();
    common::add_further_attributes(&mut mesh);
    mesh
}

#[test]
fn tangents_and_further_attributes_round_trip() {
    let mesh = full();
    let pm = build(&mesh, true);
    assert_eq!(pm.vertices().tangents, mesh.tangents);
    assert_eq!(pm.vertices().attributes, mesh.attributes);
    let bytes = mrm::write_progressive(&pm);
    let tags: Vec<String> = mrm::sections(&bytes)
        .unwrap()
        .into_iter()
        .map(|(t, _)| t)
        .collect();
    assert!(
        tags.iter().any(|t| t == "TAN") && tags.iter().any(|t| t == "ATTR"),
        "{tags:?}"
    );
    let back = mrm::read_progressive(&bytes).expect("reads");
    assert_eq!(back, pm);
    assert_eq!(
        mrm::write_progressive(&back),
        bytes,
        "written the same again"
    );
    let file = assets_of(&mesh, "full");
    let bytes = mrm::write(&file);
    let back = mrm::read(&bytes).expect("reads");
    assert_eq!(back, file);
    for (_, baked) in &back.meshes {
        for region in baked.regions.regions() {
            let v = region.progressive_mesh().vertices();
            assert_eq!(v.attributes.len(), 5);
            assert!(v.tangents.is_some());
        }
    }
}

#[test]
fn a_malformed_further_attribute_is_refused_by_name() {
    let mut mesh = full();
    mesh.attributes[2].data.pop();
    let err = mesh.validate().unwrap_err();
    assert!(err.to_string().contains("Vertex_Wind"), "{err}");
    let mut mesh = full();
    mesh.attributes[1].format.components = 3;
    mesh.attributes[1].data.truncate(mesh.positions.len() * 6);
    mesh.attributes[1].format.scalar = bevy_aslod::mesh::Scalar::U16;
    let err = mesh.validate().unwrap_err();
    assert!(err.to_string().contains("Vertex_Color"), "{err}");
    let mut mesh = full();
    let nan = f32::NAN.to_le_bytes();
    mesh.attributes[0].data[8..12].copy_from_slice(&nan);
    let err = mesh.validate().unwrap_err();
    assert!(err.to_string().contains("vertex 1 is NaN"), "{err}");
}

/// A file of format version 3 with every attribute ([`full`]'s assets; written when
/// `MRM_WRITE_V3` is set and the format is still version 3): it must keep loading.
const V3: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/full_v3.mrm");

#[test]
fn a_version_3_file_still_loads() {
    if std::env::var_os("MRM_WRITE_V3").is_some() && FORMAT_VERSION == 3 {
        std::fs::write(V3, mrm::write(&assets_of(&full(), "full"))).unwrap();
    }
    let bytes = std::fs::read(V3).expect("the committed version 3 file");
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 3);
    let file = mrm::read(&bytes).expect("a version 3 file loads");
    let mesh = full();
    for (_, baked) in &file.meshes {
        for region in baked.regions.regions() {
            let v = region.progressive_mesh().vertices();
            // Each region's table is a subset of the source's: compare every attribute with its
            // source vertex's.
            for (i, &g) in region.global_vertices().iter().enumerate() {
                let g = g as usize;
                assert_eq!(
                    v.tangents.as_ref().unwrap()[i],
                    mesh.tangents.as_ref().unwrap()[g]
                );
                for (a, b) in v.attributes.iter().zip(&mesh.attributes) {
                    assert_eq!((&a.name, a.id, a.format), (&b.name, b.id, b.format));
                    assert_eq!(a.record(i), b.record(g), "{} of vertex {g}", a.name);
                }
            }
        }
    }
}

#[test]
fn every_layout_and_attribute_round_trips() {
    let wide = grid(300, 230, &[0.0, 0.1, -0.05, 0.2, 0.0]);
    assert!(
        wide.positions.len() > usize::from(u16::MAX),
        "a wide layout"
    );
    for (name, mesh, view) in [
        ("small", small(), true),
        ("small, no view data", small(), false),
        ("cow", testdata_mesh("cow.obj"), true),
        ("bunny", testdata_mesh("stanford-bunny.obj"), false),
        ("wide grid", wide, true),
    ] {
        let pm = build(&mesh, view);
        let bytes = mrm::write_progressive(&pm);
        let back = mrm::read_progressive(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(back, pm, "{name}");
        assert_eq!(
            mrm::write_progressive(&back),
            bytes,
            "{name}: written the same again"
        );
        // The file is the mesh's memory plus a header: nothing is stored twice.
        let overhead = bytes.len() as i64 - pm.memory_bytes() as i64;
        assert!(
            (0..600).contains(&overhead),
            "{name}: {overhead} bytes over the mesh"
        );
    }
}

#[test]
fn the_sections_are_listed_in_order_with_their_sizes() {
    let pm = build(&small(), true);
    let bytes = mrm::write_progressive(&pm);
    let sections = mrm::sections(&bytes).unwrap();
    let tags: Vec<&str> = sections.iter().map(|(t, _)| t.as_str()).collect();
    assert_eq!(
        tags,
        [
            "MESH", "POS", "NRM", "UV0", "JNT", "WGT", "IDX", "STEP", "CORN", "PAIR", "FLDS",
            "ERRS", "VIEW"
        ]
    );
    assert_eq!(sections[10].1, 2, "FLDS: two widths");
    let n = pm.vertices().vertex_count() as u64;
    assert_eq!(sections[1].1, 12 * n);
    assert_eq!(
        sections[6].1,
        2 * 3 * pm.max_triangles() as u64,
        "16-bit indices"
    );
}

#[test]
fn a_newer_version_or_another_file_is_refused_by_name() {
    let mut bytes = mrm::write_progressive(&build(&small(), false));
    bytes[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    let err = mrm::read_progressive(&bytes).unwrap_err();
    assert_eq!(
        err,
        MrmError::NewerVersion {
            file: FORMAT_VERSION + 1,
            supported: FORMAT_VERSION
        }
    );
    assert!(
        err.to_string()
            .contains(&format!("version {}", FORMAT_VERSION + 1))
    );
    assert_eq!(
        mrm::read_progressive(b"PK\x03\x04 not a mesh at all"),
        Err(MrmError::NotMrm)
    );
    assert!(mrm::read_progressive(&[]).is_err());
}

/// A file of format version 1, baked by this crate from [`small`]: it must keep loading,
/// whatever later versions add.
const V1: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/small_v1.mrm");

#[test]
fn a_version_1_file_still_loads() {
    let bytes = std::fs::read(V1).expect("the committed version 1 file");
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 1);
    let pm = mrm::read_progressive(&bytes).expect("a version 1 file loads");
    let n = small().positions.len();
    assert_eq!(pm.vertices().vertex_count(), n);
    let v = pm.vertices();
    assert!(v.normals.is_some() && v.uvs.is_some() && v.joints.is_some() && v.weights.is_some());
    assert!(pm.has_view_data());
    // Every level is usable.
    let mut cache = PolygonCache::new(&pm);
    for level in 0..pm.level_count() {
        cache.set_level(&pm, level);
        assert_eq!(cache.indices().len(), 3 * pm.level_triangle_counts()[level]);
    }
    VariableMesh::new(pm).expect("its view data");
}

/// A file of format version 2, assets baked by this crate ([`small_assets`]; written when
/// `MRM_WRITE_V2` is set and the format is still version 2): it must keep loading.
const V2: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/small_v2.mrm");

#[test]
fn a_version_2_file_still_loads() {
    if std::env::var_os("MRM_WRITE_V2").is_some() && FORMAT_VERSION == 2 {
        std::fs::write(V2, mrm::write(&small_assets())).unwrap();
    }
    let bytes = std::fs::read(V2).expect("the committed version 2 file");
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 2);
    let file = mrm::read(&bytes).expect("a version 2 file loads");
    assert_eq!(file.meshes.len(), 2);
    let (plain, skinned) = (&file.meshes[0].1, &file.meshes[1].1);
    assert!(plain.variable.is_some() && skinned.skin.is_some());
    // Every region takes every level and stays closed (the sphere is closed).
    let mesh = small();
    for baked in [plain, skinned] {
        let regions = &baked.regions;
        let mut caches = RegionCaches::new(regions);
        for step in 0..=4 {
            let mut all = Vec::new();
            for (r, region) in regions.regions().iter().enumerate() {
                caches.set_triangle_count(regions, r, region.max_triangles() * step / 4);
            }
            for r in 0..regions.regions().len() {
                let mut out = Vec::new();
                caches.write_global_indices(regions, r, &mut out);
                all.extend(out);
            }
            common::assert_closed(&mesh.positions, &all, "a level of the version 2 file");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Damaged files.

/// One damaged copy of `good` (whose containers start at `starts`): what kind of damage,
/// and the bytes. Every kind but truncations and bit flips picks one container and reseals.
fn mutate(good: &[u8], starts: &[usize], rng: &mut Rng) -> (&'static str, Vec<u8>) {
    let start = starts[rng.below(starts.len())];
    let sections = table(good, start);
    let mut bytes = good.to_vec();
    let kind = match rng.below(7) {
        0 => {
            // Truncated at a section boundary, one byte either side, or anywhere.
            let (_, off, len) = sections[rng.below(sections.len())];
            let cut = match rng.below(4) {
                0 => off,
                1 => off + len,
                2 => (off + len).saturating_sub(1),
                _ => rng.below(good.len()),
            };
            bytes.truncate(cut.min(good.len().saturating_sub(1)));
            return ("truncated", bytes);
        }
        1 => {
            let i = rng.below(bytes.len());
            bytes[i] ^= 1 << rng.below(8);
            return ("bit flip", bytes);
        }
        2 => {
            // A length or offset in the table set to a huge or shifted value.
            let (e, _, _) = sections[rng.below(sections.len())];
            let field = e + 8 + 8 * rng.below(2);
            let value: u64 = match rng.below(3) {
                0 => u64::MAX - rng.below(1000) as u64,
                1 => 1 << (32 + rng.below(30)),
                _ => u64::from_le_bytes(bytes[field..field + 8].try_into().unwrap())
                    .wrapping_add(rng.below(9) as u64)
                    .wrapping_sub(4),
            };
            bytes[field..field + 8].copy_from_slice(&value.to_le_bytes());
            "table field changed"
        }
        3 => {
            // A count in a header (or any u32 in the first sections), huge or off by a
            // little.
            let (_, off, len) = sections[rng.below(sections.len().min(3))];
            if len >= 4 {
                let at = off + 4 * rng.below(len / 4);
                let old = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
                let value = match rng.below(3) {
                    0 => u32::MAX - rng.below(100) as u32,
                    1 => old ^ (1 << rng.below(32)),
                    _ => old.wrapping_add(rng.below(5) as u32).wrapping_sub(2),
                };
                bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
            }
            "count changed"
        }
        4 => {
            // Any byte of any section changed: the structural checks alone.
            let (_, off, len) = sections[rng.below(sections.len())];
            if len > 0 {
                let at = off + rng.below(len);
                bytes[at] = rng.next() as u8;
            }
            "record changed"
        }
        5 => {
            // Two table entries swapped (sections out of order).
            let a = rng.below(sections.len());
            let b = rng.below(sections.len());
            let (ea, eb) = (sections[a].0, sections[b].0);
            let entry_a = bytes[ea..ea + 24].to_vec();
            let entry_b = bytes[eb..eb + 24].to_vec();
            bytes[ea..ea + 24].copy_from_slice(&entry_b);
            bytes[eb..eb + 24].copy_from_slice(&entry_a);
            "sections swapped"
        }
        _ => {
            // A tag repeated in place of another.
            let a = rng.below(sections.len());
            let b = rng.below(sections.len());
            let tag = bytes[sections[a].0..sections[a].0 + 4].to_vec();
            let e = sections[b].0;
            bytes[e..e + 4].copy_from_slice(&tag);
            "tag repeated"
        }
    };
    reseal(&mut bytes, starts);
    (kind, bytes)
}

/// A mesh read back from a damaged file that still passed every check: it must be usable
/// without a panic by every level of a polygon cache and by the refinement's graph.
fn exercise(pm: &ProgressiveMesh) {
    let mut cache = PolygonCache::new(pm);
    for level in (0..pm.level_count()).rev().step_by(7).chain(0..1) {
        cache.set_level(pm, level);
    }
    if pm.has_view_data() {
        let _ = VariableMesh::new(pm.clone());
    }
}

/// Assets read back from a damaged file that passed every check: every region must take
/// any level and write its triangles without a panic, in any order.
fn exercise_assets(file: &MrmFile, rng: &mut Rng) {
    for (_, baked) in &file.meshes {
        let regions = &baked.regions;
        let mut caches = RegionCaches::new(regions);
        let mut out = Vec::new();
        for _ in 0..3 {
            for r in 0..regions.regions().len() {
                let max = regions.regions()[r].max_triangles();
                caches.set_triangle_count(regions, r, rng.below(max + 1));
            }
            for r in 0..regions.regions().len() {
                caches.write_global_indices(regions, r, &mut out);
            }
        }
        if let Some(pm) = &baked.variable {
            exercise(pm);
        }
    }
}

/// Checks that a refused file's error names where (a section and an offset), or the
/// [`LoadLimits`] a damaged count exceeds (checked before the data it counts is read).
fn assert_named(kind: &str, e: &MrmError) {
    let text = e.to_string();
    let named = matches!(e, MrmError::NotMrm | MrmError::NewerVersion { .. })
        || text.contains("byte ")
        || matches!(
            e,
            MrmError::MissingSection(_) | MrmError::LimitExceeded { .. }
        );
    assert!(named, "{kind}: the error names no place: {text}");
}

fn mutations() -> usize {
    std::env::var("MRM_MUTATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(if cfg!(debug_assertions) {
            6_000
        } else {
            100_000
        })
}

/// Runs `mutations` damaged copies of `good` through `read`, and prints what was refused.
fn damage(good: &[u8], mut read: impl FnMut(&[u8], &mut Rng) -> Result<(), MrmError>) {
    let starts = containers(good);
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut kinds = std::collections::BTreeMap::<&str, (usize, usize)>::new();
    for _ in 0..mutations() {
        let (kind, bytes) = mutate(good, &starts, &mut rng);
        let entry = kinds.entry(kind).or_default();
        entry.0 += 1;
        // Only a change that undid itself, or one the format cannot tell from a real mesh,
        // reads: `read` must find it usable.
        if let Err(e) = read(&bytes, &mut rng) {
            entry.1 += 1;
            assert_named(kind, &e);
        }
    }
    for (kind, (tried, refused)) in &kinds {
        println!("{kind}: {refused} of {tried} refused");
        assert!(*tried > 0, "{kind} never tried");
        // Without resealing, every damage is caught (by a checksum or a length at least).
        if matches!(*kind, "truncated" | "bit flip") {
            assert_eq!(refused, tried, "{kind}: a damaged file was read");
        }
    }
}

#[test]
fn damaged_files_are_errors_that_name_where() {
    let good = mrm::write_progressive(&build(&small(), true));
    damage(&good, |bytes, _| {
        mrm::read_progressive(bytes).map(|pm| exercise(&pm))
    });
}

#[test]
fn damaged_files_with_every_attribute_are_errors_that_name_where() {
    let good = mrm::write_progressive(&build(&full(), true));
    damage(&good, |bytes, _| {
        mrm::read_progressive(bytes).map(|pm| exercise(&pm))
    });
}

#[test]
fn damaged_asset_files_are_errors_that_name_where() {
    let good = mrm::write(&small_assets());
    assert!(containers(&good).len() > 8, "nested containers");
    damage(&good, |bytes, rng| {
        mrm::read(bytes).map(|file| exercise_assets(&file, rng))
    });
}

// ---------------------------------------------------------------------------------------------
// Assets.

fn build_info(name: &str, partition: &str, options: BuildOptions) -> BuildInfo {
    BuildInfo {
        source_name: name.into(),
        source_hash: mrm::source_hash(name.as_bytes()),
        partition: partition.into(),
        writer: "tests/mrm.rs".into(),
        rigid_delta: None,
        options,
    }
}

/// Two small assets: the sphere in clusters with refinement data, and skinned.
fn small_assets() -> MrmFile {
    assets_of(&small(), "small")
}

/// Two assets of a sphere (of [`small`]'s shape): in clusters with refinement data, and
/// skinned.
fn assets_of(mesh: &IndexedMesh, name: &str) -> MrmFile {
    let mesh = mesh.clone();
    // The plain asset has a merged root (the `ROOT` section), the skinned one none.
    let options = BuildOptions::default()
        .with_view_dependent(true)
        .with_root_ratio(0.5);
    let partition = Partition::clusters(&mesh, 4).unwrap();
    let plain = BakedMesh::build(&mesh, &partition, &options).unwrap();
    assert!(plain.regions.root().is_some());
    // Bone 0 holds the bottom, bone 1 the top, and a band blends them.
    let mut skinned = mesh.clone();
    let (joints, weights) = skinned
        .positions
        .iter()
        .map(|p| match p.y {
            y if y < -0.3 => ([0, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
            y if y > 0.3 => ([1, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
            _ => ([0, 1, 2, 0], [0.45, 0.45, 0.1, 0.0]),
        })
        .unzip();
    skinned.joints = Some(joints);
    skinned.weights = Some(weights);
    let names = vec!["root".into(), "a".into(), "b".into()];
    let skinned = BakedMesh::build_skinned(&skinned, &[Mat4::IDENTITY; 3], names, 0.01).unwrap();
    assert!(skinned.skin.is_some() && skinned.regions.regions().len() > 1);
    MrmFile {
        build: build_info(name, "clusters 4", options),
        meshes: vec![
            ("Mesh0/Primitive0".into(), plain),
            ("Mesh1/Primitive0".into(), skinned),
        ],
    }
}

#[test]
fn assets_round_trip_field_for_field() {
    let mut files = vec![small_assets()];
    for name in ["cow.obj", "fandisk.obj", "spot.obj", "stanford-bunny.obj"] {
        let mesh = testdata_mesh(name);
        let partition = Partition::clusters(&mesh, 16).unwrap();
        let options = BuildOptions::default()
            .with_view_dependent(name == "cow.obj")
            .with_root_ratio(if name == "spot.obj" { 0.0 } else { 0.3 });
        let baked = BakedMesh::build(&mesh, &partition, &options).unwrap();
        assert_eq!(baked.regions.root().is_some(), name != "spot.obj");
        files.push(MrmFile {
            build: build_info(name, "clusters 16", options),
            meshes: vec![(name.into(), baked)],
        });
    }
    let robot = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/testdata/characters/RobotExpressive.glb"
    );
    let clusters = |m: &IndexedMesh| Partition::clusters(m, 4);
    let options = BuildOptions::default();
    let meshes = mrm::bake_gltf(robot.as_ref(), &clusters, &options, 0.01, &mut |_| {})
        .expect("RobotExpressive");
    assert!(meshes.len() > 1 && meshes.iter().any(|(_, m)| m.skin.is_some()));
    files.push(MrmFile {
        build: build_info("RobotExpressive.glb", "skin", BuildOptions::default()),
        meshes,
    });
    for file in &files {
        let name = &file.build.source_name;
        let bytes = mrm::write(file);
        let back = mrm::read(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(back == *file, "{name}: read back differs");
        assert_eq!(mrm::write(&back), bytes, "{name}: written the same again");
        assert_eq!(mrm::kind(&bytes), Ok(MrmKind::Assets));
        assert!(mrm::read_progressive(&bytes).is_err());
    }
}

#[test]
fn a_progressive_file_is_not_read_as_assets() {
    let bytes = mrm::write_progressive(&build(&small(), false));
    assert_eq!(mrm::kind(&bytes), Ok(MrmKind::Progressive));
    let err = mrm::read(&bytes).unwrap_err();
    assert!(err.to_string().contains("progressive"), "{err}");
}

/// `assets/mannequin.mrm`, which the examples load, is baked from `assets/mannequin.glb`
/// (a stale one would still load, but not the model beside it).
#[test]
fn the_committed_mannequin_is_baked_from_the_committed_glb() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/");
    let glb = std::fs::read(format!("{dir}mannequin.glb")).unwrap();
    let bytes = std::fs::read(format!("{dir}mannequin.mrm")).unwrap();
    let file = mrm::read(&bytes).expect("assets/mannequin.mrm loads");
    assert_eq!(
        file.build.source_hash,
        mrm::source_hash(&glb),
        "assets/mannequin.mrm is stale: `cargo run --release --no-default-features --features cli \
         --bin aslod -- bake assets/mannequin.glb -o assets/mannequin.mrm`"
    );
    let (key, mannequin) = &file.meshes[0];
    assert_eq!(key, "Mesh0/Primitive0");
    let skin = mannequin.skin.as_ref().expect("skinned");
    assert_eq!(skin.inverse_bindposes.len(), 10);
    assert_eq!(
        mannequin.regions.regions().len(),
        19,
        "10 rigid and 9 deformable regions"
    );
}

// ---------------------------------------------------------------------------------------------
// Crafted files: each of these was read, or took minutes, before its check.

/// A container of `sections` (tag, bytes), as the format lays it out.
fn container(version: u32, sections: &[(&[u8; 4], Vec<u8>)]) -> Vec<u8> {
    let table_end = 16 + 24 * sections.len() + 4;
    let mut out = b"ASLODMRM".to_vec();
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(sections.len() as u32).to_le_bytes());
    let mut offset = table_end as u64;
    for (tag, bytes) in sections {
        out.extend_from_slice(*tag);
        out.extend_from_slice(&crc32(bytes).to_le_bytes());
        out.extend_from_slice(&offset.to_le_bytes());
        out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        offset += bytes.len() as u64;
    }
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    for (_, bytes) in sections {
        out.extend_from_slice(bytes);
    }
    out
}

/// `good` with the four bytes at `at` in the first section tagged `tag` (in any container)
/// set to `value`, every checksum made to match.
fn with_f32(good: &[u8], tag: &[u8; 4], at: usize, value: f32) -> Vec<u8> {
    let mut bytes = good.to_vec();
    let starts = containers(&bytes);
    let (_, data, _) = starts
        .iter()
        .flat_map(|&s| table(&bytes, s))
        .find(|&(e, _, _)| &bytes[e..e + 4] == tag)
        .expect("the section");
    bytes[data + at..data + at + 4].copy_from_slice(&value.to_le_bytes());
    reseal(&mut bytes, &starts);
    bytes
}

#[test]
fn non_finite_uvs_and_weights_are_refused() {
    let good = mrm::write_progressive(&build(&small(), false));
    for (tag, at, value, expected) in [
        (b"UV0 ", 4, f32::NAN, "not finite"),
        (b"UV0 ", 0, f32::INFINITY, "not finite"),
        (b"WGT ", 8, f32::NAN, "weight"),
        (b"WGT ", 0, -0.5, "weight"),
    ] {
        let e = mrm::read_progressive(&with_f32(&good, tag, at, value)).unwrap_err();
        let name = String::from_utf8_lossy(tag);
        assert!(e.to_string().contains(expected), "{name} {value}: {e}");
        assert!(e.to_string().contains(name.trim()), "{name}: {e}");
    }
}

#[test]
fn region_boxes_and_bounds_that_enclose_nothing_are_refused() {
    let good = mrm::write(&small_assets());
    // The first box's first half extent, negative.
    let e = mrm::read(&with_f32(&good, b"OBBS", 48, -1.0)).unwrap_err();
    assert!(e.to_string().contains("negative extent"), "{e}");
    // The first region's bounds: minimum x above the maximum.
    let e = mrm::read(&with_f32(&good, b"RGN ", 32, 1e6)).unwrap_err();
    assert!(e.to_string().contains("minimum is above"), "{e}");
}

#[test]
fn many_keys_are_checked_for_repeats_in_linear_time() {
    let good = mrm::write(&small_assets());
    let version = u32::from_le_bytes(good[8..12].try_into().unwrap());
    let sections: Vec<([u8; 4], Vec<u8>)> = table(&good, 0)
        .into_iter()
        .map(|(e, data, len)| {
            (
                good[e..e + 4].try_into().unwrap(),
                good[data..data + len].to_vec(),
            )
        })
        .collect();
    let count = 150_000u32;
    let mut keys = (count + 1).to_le_bytes().to_vec();
    for k in (0..count).chain([0]) {
        let key = format!("Mesh{k}/Primitive0");
        keys.extend_from_slice(&(key.len() as u32).to_le_bytes());
        keys.extend_from_slice(key.as_bytes());
        keys.extend_from_slice(&0u64.to_le_bytes());
    }
    let crafted: Vec<(&[u8; 4], Vec<u8>)> = sections
        .iter()
        .map(|(tag, bytes)| {
            (
                tag,
                if tag == b"KEYS" {
                    keys.clone()
                } else {
                    bytes.clone()
                },
            )
        })
        .collect();
    let start = std::time::Instant::now();
    let e = mrm::read(&container(version, &crafted)).unwrap_err();
    assert!(e.to_string().contains("repeated"), "{e}");
    // Quadratic, this took minutes; linear, milliseconds.
    assert!(start.elapsed().as_secs() < 20, "{:?}", start.elapsed());
}

#[test]
fn load_limits_hold_for_mrm_files() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/mannequin.mrm");
    let bytes = std::fs::read(path).unwrap();
    let file = mrm::read(&bytes).unwrap();
    let (_, mannequin) = &file.meshes[0];
    let vertices = mannequin.regions.vertex_count() as u64;
    let twice = mrm::write(&MrmFile {
        build: file.build.clone(),
        meshes: vec![
            ("a".into(), mannequin.clone()),
            ("b".into(), mannequin.clone()),
        ],
    });
    let defaults = LoadLimits::default();
    let limit_of = |bytes: &[u8], limits: LoadLimits| match mrm::read_with_limits(bytes, &limits) {
        Err(MrmError::LimitExceeded { limit, .. }) => limit,
        other => panic!("expected a limit, got {:?}", other.map(|f| f.meshes.len())),
    };
    for (file, limits, expected) in [
        (
            &twice,
            LoadLimits {
                keys: 1,
                ..defaults
            },
            "keys",
        ),
        (
            &bytes,
            LoadLimits {
                file_bytes: bytes.len() as u64 - 1,
                ..defaults
            },
            "file_bytes",
        ),
        (
            &bytes,
            LoadLimits {
                vertices: vertices - 1,
                ..defaults
            },
            "vertices",
        ),
        (
            &bytes,
            LoadLimits {
                triangles: 1_000,
                ..defaults
            },
            "triangles",
        ),
        (
            &bytes,
            LoadLimits {
                joints: 9,
                ..defaults
            },
            "joints",
        ),
        (
            &bytes,
            LoadLimits {
                decoded_bytes: 100_000,
                ..defaults
            },
            "decoded_bytes",
        ),
    ] {
        assert_eq!(limit_of(file, limits), expected);
    }
    // At the file's own counts, it reads; the limits hold for all its assets together.
    let exact = LoadLimits {
        keys: 2,
        file_bytes: twice.len() as u64,
        vertices: 2 * vertices,
        joints: 10,
        ..defaults
    };
    assert_eq!(
        mrm::read_with_limits(&twice, &exact).unwrap().meshes.len(),
        2
    );
    let one_asset = LoadLimits { vertices, ..exact };
    assert_eq!(limit_of(&twice, one_asset), "vertices");
    let e = mrm::read_with_limits(
        &twice,
        &LoadLimits {
            keys: 1,
            ..defaults
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("raise LoadLimits::keys"), "{e}");

    let progressive = mrm::write_progressive(&build(&small(), false));
    let n = small().vertex_count() as u64;
    for (limits, expected) in [
        (
            LoadLimits {
                vertices: n - 1,
                ..defaults
            },
            "vertices",
        ),
        (
            LoadLimits {
                triangles: 10,
                ..defaults
            },
            "triangles",
        ),
        (
            LoadLimits {
                file_bytes: 100,
                ..defaults
            },
            "file_bytes",
        ),
    ] {
        match mrm::read_progressive_with_limits(&progressive, &limits) {
            Err(MrmError::LimitExceeded { limit, .. }) => assert_eq!(limit, expected),
            other => panic!(
                "expected {expected}, got {:?}",
                other.map(|p| p.max_triangles())
            ),
        }
    }
    let within = LoadLimits {
        vertices: n,
        ..defaults
    };
    assert!(mrm::read_progressive_with_limits(&progressive, &within).is_ok());
}
