//! A GLB whose one node places a quad many times through `EXT_mesh_gpu_instancing` (shared by
//! the import, CLI and plugin tests).

/// A 1×1 quad in XZ (two triangles, a normal up), placed by one node at `node_at` through
/// `EXT_mesh_gpu_instancing` once per element of `translations`; the second copy, if any,
/// is turned a quarter turn about Y and scaled by 2. `extra` is spliced into the extension's
/// attributes (a malformed file's `"SCALE": 9`, say). Returns the GLB's bytes.
pub fn instanced_quads(translations: &[[f32; 3]], node_at: [f32; 3], extra: &str) -> Vec<u8> {
    let n = translations.len();
    let mut bin = Vec::new();
    let push = |bin: &mut Vec<u8>, values: &[f32]| {
        for v in values {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    };
    push(&mut bin, &[0., 0., 0., 1., 0., 0., 1., 0., 1., 0., 0., 1.]);
    push(&mut bin, &[0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1., 0.]);
    for i in [0u16, 3, 1, 1, 3, 2] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let t_at = bin.len();
    push(&mut bin, translations.as_flattened());
    let r_at = bin.len();
    let half = std::f32::consts::FRAC_1_SQRT_2;
    let mut rotations = vec![[0.0, 0.0, 0.0, 1.0]; n];
    let mut scales = vec![[1.0; 3]; n];
    if n > 1 {
        rotations[1] = [0.0, half, 0.0, half];
        scales[1] = [2.0; 3];
    }
    push(&mut bin, rotations.as_flattened());
    let s_at = bin.len();
    push(&mut bin, scales.as_flattened());
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["EXT_mesh_gpu_instancing"],
        "scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{{"mesh":0,"translation":{node_at:?},"extensions":{{"EXT_mesh_gpu_instancing":
            {{"attributes":{{"TRANSLATION":3,"ROTATION":4,"SCALE":5{extra}}}}}}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2}}]}}],
        "accessors":[
            {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,0,1]}},
            {{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"}},
            {{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}},
            {{"bufferView":3,"componentType":5126,"count":{n},"type":"VEC3"}},
            {{"bufferView":4,"componentType":5126,"count":{n},"type":"VEC4"}},
            {{"bufferView":5,"componentType":5126,"count":{n},"type":"VEC3"}}],
        "bufferViews":[
            {{"buffer":0,"byteOffset":0,"byteLength":48}},
            {{"buffer":0,"byteOffset":48,"byteLength":48}},
            {{"buffer":0,"byteOffset":96,"byteLength":12}},
            {{"buffer":0,"byteOffset":{t_at},"byteLength":{}}},
            {{"buffer":0,"byteOffset":{r_at},"byteLength":{}}},
            {{"buffer":0,"byteOffset":{s_at},"byteLength":{}}}],
        "buffers":[{{"byteLength":{}}}]}}"#,
        r_at - t_at,
        s_at - r_at,
        bin.len() - s_at,
        bin.len(),
    );
    super::glb(&json, &bin)
}
