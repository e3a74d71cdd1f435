//! Flattening: every primitive of every instance appended to one mesh in world space.

use super::accessors::{Data, type_error};
use super::container::{gltf_error, semantic_name};
use super::plan::{Plan, is_carried};
use super::scene::{GltfSkinInfo, Instance};
use crate::mesh::tangents::mikktspace;
use crate::mesh::{
    COLOR_ID, IndexedMesh, MeshError, MeshResult, UV_1_ID, ValidationReport, VertexAttribute,
};
use glam::{Mat3, Vec2, Vec3, Vec4};
use gltf::Primitive;
use gltf::accessor::DataType;
use gltf::mesh::{Mode, Semantic};
use std::collections::HashMap;
use std::rc::Rc;

/// The result of [`load_gltf`]: the flattened mesh and what else the file held.
///
/// [`load_gltf`]: super::load_gltf
#[derive(Clone, Debug)]
pub struct GltfImport {
    /// Every triangle primitive of the scene in one mesh, already validated.
    ///
    /// Positions and normals are in world space, except for skinned meshes: the transform of
    /// a skinned mesh's node is ignored, as the glTF specification requires, so their vertices
    /// stay in bind (mesh) space and the skin's joints place them. Joint indices refer to the
    /// joint list of the lowest-numbered skin that a node uses ([`skins`](Self::skins)); other
    /// skins are remapped to it through their joint nodes.
    ///
    /// Normals are kept only when every primitive has them. Texture coordinates, tangents,
    /// joints and weights are kept when any primitive has them, and are zero for the vertices
    /// of primitives without; `TEXCOORD_1` and `COLOR_0` become further attributes
    /// ([`UV_1_ID`](crate::mesh::UV_1_ID), [`COLOR_ID`](crate::mesh::COLOR_ID); colours are
    /// white where a primitive has none). A primitive whose material has a normal map and
    /// which has no `TANGENT` gets MikkTSpace tangents, as Bevy's glTF loader makes them.
    pub mesh: IndexedMesh,
    /// Vertex attributes of some primitive that the mesh does not carry (`TEXCOORD_2` and
    /// up, `COLOR_1` and up, `JOINTS_1`/`WEIGHTS_1`, custom `_NAME`s other than `_REGION`),
    /// by glTF name, sorted; each import that drops one also logs a warning naming them.
    pub dropped_attributes: Vec<String>,
    /// Number of triangle primitives flattened into the mesh (each instance counts).
    pub primitives: usize,
    /// Copies of meshes placed by nodes through `EXT_mesh_gpu_instancing` (each placed
    /// in the mesh, as the node's instances draw it), over all such nodes.
    pub gpu_instances: usize,
    /// How many of those primitives have morph targets. Only their base shape is imported.
    pub morph_target_primitives: usize,
    /// Every skin of the document, in document order.
    pub skins: Vec<GltfSkinInfo>,
    /// What [`IndexedMesh::validate`] dropped from the flattened mesh.
    pub report: ValidationReport,
    /// A region id per vertex, when the file paints regions (ASLOD's artists painted them with
    /// vertex colours): the custom attribute `_REGION` (integer or float scalar), or else
    /// `COLOR_0` quantised to 8 bits per channel (RGB packed into one id, so each distinct
    /// colour is one region). Vertices of primitives without either get `u32::MAX`. Feed the
    /// ids to `regions::Partition::from_ids`, which renumbers them.
    pub region_ids: Option<Vec<u32>>,
}

/// Accumulates the flattened mesh.
pub(super) struct Builder {
    mesh: IndexedMesh,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    tangents: Vec<Vec4>,
    uvs1: Vec<[f32; 2]>,
    colors: Vec<[f32; 4]>,
    region_ids: Vec<u32>,
    any_region_ids: bool,
    /// Which attributes some, and which all, primitives had.
    any_normals: bool,
    all_normals: bool,
    any_uvs: bool,
    any_joints: bool,
    any_weights: bool,
    any_tangents: bool,
    any_uvs1: bool,
    any_colors: bool,
    /// Attributes of some primitive that the mesh cannot carry, by glTF name.
    dropped: std::collections::BTreeSet<String>,
    /// Per skin, the map from its joint indices to those of the primary skin (`None` when a
    /// joint node is missing there, which drops the joints).
    joint_maps: Rc<JointMaps>,
    /// Per skin, its number of joints.
    joint_counts: Vec<usize>,
    joints_unmappable: bool,
    primitives: usize,
    morph_target_primitives: usize,
    /// The vertices the whole import will have (its [`Plan`]), which a column gets room for
    /// when it starts.
    planned_vertices: usize,
}

