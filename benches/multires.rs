//! Progressive mesh benchmarks on the Stanford bunny (69,451 triangles):
//! - `cache_sweep`: the polygon cache swept between 1% and 100% and back; the throughput is
//!   triangles added or removed per second (target: at least 100 million), with 32-bit and
//!   16-bit indices;
//! - `build`: the whole progressive sequence, against meshoptimizer's single simplification
//!   to 1% (the `meshopt` crate) in the same run;
//! - `build_attributes`: the whole sequence of the WaterBottle (6,886 triangles, normals and
//!   UVs with seams) with the default attribute terms and without them (target: at most
//!   1.3× slower with them).

use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

const BUNNY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/testdata/meshes/stanford-bunny.obj"
);

fn bunny() -> IndexedMesh {
    IndexedMesh::load(BUNNY).expect("the bunny loads").0
}

fn cache_sweep(c: &mut Criterion) {
    let mesh = bunny();
    let pm = ProgressiveMesh::build(&mesh, &BuildOptions::default()).expect("builds");
    let full = pm.max_triangles();
    let low = full / 100;
    let mut cache = PolygonCache::new(&pm);
    cache.set_triangle_count(&pm, low);
    let moved = (full - cache.triangle_count()) as u64;
    let mut group = c.benchmark_group("cache_sweep");
    group.throughput(Throughput::Elements(2 * moved));
    group.bench_function("bunny_1pc_to_100pc_and_back", |b| {
        b.iter(|| {
            cache.set_triangle_count(&pm, black_box(full));
            cache.set_triangle_count(&pm, black_box(low));
            black_box(cache.indices().len())
        })
    });
    let mut narrow = PolygonCache::<u16>::with_index_type(&pm).expect("the bunny fits u16");
    narrow.set_triangle_count(&pm, low);
    group.bench_function("bunny_1pc_to_100pc_and_back_u16", |b| {
        b.iter(|| {
            narrow.set_triangle_count(&pm, black_box(full));
            narrow.set_triangle_count(&pm, black_box(low));
            black_box(narrow.indices().len())
        })
    });
    group.finish();
}

fn build(c: &mut Criterion) {
    let mesh = bunny();
    let bytes: Vec<u8> = mesh
        .positions
        .iter()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let adapter = meshopt::VertexDataAdapter::new(&bytes, 12, 0).expect("stride 12");
    let mut group = c.benchmark_group("build_bunny");
    group.sample_size(10);
    group.bench_function("ours_full_sequence", |b| {
        b.iter(|| ProgressiveMesh::build(black_box(&mesh), &BuildOptions::default()))
    });
    group.bench_function("meshopt_simplify_to_1pc", |b| {
        b.iter(|| {
            meshopt::simplify(
                black_box(&mesh.indices),
                &adapter,
                3 * mesh.triangle_count() / 100,
                f32::MAX,
                meshopt::SimplifyOptions::None,
                None,
            )
        })
    });
    group.finish();
}

fn build_attributes(c: &mut Criterion) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/testdata/textured/WaterBottle.glb"
    );
    let mesh = IndexedMesh::load(path).expect("the bottle loads").0;
    let without = BuildOptions::default()
        .with_normal_weight(0.0)
        .with_uv_weight(0.0)
        .with_color_weight(0.0);
    let mut group = c.benchmark_group("build_attributes");
    group.sample_size(20);
    group.bench_function("bottle_default", |b| {
        b.iter(|| ProgressiveMesh::build(black_box(&mesh), &BuildOptions::default()))
    });
    group.bench_function("bottle_without_attribute_terms", |b| {
        b.iter(|| ProgressiveMesh::build(black_box(&mesh), &without))
    });
    group.finish();
}

criterion_group!(benches, cache_sweep, build, build_attributes);
criterion_main!(benches);
