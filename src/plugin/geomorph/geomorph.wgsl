// Bevy's mesh vertex shader (bevy_pbr 0.19 `mesh.wgsl`) with geomorphs: a vertex with the
// morph attributes is drawn on its way from `morph_from.xyz` to its position, started at
// `morph_from.w` seconds and taking `1 / morph_normal_from.w`, by `globals.time`; its normal,
// UVs (`ASLOD_GEOMORPH_UV`) and tangent (`ASLOD_GEOMORPH_TANGENT`) go along.
// Regions have no morph targets, so Bevy's morph-target path is left out.
#import bevy_pbr::{
    mesh_functions,
    skinning,
    forward_io::VertexOutput,
    mesh_view_bindings::globals,
    view_transformations::position_world_to_clip,
}
#import bevy_aslod::geomorph

struct Vertex {
    @builtin(instance_index) instance_index: u32,
#ifdef VERTEX_POSITIONS
    @location(0) position: vec3<f32>,
#endif
#ifdef VERTEX_NORMALS
    @location(1) normal: vec3<f32>,
#endif
#ifdef VERTEX_UVS_A
    @location(2) uv: vec2<f32>,
#endif
#ifdef VERTEX_UVS_B
    @location(3) uv_b: vec2<f32>,
#endif
#ifdef VERTEX_TANGENTS
    @location(4) tangent: vec4<f32>,
#endif
#ifdef VERTEX_COLORS
    @location(5) color: vec4<f32>,
#endif
#ifdef SKINNED
    @location(6) joint_indices: vec4<u32>,
    @location(7) joint_weights: vec4<f32>,
#endif
#ifdef ASLOD_GEOMORPH
    @location(8) morph_from: vec4<f32>,
    @location(9) morph_normal_from: vec4<f32>,
#endif
#ifdef ASLOD_GEOMORPH_UV
    @location(10) morph_uv_from: vec2<f32>,
#endif
#ifdef ASLOD_GEOMORPH_TANGENT
    @location(11) morph_tangent_from: vec4<f32>,
#endif
};

@vertex
fn vertex(vertex_in: Vertex) -> VertexOutput {
    var out: VertexOutput;
    var vertex = vertex_in;

#ifdef ASLOD_GEOMORPH
    let t = geomorph::progress(globals.time, vertex.morph_from.w, vertex.morph_normal_from.w);
#ifdef VERTEX_POSITIONS
    vertex.position = geomorph::position(vertex.morph_from.xyz, vertex.position, t);
#endif
#ifdef VERTEX_NORMALS
    vertex.normal = geomorph::normal(vertex.morph_normal_from.xyz, vertex.normal, t);
#endif
#ifdef ASLOD_GEOMORPH_UV
#ifdef VERTEX_UVS_A
    vertex.uv = geomorph::uv(vertex.morph_uv_from, vertex.uv, t);
#endif
#endif
#ifdef ASLOD_GEOMORPH_TANGENT
#ifdef VERTEX_TANGENTS
    vertex.tangent = geomorph::tangent(vertex.morph_tangent_from.xyz, vertex.tangent, t);
#endif
#endif
#endif

    let mesh_world_from_local = mesh_functions::get_world_from_local(vertex_in.instance_index);

#ifdef SKINNED
    var world_from_local = skinning::skin_model(
        vertex.joint_indices,
        vertex.joint_weights,
        vertex_in.instance_index
    );
#else
    var world_from_local = mesh_world_from_local;
#endif

#ifdef VERTEX_NORMALS
#ifdef SKINNED
    out.world_normal = skinning::skin_normals(world_from_local, vertex.normal);
#else
    out.world_normal = mesh_functions::mesh_normal_local_to_world(
        vertex.normal,
        vertex_in.instance_index
    );
#endif
#endif

#ifdef VERTEX_POSITIONS
    out.world_position = mesh_functions::mesh_position_local_to_world(world_from_local, vec4<f32>(vertex.position, 1.0));
    out.position = position_world_to_clip(out.world_position.xyz);
#endif

#ifdef VERTEX_UVS_A
    out.uv = vertex.uv;
#endif
#ifdef VERTEX_UVS_B
    out.uv_b = vertex.uv_b;
#endif

#ifdef VERTEX_TANGENTS
    out.world_tangent = mesh_functions::mesh_tangent_local_to_world(
        world_from_local,
        vertex.tangent,
        vertex_in.instance_index
    );
#endif

#ifdef VERTEX_COLORS
    out.color = vertex.color;
#endif

#ifdef VERTEX_OUTPUT_INSTANCE_INDEX
    out.instance_index = vertex_in.instance_index;
#endif

#ifdef VISIBILITY_RANGE_DITHER
    out.visibility_range_dither = mesh_functions::get_visibility_range_dither_level(
        vertex_in.instance_index, mesh_world_from_local[3]);
#endif

    return out;
}