/// Per skin, the map from its joint indices to those of the primary skin (`None` for every
/// skin without a primary one, or with a joint node the primary lacks).
pub(super) type JointMaps = Vec<Option<Vec<u16>>>;

/// [`JointMaps`] onto skin `primary`: linear in the joints of all skins.
pub(super) fn joint_maps(skins: &[GltfSkinInfo], primary: Option<usize>) -> JointMaps {
    let index_of: HashMap<usize, usize> = primary
        .and_then(|p| skins.get(p))
        .map(|p| {
            p.joints
                .iter()
                .enumerate()
                .rev()
                .map(|(j, &node)| (node, j))
                .collect()
        })
        .unwrap_or_default();
    skins
        .iter()
        .map(|skin| {
            primary?;
            skin.joints
                .iter()
                .map(|node| u16::try_from(*index_of.get(node)?).ok())
                .collect()
        })
        .collect()
}

impl Builder {
    /// A builder of the whole scene, with room for all of the `plan` (so that no column
    /// grows by doubling, which would hold up to three times its size while it moves).
    pub(super) fn new(skins: &[GltfSkinInfo], instances: &[Instance<'_>], plan: &Plan) -> Self {
        let primary = instances.iter().filter_map(|i| i.skin).min();
        let mut builder = Self::with_joint_maps(skins, Rc::new(joint_maps(skins, primary)));
        builder.planned_vertices = usize::try_from(plan.vertices).unwrap_or(usize::MAX);
        let corners = plan.triangles.saturating_mul(3);
        builder
            .mesh
            .positions
            .reserve_exact(builder.planned_vertices);
        builder
            .mesh
            .indices
            .reserve_exact(usize::try_from(corners).unwrap_or(usize::MAX));
        builder
    }

    /// A builder whose primary skin's joint maps, [`joint_maps`], are already made (so
    /// that builders of many primitives share them).
    pub(super) fn with_joint_maps(skins: &[GltfSkinInfo], joint_maps: Rc<JointMaps>) -> Self {
        Self {
            mesh: IndexedMesh::default(),
            normals: Vec::new(),
            uvs: Vec::new(),
            joints: Vec::new(),
            weights: Vec::new(),
            tangents: Vec::new(),
            uvs1: Vec::new(),
            colors: Vec::new(),
            region_ids: Vec::new(),
            any_region_ids: false,
            any_normals: false,
            all_normals: true,
            any_uvs: false,
            any_joints: false,
            any_weights: false,
            any_tangents: false,
            any_uvs1: false,
            any_colors: false,
            dropped: std::collections::BTreeSet::new(),
            joint_maps,
            joint_counts: skins.iter().map(|s| s.joints.len()).collect(),
            joints_unmappable: false,
            primitives: 0,
            morph_target_primitives: 0,
            planned_vertices: 0,
        }
    }

    pub(super) fn add_primitive(
        &mut self,
        data: &Data<'_>,
        primitive: &Primitive<'_>,
        instance: &Instance<'_>,
    ) -> MeshResult<()> {
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            log::debug!("glTF: skipping a primitive of mode {mode:?}");
            return Ok(());
        }
        let at = format!(
            "meshes[{}].primitives[{}]",
            instance.mesh.index(),
            primitive.index()
        );
        let Some(position_accessor) = primitive.get(&Semantic::Positions) else {
            return Err(gltf_error(format!("{at}.attributes: no POSITION")));
        };
        let vertex_count = position_accessor.count();
        for (semantic, accessor) in primitive.attributes() {
            if accessor.count() != vertex_count {
                return Err(MeshError::AttributeCountMismatch {
                    attribute: semantic_name(&semantic),
                    expected: vertex_count,
                    found: accessor.count(),
                });
            }
        }

        let attribute = |semantic: Semantic| {
            let name = semantic_name(&semantic);
            primitive
                .get(&semantic)
                .map(|a| (a, format!("{at}.attributes.{name}")))
        };
        let positions = data.read_floats::<3>(&position_accessor, &format!("{at}.POSITION"))?;
        let normals = match attribute(Semantic::Normals) {
            Some((a, what)) => Some(data.read_floats::<3>(&a, &what)?),
            None => None,
        };
        let uvs = match attribute(Semantic::TexCoords(0)) {
            Some((a, what)) => Some(data.read_floats::<2>(&a, &what)?),
            None => None,
        };
        let uvs1 = match attribute(Semantic::TexCoords(1)) {
            Some((a, what)) => Some(data.read_floats::<2>(&a, &what)?),
            None => None,
        };
        let tangents = match attribute(Semantic::Tangents) {
            Some((a, what)) => Some(data.read_floats::<4>(&a, &what)?),
            None => None,
        };
        let colors = match attribute(Semantic::Colors(0)) {
            Some((a, what)) if a.dimensions().multiplicity() == 3 => Some(
                data.read_floats::<3>(&a, &what)?
                    .into_iter()
                    .map(|[r, g, b]| [r, g, b, 1.0])
                    .collect(),
            ),
            Some((a, what)) => Some(data.read_floats::<4>(&a, &what)?),
            None => None,
        };
        for (semantic, _) in primitive.attributes() {
            if !is_carried(&semantic) {
                self.dropped.insert(match &semantic {
                    Semantic::Extras(name) => format!("_{name}"),
                    other => semantic_name(other).to_string(),
                });
            }
        }
        let joints = match attribute(Semantic::Joints(0)) {
            Some((a, what)) => {
                Some(data.read_uints::<4>(&a, &what, &[DataType::U8, DataType::U16])?)
            }
            None => None,
        };
        let weights = match attribute(Semantic::Weights(0)) {
            Some((a, what)) => {
                let ty = a.data_type();
                if ty != DataType::F32
                    && !(a.normalized() && matches!(ty, DataType::U8 | DataType::U16))
                {
                    return Err(type_error(&a, &what, "F32 or normalized U8/U16"));
                }
                Some(data.read_floats::<4>(&a, &what)?)
            }
            None => None,
        };
        let indices = match primitive.indices() {
            Some(a) => {
                let what = format!("{at}.indices");
                let allowed = [DataType::U8, DataType::U16, DataType::U32];
                data.read_uints::<1>(&a, &what, &allowed)?
                    .into_iter()
                    .map(|[i]| i)
                    .collect()
            }
            None => (0..vertex_count as u32).collect::<Vec<u32>>(),
        };
        if let Some(pos) = indices.iter().position(|&i| i as usize >= vertex_count) {
            return Err(MeshError::IndexOutOfRange {
                triangle: pos / 3,
                index: indices[pos],
                vertex_count,
            });
        }
        let triangles = triangulate(mode, &indices)?;
        // A normal map needs tangents: a primitive without them gets MikkTSpace's, as Bevy's
        // glTF loader makes them, in its own space before the node's transform.
        let tangents = match (tangents, &normals, &uvs) {
            (None, Some(normals), Some(uvs)) if primitive.material().normal_texture().is_some() => {
                let vec3s = |v: &[[f32; 3]]| v.iter().map(|&p| Vec3::from(p)).collect::<Vec<_>>();
                let uvs: Vec<Vec2> = uvs.iter().map(|&t| Vec2::from(t)).collect();
                let made = mikktspace(&vec3s(&positions), &vec3s(normals), &uvs, &triangles);
                if made.is_none() {
                    log::warn!("glTF: {at}: MikkTSpace could not make tangents");
                }
                made.map(|t| t.iter().map(Vec4::to_array).collect())
            }
            (tangents, ..) => tangents,
        };

        let base = self.mesh.positions.len();
        if base + vertex_count > u32::MAX as usize {
            return Err(MeshError::TooLarge {
                what: "vertices in the glTF scene",
                count: (base + vertex_count) as u64,
                limit: u64::from(u32::MAX),
            });
        }
        let m = instance.transform;
        let linear = Mat3::from_mat4(m);
        let det = linear.determinant();
        // The cofactor matrix is the inverse transpose times the determinant, and stays
        // finite for singular transforms; the sign keeps normals pointing outwards.
        let cofactor = Mat3::from_cols(
            linear.y_axis.cross(linear.z_axis),
            linear.z_axis.cross(linear.x_axis),
            linear.x_axis.cross(linear.y_axis),
        ) * if det < 0.0 { -1.0 } else { 1.0 };
        self.mesh
            .positions
            .extend(positions.iter().map(|&p| m.transform_point3(Vec3::from(p))));

        // Each column starts with the first primitive that has its attribute.
        let room = self.planned_vertices.max(base + vertex_count);
        let column = Column {
            base,
            vertex_count,
            room,
        };
        self.all_normals &= normals.is_some();
        column.append(
            &mut self.normals,
            &mut self.any_normals,
            normals.map(|n| {
                n.into_iter()
                    .map(|n| (cofactor * Vec3::from(n)).normalize_or_zero())
            }),
            Vec3::ZERO,
        );
        // A tangent follows the surface like a position difference; a mirroring transform
        // flips the bitangent's handedness.
        column.append(
            &mut self.tangents,
            &mut self.any_tangents,
            tangents.map(|t| {
                t.into_iter().map(|[x, y, z, w]| {
                    let t = (linear * Vec3::new(x, y, z)).normalize_or_zero();
                    t.extend(if det < 0.0 { -w } else { w })
                })
            }),
            Vec4::ZERO,
        );
        column.append(&mut self.uvs1, &mut self.any_uvs1, uvs1, [0.0; 2]);
        // Primitives without colours draw as white, as Bevy draws a mesh without them.
        column.append(&mut self.colors, &mut self.any_colors, colors, [1.0; 4]);
        column.append(
            &mut self.uvs,
            &mut self.any_uvs,
            uvs.map(|t| t.into_iter().map(Vec2::from)),
            Vec2::ZERO,
        );
        column.append(&mut self.weights, &mut self.any_weights, weights, [0.0; 4]);
        let joints = joints
            .map(|js| {
                js.into_iter()
                    .map(|j| self.map_joints(j, instance.skin, &at))
                    .collect::<MeshResult<Vec<_>>>()
            })
            .transpose()?;
        column.append(&mut self.joints, &mut self.any_joints, joints, [0; 4]);
        let ids = read_region_ids(data, primitive, &at)?;
        column.append(
            &mut self.region_ids,
            &mut self.any_region_ids,
            ids,
            u32::MAX,
        );

        let flip = det < 0.0;
        self.mesh.indices.reserve(triangles.len() * 3);
        for [a, b, c] in triangles {
            let (b, c) = if flip { (c, b) } else { (b, c) };
            self.mesh.indices.extend([a, b, c].map(|i| i + base as u32));
        }
        self.primitives += 1;
        if primitive.morph_targets().len() > 0 {
            self.morph_target_primitives += 1;
        }
        Ok(())
    }

