//! Writing the mannequin as binary glTF 2.0: one buffer, 4-byte aligned views, JSON with
//! sorted keys (serde_json's default map), so the same mannequin always gives the same bytes.

use super::Mannequin;
use glam::{Mat4, Vec3};
use serde_json::{Value, json};

const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The binary chunk and the buffer views and accessors that describe it.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    /// Appends a buffer view (4-byte aligned) and one accessor over all of it; returns the
    /// accessor's index.
    fn push(
        &mut self,
        data: &[u8],
        target: Option<u32>,
        component_type: u32,
        kind: &str,
        count: usize,
        bounds: Option<(Value, Value)>,
    ) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.bytes.len(),
            "byteLength": data.len(),
        });
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(view);
        let mut accessor = json!({
            "bufferView": self.views.len() - 1,
            "componentType": component_type,
            "count": count,
            "type": kind,
        });
        if let Some((min, max)) = bounds {
            accessor["min"] = min;
            accessor["max"] = max;
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn floats<const N: usize>(
        &mut self,
        values: &[[f32; N]],
        target: Option<u32>,
        kind: &str,
        with_bounds: bool,
    ) -> usize {
        let data: Vec<u8> = values
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let bounds = with_bounds.then(|| {
            let mut min = [f32::INFINITY; N];
            let mut max = [f32::NEG_INFINITY; N];
            for v in values {
                for c in 0..N {
                    min[c] = min[c].min(v[c]);
                    max[c] = max[c].max(v[c]);
                }
            }
            (json!(min.to_vec()), json!(max.to_vec()))
        });
        self.push(&data, target, FLOAT, kind, values.len(), bounds)
    }
}

fn vec3s(values: &[Vec3]) -> Vec<[f32; 3]> {
    values.iter().map(|v| v.to_array()).collect()
}

pub(super) fn write(m: &Mannequin) -> Vec<u8> {
    let mut bin = Bin::default();
    let mesh = &m.mesh;

    // The mesh's attributes and indices.
    let position = bin.floats(&vec3s(&mesh.positions), Some(ARRAY_BUFFER), "VEC3", true);
    let normals = mesh.normals.as_deref().unwrap_or_default();
    let normal = bin.floats(&vec3s(normals), Some(ARRAY_BUFFER), "VEC3", false);
    let joints = mesh.joints.as_deref().unwrap_or_default();
    let joint_bytes: Vec<u8> = joints
        .iter()
        .flatten()
        .flat_map(|j| j.to_le_bytes())
        .collect();
    let joints_0 = bin.push(
        &joint_bytes,
        Some(ARRAY_BUFFER),
        UNSIGNED_SHORT,
        "VEC4",
        joints.len(),
        None,
    );
    let weights = mesh.weights.as_deref().unwrap_or_default();
    let weights_0 = bin.floats(weights, Some(ARRAY_BUFFER), "VEC4", false);
    let region_values: Vec<[f32; 1]> = m.region_of.iter().map(|&r| [r as f32]).collect();
    let region = bin.floats(&region_values, Some(ARRAY_BUFFER), "SCALAR", false);
    let index_bytes: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    let indices = bin.push(
        &index_bytes,
        Some(ELEMENT_ARRAY_BUFFER),
        UNSIGNED_INT,
        "SCALAR",
        mesh.indices.len(),
        None,
    );

    // The skin: joints in bind pose are pure translations, so each inverse bind matrix undoes
    // its joint's world position.
    let inverse_bind: Vec<[f32; 16]> = m
        .joints
        .iter()
        .map(|j| Mat4::from_translation(-j.pivot).to_cols_array())
        .collect();
    let inverse_bind_matrices = bin.floats(&inverse_bind, None, "MAT4", false);

    // The animation: one sampler per joint rotation, one for the root's translation.
    let anim = &m.animation;
    let times: Vec<[f32; 1]> = anim.times.iter().map(|&t| [t]).collect();
    let input = bin.floats(&times, None, "SCALAR", true);
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    for (node, keys) in anim.rotations.iter().enumerate() {
        let values: Vec<[f32; 4]> = keys.iter().map(|q| q.to_array()).collect();
        let output = bin.floats(&values, None, "VEC4", false);
        channels.push(json!({
            "sampler": samplers.len(),
            "target": {"node": node, "path": "rotation"},
        }));
        samplers.push(json!({"input": input, "output": output, "interpolation": "LINEAR"}));
    }
    let output = bin.floats(&vec3s(&anim.root_translations), None, "VEC3", false);
    channels.push(json!({
        "sampler": samplers.len(),
        "target": {"node": 0, "path": "translation"},
    }));
    samplers.push(json!({"input": input, "output": output, "interpolation": "LINEAR"}));
    while !bin.bytes.len().is_multiple_of(4) {
        bin.bytes.push(0);
    }

    // Nodes: the joints first (skin joint j is node j), then the mesh's node at the scene root
    // beside the skeleton, as glTF asks of skinned meshes.
    let mut nodes: Vec<Value> = m
        .joints
        .iter()
        .enumerate()
        .map(|(i, joint)| {
            let mut node = json!({"name": joint.name, "translation": joint.translation.to_array()});
            let children: Vec<usize> = (0..m.joints.len())
                .filter(|&c| m.joints[c].parent == Some(i))
                .collect();
            if !children.is_empty() {
                node["children"] = json!(children);
            }
            node
        })
        .collect();
    let mesh_node = nodes.len();
    nodes.push(json!({"name": "mannequin", "mesh": 0, "skin": 0}));
    let root = m
        .joints
        .iter()
        .position(|j| j.parent.is_none())
        .unwrap_or(0);

    let document = json!({
        "asset": {"version": "2.0", "generator": "bevy_aslod mannequin"},
        "scene": 0,
        "scenes": [{"name": "mannequin", "nodes": [root, mesh_node]}],
        "nodes": nodes,
        "meshes": [{
            "name": "mannequin",
            "primitives": [{
                "attributes": {
                    "POSITION": position,
                    "NORMAL": normal,
                    "JOINTS_0": joints_0,
                    "WEIGHTS_0": weights_0,
                    "_REGION": region,
                },
                "indices": indices,
                "material": 0,
                "mode": 4,
            }],
        }],
        "materials": [{
            "name": "skin",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.8, 0.62, 0.5, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.65,
            },
        }],
        "skins": [{
            "name": "mannequin",
            "joints": (0..m.joints.len()).collect::<Vec<_>>(),
            "inverseBindMatrices": inverse_bind_matrices,
            "skeleton": root,
        }],
        "animations": [{"name": anim.name, "channels": channels, "samplers": samplers}],
        "buffers": [{"byteLength": bin.bytes.len()}],
        "bufferViews": bin.views,
        "accessors": bin.accessors,
    });
    container(&document.to_string().into_bytes(), &bin.bytes)
}

/// The GLB container: a 12-byte header, the JSON chunk padded with spaces and the binary chunk
/// padded with zeros, both to 4 bytes.
fn container(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let pad = |n: usize| n.next_multiple_of(4);
    let total = 12 + 8 + pad(json.len()) + 8 + pad(bin.len());
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(pad(json.len()) as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(json);
    out.resize(out.len() + pad(json.len()) - json.len(), b' ');
    out.extend_from_slice(&(pad(bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(bin);
    out.resize(out.len() + pad(bin.len()) - bin.len(), 0);
    out
}
