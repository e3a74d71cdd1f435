//! A level of props: one `.glb` placed many times by one glTF whose nodes share its meshes
//! (the `textured` example's `--copies`, and the plugin's prop-field test).

use std::path::{Path, PathBuf};

/// Writes `prop` (a `.glb`) again into `dir` as `field.glb`, its scene replaced by `side²`
/// copies on a square grid `spacing` apart in X and Z: each copy a node whose children are
/// the prop's root nodes again, so every copy shows the same meshes. The binary chunk and
/// everything else (materials, images) stay as they are. Copy `i` stands at column `i %
/// side`, row `i / side`, the grid centred on the origin.
///
/// # Panics
/// If `prop` cannot be read or is not a GLB with a scene, or `dir` cannot be written.
pub fn prop_field(prop: &Path, dir: &Path, side: usize, spacing: f32) -> PathBuf {
    let bytes = std::fs::read(prop).expect("the prop reads");
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let json_len = word(12);
    let mut json: serde_json::Value =
        serde_json::from_slice(&bytes[20..20 + json_len]).expect("GLB JSON");
    // The BIN chunk's payload, past its 8-byte header.
    let bin = bytes.get(28 + json_len..).unwrap_or_default();
    let scene = json["scene"].as_u64().unwrap_or(0) as usize;
    let roots = json["scenes"][scene]["nodes"].clone();
    let nodes = json["nodes"].as_array_mut().expect("nodes");
    let mut copies = Vec::new();
    for i in 0..side * side {
        let (x, z) = ((i % side) as f32, (i / side) as f32);
        let half = (side as f32 - 1.0) * 0.5;
        let first_child = nodes.len() + 1;
        let children: Vec<usize> = (0..roots.as_array().unwrap().len())
            .map(|k| first_child + k)
            .collect();
        copies.push(nodes.len());
        nodes.push(serde_json::json!({
            "name": format!("copy{i}"),
            "translation": [(x - half) * spacing, 0.0, (z - half) * spacing],
            "children": children,
        }));
        for root in roots.as_array().unwrap() {
            let mut node = nodes[root.as_u64().unwrap() as usize].clone();
            node["name"] = format!("copy{i}_{}", node["name"].as_str().unwrap_or("")).into();
            nodes.push(node);
        }
    }
    json["scenes"] = serde_json::json!([{ "nodes": copies }]);
    json["scene"] = 0.into();
    let path = dir.join("field.glb");
    std::fs::write(&path, glb(&serde_json::to_vec(&json).unwrap(), bin)).unwrap();
    path
}

/// A GLB container of `json` and, when not empty, a `BIN` chunk of `bin` (each padded to 4
/// bytes, JSON with spaces).
pub fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut text = json.to_vec();
    text.resize(text.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + text.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    for (kind, chunk) in [(b"JSON", &text), (b"BIN\0", &bin)] {
        if !chunk.is_empty() {
            out.extend_from_slice(&(chunk.len() as u32).to_le_bytes());
            out.extend_from_slice(kind);
            out.extend_from_slice(chunk);
        }
    }
    out
}