    /// Checks a vertex's joints against its skin and maps them to the primary skin.
    fn map_joints(
        &mut self,
        joints: [u32; 4],
        skin: Option<usize>,
        at: &str,
    ) -> MeshResult<[u16; 4]> {
        let Some(s) = skin else {
            // No skin to check against; u8/u16 data always fits.
            return Ok(joints.map(|j| j as u16));
        };
        let count = self.joint_counts[s];
        let mut out = [0; 4];
        for (o, &j) in out.iter_mut().zip(&joints) {
            if j as usize >= count {
                return Err(gltf_error(format!(
                    "{at}.attributes.JOINTS_0: joint {j} is out of range for skins[{s}] \
                     ({count} joints)"
                )));
            }
            *o = match &self.joint_maps[s] {
                Some(map) => map[j as usize],
                None => {
                    self.joints_unmappable = true;
                    0
                }
            };
        }
        Ok(out)
    }

    pub(super) fn finish(self, skins: Vec<GltfSkinInfo>) -> GltfImport {
        let mut mesh = self.mesh;
        if self.any_normals && !self.all_normals {
            log::warn!("glTF: only some primitives have normals; dropping normals");
        }
        mesh.normals = (self.any_normals && self.all_normals).then_some(self.normals);
        mesh.uvs = self.any_uvs.then_some(self.uvs);
        // Primitives without tangents (none given, no normal map) keep zero ones, which no
        // material of theirs reads.
        mesh.tangents = self.any_tangents.then_some(self.tangents);
        if self.any_uvs1 {
            mesh.attributes.push(VertexAttribute::from_f32(
                "Vertex_Uv_1",
                UV_1_ID,
                &self.uvs1,
            ));
        }
        if self.any_colors {
            mesh.attributes.push(VertexAttribute::from_f32(
                "Vertex_Color",
                COLOR_ID,
                &self.colors,
            ));
        }
        if !self.dropped.is_empty() {
            let names: Vec<&str> = self.dropped.iter().map(String::as_str).collect();
            log::warn!(
                "glTF: vertex attributes {} are not carried (this importer keeps POSITION, \
                 NORMAL, TANGENT, TEXCOORD_0/1, COLOR_0, JOINTS_0, WEIGHTS_0 and _REGION)",
                names.join(", ")
            );
        }
        let keep_joints = self.any_joints && !self.joints_unmappable;
        if self.joints_unmappable {
            log::warn!(
                "glTF: skins with joints missing from the primary skin; dropping joints and \
                 weights"
            );
        }
        mesh.joints = keep_joints.then_some(self.joints);
        mesh.weights = (keep_joints && self.any_weights).then_some(self.weights);
        GltfImport {
            mesh,
            dropped_attributes: self.dropped.into_iter().collect(),
            primitives: self.primitives,
            gpu_instances: 0,
            morph_target_primitives: self.morph_target_primitives,
            skins,
            report: ValidationReport::default(),
            region_ids: self.any_region_ids.then_some(self.region_ids),
        }
    }
}

