// Bevy's prepass vertex shader (bevy_pbr 0.19 `prepass.wgsl`: depth, normal, motion-vector
// and deferred prepasses, and shadows) with geomorphs, as `geomorph.wgsl` draws them.
// Regions have no morph targets, so Bevy's morph-target path is left out.
#import bevy_pbr::{
    mesh_functions,
    prepass_io::VertexOutput,
    skinning,
    view_transformations::position_world_to_clip,
}
#import bevy_render::globals::Globals
#import bevy_aslod::geomorph

// The prepass view bind group has the globals at binding 1.
@group(0) @binding(1) var<uniform> prepass_globals: Globals;

struct Vertex {
    @builtin(instance_index) instance_index: u32,
    @location(0) position: vec3<f32>,
#ifdef VERTEX_UVS_A
    @location(1) uv: vec2<f32>,
#endif
#ifdef VERTEX_UVS_B
    @location(2) uv_b: vec2<f32>,
#endif
#ifdef NORMAL_PREPASS_OR_DEFERRED_PREPASS
#ifdef VERTEX_NORMALS
    @location(3) normal: vec3<f32>,
#endif
#ifdef VERTEX_TANGENTS
    @location(4) tangent: vec4<f32>,
#endif
#endif
#ifdef SKINNED
    @location(5) joint_indices: vec4<u32>,
    @location(6) joint_weights: vec4<f32>,
#endif
#ifdef VERTEX_COLORS
    @location(7) color: vec4<f32>,
#endif
#ifdef ASLOD_GEOMORPH
    @location(8) morph_from: vec4<f32>,
    @location(9) morph_normal_from: vec4<f32>,
#endif
#ifdef ASLOD_GEOMORPH_UV
#ifdef VERTEX_UVS_A
    @location(10) morph_uv_from: vec2<f32>,
#endif
#endif
#ifdef ASLOD_GEOMORPH_TANGENT
#ifdef NORMAL_PREPASS_OR_DEFERRED_PREPASS
#ifdef VERTEX_TANGENTS
    @location(11) morph_tangent_from: vec4<f32>,
#endif
#endif
#endif
}

// Where the vertex is drawn at `time`.
fn morph_position(vertex: Vertex, time: f32) -> vec3<f32> {
#ifdef ASLOD_GEOMORPH
    let t = geomorph::progress(time, vertex.morph_from.w, vertex.morph_normal_from.w);
    return geomorph::position(vertex.morph_from.xyz, vertex.position, t);
#else
    return vertex.position;
#endif
}

@vertex
fn vertex(vertex_in: Vertex) -> VertexOutput {
    var out: VertexOutput;
    var vertex = vertex_in;
    vertex.position = morph_position(vertex_in, prepass_globals.time);
#ifdef ASLOD_GEOMORPH
    let t = geomorph::progress(prepass_globals.time, vertex.morph_from.w, vertex.morph_normal_from.w);
#ifdef NORMAL_PREPASS_OR_DEFERRED_PREPASS
#ifdef VERTEX_NORMALS
    vertex.normal = geomorph::normal(vertex.morph_normal_from.xyz, vertex.normal, t);
#endif
#ifdef ASLOD_GEOMORPH_TANGENT
#ifdef VERTEX_TANGENTS
    vertex.tangent = geomorph::tangent(vertex.morph_tangent_from.xyz, vertex.tangent, t);
#endif
#endif
#endif
#ifdef ASLOD_GEOMORPH_UV
#ifdef VERTEX_UVS_A
    vertex.uv = geomorph::uv(vertex.morph_uv_from, vertex.uv, t);
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

    out.world_position = mesh_functions::mesh_position_local_to_world(world_from_local, vec4<f32>(vertex.position, 1.0));
    out.position = position_world_to_clip(out.world_position.xyz);
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    out.unclipped_depth = out.position.z;
    out.position.z = min(out.position.z, 1.0);
#endif

#ifdef VERTEX_UVS_A
    out.uv = vertex.uv;
#endif
#ifdef VERTEX_UVS_B
    out.uv_b = vertex.uv_b;
#endif

#ifdef NORMAL_PREPASS_OR_DEFERRED_PREPASS
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
#ifdef VERTEX_TANGENTS
    out.world_tangent = mesh_functions::mesh_tangent_local_to_world(
        world_from_local,
        vertex.tangent,
        vertex_in.instance_index
    );
#endif
#endif

#ifdef VERTEX_COLORS
    out.color = vertex.color;
#endif

#ifdef MOTION_VECTOR_PREPASS
    // Where the vertex was drawn last frame: its morph a frame earlier.
    let previous = morph_position(vertex_in, prepass_globals.time - prepass_globals.delta_time);
#ifdef SKINNED
#ifdef HAS_PREVIOUS_SKIN
    let prev_model = skinning::skin_prev_model(
        vertex.joint_indices,
        vertex.joint_weights,
        vertex_in.instance_index
    );
#else
    let prev_model = mesh_functions::get_previous_world_from_local(vertex_in.instance_index);
#endif
#else
    let prev_model = mesh_functions::get_previous_world_from_local(vertex_in.instance_index);
#endif
    out.previous_world_position = mesh_functions::mesh_position_local_to_world(
        prev_model,
        vec4<f32>(previous, 1.0)
    );
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