/// Where one primitive's vertices go in the attribute columns.
struct Column {
    /// The vertices of the primitives before it.
    base: usize,
    /// Its vertices.
    vertex_count: usize,
    /// Room a column gets when it starts: the vertices of the whole import.
    room: usize,
}

impl Column {
    /// Appends the primitive's `values` of one attribute to `column`, or `fill` for each
    /// vertex when it has none. A column stays empty until some primitive has the attribute
    /// (`any` turns on); it then gets `fill` for the vertices before, and room for all.
    fn append<T: Clone>(
        &self,
        column: &mut Vec<T>,
        any: &mut bool,
        values: Option<impl IntoIterator<Item = T>>,
        fill: T,
    ) {
        match values {
            Some(values) => {
                if !*any {
                    *any = true;
                    column.reserve_exact(self.room);
                    column.resize(self.base, fill);
                }
                column.extend(values);
            }
            None if *any => column.resize(self.base + self.vertex_count, fill),
            None => {}
        }
    }
}

/// Turns a primitive's index list into triangles (`TRIANGLES`, `TRIANGLE_STRIP` or
/// `TRIANGLE_FAN`), in the order and winding the specification defines.
fn triangulate(mode: Mode, indices: &[u32]) -> MeshResult<Vec<[u32; 3]>> {
    Ok(match mode {
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(i, w)| {
                if i % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[0], w[2], w[1]]
                }
            })
            .collect(),
        Mode::TriangleFan => match indices.split_first() {
            Some((&first, rest)) => rest.windows(2).map(|w| [w[0], w[1], first]).collect(),
            None => Vec::new(),
        },
        _ => {
            if !indices.len().is_multiple_of(3) {
                return Err(MeshError::IndexCountNotMultipleOfThree {
                    count: indices.len(),
                });
            }
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }
    })
}

/// A primitive's painted region ids: `_REGION`, or `COLOR_0` quantised (see
/// [`GltfImport::region_ids`]).
fn read_region_ids(
    data: &Data<'_>,
    primitive: &Primitive<'_>,
    at: &str,
) -> MeshResult<Option<Vec<u32>>> {
    if let Some(a) = primitive.get(&Semantic::Extras("REGION".to_string())) {
        let what = format!("{at}.attributes._REGION");
        let ids = if a.data_type() == DataType::F32 {
            data.read_floats::<1>(&a, &what)?
                .into_iter()
                .map(|[x]| {
                    if x.is_finite() && x >= 0.0 {
                        x.round() as u32
                    } else {
                        u32::MAX
                    }
                })
                .collect()
        } else {
            let allowed = [DataType::U8, DataType::U16, DataType::U32];
            data.read_uints::<1>(&a, &what, &allowed)?
                .into_iter()
                .map(|[x]| x)
                .collect()
        };
        return Ok(Some(ids));
    }
    let Some(a) = primitive.get(&Semantic::Colors(0)) else {
        return Ok(None);
    };
    let what = format!("{at}.attributes.COLOR_0");
    let quantise = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u32;
    let pack = |r: f32, g: f32, b: f32| quantise(r) << 16 | quantise(g) << 8 | quantise(b);
    let ids = if a.dimensions().multiplicity() == 3 {
        data.read_floats::<3>(&a, &what)?
            .into_iter()
            .map(|[r, g, b]| pack(r, g, b))
            .collect()
    } else {
        data.read_floats::<4>(&a, &what)?
            .into_iter()
            .map(|[r, g, b, _]| pack(r, g, b))
            .collect()
    };
    Ok(Some(ids))
}
