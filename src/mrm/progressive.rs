//! A [`ProgressiveMesh`] as `.mrm` sections, and back, checked.

use super::container::{Reader, Section, Sections, f32s};
use super::{FORMAT_VERSION, MrmError};
use crate::mesh::{AttributeFormat, IndexedMesh, LoadLimits, Scalar, VertexAttribute};
use crate::multires::ProgressiveMesh;
use crate::multires::hierarchy::{Moved, ViewData};
use crate::multires::records::{Corner, Fields, Header, Layout, Records, error_from_u16};
use glam::{Vec2, Vec3, Vec4};

/// The sections, in file order, and whether each is required.
pub(super) const SECTIONS: [([u8; 4], bool); 15] = [
    (*b"MESH", true),
    (*b"POS ", true),
    (*b"NRM ", false),
    (*b"UV0 ", false),
    (*b"JNT ", false),
    (*b"WGT ", false),
    (*b"TAN ", false),
    (*b"ATTR", false),
    (*b"IDX ", true),
    (*b"STEP", true),
    (*b"CORN", true),
    (*b"PAIR", true),
    // Required from version 4 (`read_fields` checks).
    (*b"FLDS", false),
    (*b"ERRS", true),
    (*b"VIEW", false),
];

/// The first format version whose records have their own field widths (`FLDS`).
const FIELDS_VERSION: u32 = 4;

const NORMALS: u8 = 1;
const UVS: u8 = 2;
const JOINTS: u8 = 4;
const WEIGHTS: u8 = 8;
/// Tangents (`TAN `, from version 3).
const TANGENTS: u8 = 16;
/// Further attributes (`ATTR`, from version 3).
const FURTHER: u8 = 32;
/// The most further attributes a vertex table may have in a file (Bevy's vertex buffers take
/// at most 16 attributes in all on most devices).
const MAX_FURTHER: usize = 32;

fn vec3s(v: &[Vec3]) -> Vec<u8> {
    v.iter()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect()
}

/// The file bytes of `mesh`.
pub(super) fn write(mesh: &ProgressiveMesh) -> Vec<u8> {
    let v = &mesh.vertices;
    let (attributes, vertex_sections) = vertex_sections(v);
    let (narrow, index_count, steps, corners, pairs) = layout_counts(&mesh.records);
    let mut head = Vec::with_capacity(32);
    head.extend_from_slice(&(v.positions.len() as u32).to_le_bytes());
    head.extend_from_slice(&[attributes, narrow, u8::from(mesh.view.is_some()), 0]);
    for x in [
        mesh.base_triangles as usize,
        index_count,
        steps,
        corners,
        pairs,
    ] {
        head.extend_from_slice(&(x as u32).to_le_bytes());
    }
    let mut sections = vec![(*b"MESH", head)];
    sections.extend(vertex_sections);
    record_sections(&mut sections, mesh);
    super::container::write(FORMAT_VERSION, &sections)
}

/// Whether the records are narrow (1) or wide (0), and their index, step, corner and pair
/// counts.
pub(super) fn layout_counts(records: &Layout) -> (u8, usize, usize, usize, usize) {
    match records {
        Layout::Narrow(r) => (
            1u8,
            r.indices.len(),
            r.steps.len(),
            r.corners.len(),
            r.pairs.len(),
        ),
        Layout::Wide(r) => (
            0u8,
            r.indices.len(),
            r.steps.len(),
            r.corners.len(),
            r.pairs.len(),
        ),
    }
}

/// The attribute flags of a vertex table and its sections (`POS ` to `WGT `).
pub(super) fn vertex_sections(v: &IndexedMesh) -> (u8, Sections) {
    let flag = |on: bool, bit: u8| if on { bit } else { 0 };
    let attributes = flag(v.normals.is_some(), NORMALS)
        | flag(v.uvs.is_some(), UVS)
        | flag(v.joints.is_some(), JOINTS)
        | flag(v.weights.is_some(), WEIGHTS)
        | flag(v.tangents.is_some(), TANGENTS)
        | flag(!v.attributes.is_empty(), FURTHER);
    let mut sections = vec![(*b"POS ", vec3s(&v.positions))];
    if let Some(normals) = &v.normals {
        sections.push((*b"NRM ", vec3s(normals)));
    }
    if let Some(uvs) = &v.uvs {
        let bytes = uvs
            .iter()
            .flat_map(|t| t.to_array())
            .flat_map(f32::to_le_bytes);
        sections.push((*b"UV0 ", bytes.collect()));
    }
    if let Some(joints) = &v.joints {
        let bytes = joints.iter().flatten().flat_map(|j| j.to_le_bytes());
        sections.push((*b"JNT ", bytes.collect()));
    }
    if let Some(weights) = &v.weights {
        let bytes = weights.iter().flatten().flat_map(|w| w.to_le_bytes());
        sections.push((*b"WGT ", bytes.collect()));
    }
    if let Some(tangents) = &v.tangents {
        let bytes = tangents
            .iter()
            .flat_map(|t| t.to_array())
            .flat_map(f32::to_le_bytes);
        sections.push((*b"TAN ", bytes.collect()));
    }
    if !v.attributes.is_empty() {
        let mut out = (v.attributes.len() as u32).to_le_bytes().to_vec();
        for a in &v.attributes {
            out.extend_from_slice(&(a.name.len() as u32).to_le_bytes());
            out.extend_from_slice(a.name.as_bytes());
            out.extend_from_slice(&a.id.to_le_bytes());
            out.extend_from_slice(&[a.format.scalar.code(), a.format.components, 0, 0]);
            out.extend_from_slice(&a.data);
        }
        sections.push((*b"ATTR", out));
    }
    (attributes, sections)
}

/// The sections of a mesh's records, their field widths, error table and view data (`IDX `
/// to `VIEW`).
pub(super) fn record_sections(sections: &mut Sections, mesh: &ProgressiveMesh) {
    match &mesh.records {
        Layout::Narrow(r) => records(sections, r, |x: u16| x.to_le_bytes().to_vec()),
        Layout::Wide(r) => records(sections, r, |x: u32| x.to_le_bytes().to_vec()),
    }
    let errors = mesh.errors.iter().flat_map(|e| e.to_le_bytes()).collect();
    sections.push((*b"ERRS", errors));
    if let Some(view) = &mesh.view {
        sections.push((*b"VIEW", view_bytes(view)));
    }
}

fn records<V: Copy, H: Header + Into<u32>, C: Corner>(
    sections: &mut Sections,
    r: &Records<V, H, C>,
    bytes: impl Fn(V) -> Vec<u8>,
) {
    let wide = size_of::<C>() == 4;
    sections.push((*b"IDX ", r.indices.iter().flat_map(|&i| bytes(i)).collect()));
    let header = |h: H| -> Vec<u8> {
        let h: u32 = h.into();
        if wide {
            h.to_le_bytes().to_vec()
        } else {
            (h as u16).to_le_bytes().to_vec()
        }
    };
    sections.push((*b"STEP", r.steps.iter().flat_map(|&h| header(h)).collect()));
    let corner = |c: C| -> Vec<u8> {
        let b = c.get().to_le_bytes();
        if wide { b.to_vec() } else { b[..3].to_vec() }
    };
    sections.push((
        *b"CORN",
        r.corners.iter().flat_map(|&c| corner(c)).collect(),
    ));
    let pairs = r.pairs.iter().flatten().flat_map(|&v| bytes(v)).collect();
    sections.push((*b"PAIR", pairs));
    sections.push((*b"FLDS", vec![r.fields.pair_bits, r.fields.removed_bits]));
}

fn view_bytes(view: &ViewData) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&view.diagonal.to_le_bytes());
    match &view.moved {
        Moved::Narrow(m) => {
            out.push(1);
            out.extend(m.iter().flatten().flat_map(|v| v.to_le_bytes()));
        }
        Moved::Wide(m) => {
            out.push(0);
            out.extend(m.iter().flatten().flat_map(|v| v.to_le_bytes()));
        }
    }
    out.extend(view.centre.iter().flatten().map(|&c| c as u8));
    out.extend(view.radius.iter().flat_map(|r| r.to_le_bytes()));
    out.extend(view.error.iter().flat_map(|e| e.to_le_bytes()));
    out.extend(view.cone.iter().flatten());
    out
}

/// The section `tag`, or the error that it is missing.
pub(super) fn section<'a>(
    sections: &[Section<'a>],
    tag: &[u8; 4],
) -> Result<Section<'a>, MrmError> {
    sections
        .iter()
        .find(|s| &s.tag == tag)
        .copied()
        .ok_or_else(|| MrmError::MissingSection(super::container::tag_name(*tag)))
}

/// Reads a progressive mesh from checked sections (see [`super::container::read`]) of a
/// file of format `version`.
pub(super) fn read(
    sections: &[Section<'_>],
    version: u32,
    limits: &LoadLimits,
) -> Result<ProgressiveMesh, MrmError> {
    let mesh = section(sections, b"MESH")?;
    let mut r = Reader::new(mesh);
    let n = r.u32()? as usize;
    let [attributes, narrow, has_view, _] = r.array::<4>()?;
    let counts = Counts {
        vertices: n,
        base: r.u32()? as usize,
        indices: r.u32()? as usize,
        steps: r.u32()? as usize,
        corners: r.u32()? as usize,
        pairs: r.u32()? as usize,
    };
    r.finish()?;
    super::within("vertices", n, limits.vertices)?;
    super::within("triangles", counts.indices / 3, limits.triangles)?;
    let vertices = read_vertices(sections, &r, n, attributes)?;
    read_mesh(sections, &r, version, vertices, &counts, narrow, has_view)
}

/// The records, error table and view data of a mesh over `vertices`, as `counts`, `narrow`
/// and `has_view` declare them in the header `r` read (errors about those point there), in
/// a file of format `version`.
pub(super) fn read_mesh(
    sections: &[Section<'_>],
    r: &Reader<'_>,
    version: u32,
    vertices: IndexedMesh,
    counts: &Counts,
    narrow: u8,
    has_view: u8,
) -> Result<ProgressiveMesh, MrmError> {
    if narrow > 1 || has_view > 1 {
        return Err(r.invalid(4, "unknown flags"));
    }
    if !counts.indices.is_multiple_of(3) || counts.base > counts.indices / 3 {
        return Err(r.invalid(4, "the index count or base triangle count is inconsistent"));
    }
    if sections.iter().any(|s| &s.tag == b"VIEW") != (has_view != 0) {
        return Err(r.invalid(4, "a section is missing or present against the flags"));
    }
    let fields = read_fields(sections, version, narrow == 1)?;
    let records = if narrow == 1 {
        Layout::Narrow(read_records::<u16, u16, [u8; 3], 2, 2, 3>(
            sections,
            counts,
            fields,
            u16::from_le_bytes,
            u16::from_le_bytes,
            |b| <[u8; 3]>::pack(u32::from_le_bytes([b[0], b[1], b[2], 0])),
        )?)
    } else {
        Layout::Wide(read_records::<u32, u32, u32, 4, 4, 4>(
            sections,
            counts,
            fields,
            u32::from_le_bytes,
            u32::from_le_bytes,
            u32::from_le_bytes,
        )?)
    };
    let (errors, r) = Reader::whole::<2, _>(
        section(sections, b"ERRS")?,
        counts.steps,
        u16::from_le_bytes,
    )?;
    let mut previous = 0.0f32;
    for (k, &e) in errors.iter().enumerate() {
        let e = error_from_u16(e);
        if !(e.is_finite() && e >= previous) {
            return Err(r.invalid(
                2 * k,
                "the error table is not finite, positive and monotone",
            ));
        }
        previous = e;
    }
    let view = if has_view != 0 {
        Some(read_view(
            section(sections, b"VIEW")?,
            counts.vertices,
            counts.steps,
        )?)
    } else {
        None
    };
    Ok(ProgressiveMesh {
        vertices,
        base_triangles: counts.base as u32,
        records,
        errors,
        view,
    })
}

/// The field widths of a mesh's records (`narrow` or wide): its `FLDS` section from format
/// version 4 (a pair selector of 1 to 8 bits and a removed count of 2 to 8 bits, with room
/// for a corner count in a narrow mesh's 16-bit headers), [`Fields::CLASSIC`] before.
fn read_fields(sections: &[Section<'_>], version: u32, narrow: bool) -> Result<Fields, MrmError> {
    let found = sections.iter().find(|s| &s.tag == b"FLDS").copied();
    if version < FIELDS_VERSION {
        return match found {
            Some(s) => Err(Reader::new(s).invalid(0, "a FLDS section before format version 4")),
            None => Ok(Fields::CLASSIC),
        };
    }
    let Some(s) = found else {
        return Err(MrmError::MissingSection("FLDS".into()));
    };
    let mut r = Reader::new(s);
    let [pair_bits, removed_bits] = r.array::<2>()?;
    r.finish()?;
    let fields = Fields {
        pair_bits,
        removed_bits,
    };
    if !(Fields::CLASSIC.pair_bits..=Fields::MAX_BITS).contains(&pair_bits) {
        return Err(r.invalid(0, "the pair selector width is not 1 to 8 bits"));
    }
    if !(Fields::CLASSIC.removed_bits..=Fields::MAX_BITS).contains(&removed_bits) {
        return Err(r.invalid(1, "the removed-triangle count width is not 2 to 8 bits"));
    }
    if narrow && !<u16 as Header>::fits(fields) {
        return Err(r.invalid(
            0,
            "the field widths leave 16-bit step headers no corner count",
        ));
    }
    debug_assert!(fields.is_valid());
    Ok(fields)
}

/// The vertex table (`POS ` to `WGT `) of `n` vertices with the attributes `attributes`
/// flags, from the header `r` read.
pub(super) fn read_vertices(
    sections: &[Section<'_>],
    r: &Reader<'_>,
    n: usize,
    attributes: u8,
) -> Result<IndexedMesh, MrmError> {
    let find = |tag: &[u8; 4]| sections.iter().any(|s| &s.tag == tag);
    let section = |tag: &[u8; 4]| section(sections, tag);
    if attributes & !(NORMALS | UVS | JOINTS | WEIGHTS | TANGENTS | FURTHER) != 0 {
        return Err(r.invalid(4, "unknown flags"));
    }
    // Each optional section is there exactly when its flag says so.
    for (tag, on) in [
        (b"NRM ", attributes & NORMALS != 0),
        (b"UV0 ", attributes & UVS != 0),
        (b"JNT ", attributes & JOINTS != 0),
        (b"WGT ", attributes & WEIGHTS != 0),
        (b"TAN ", attributes & TANGENTS != 0),
        (b"ATTR", attributes & FURTHER != 0),
    ] {
        if find(tag) != on {
            return Err(r.invalid(4, "a section is missing or present against the flags"));
        }
    }
    let finite = "a value is not finite";
    let read_vec3 = |tag: &[u8; 4]| {
        checked::<12, _>(
            section(tag)?,
            n,
            |b| Vec3::from(f32s::<3>(&b)),
            |p| p.is_finite(),
            finite,
        )
    };
    let positions = read_vec3(b"POS ")?;
    let normals = (attributes & NORMALS != 0)
        .then(|| read_vec3(b"NRM "))
        .transpose()?;
    let uvs = (attributes & UVS != 0)
        .then(|| {
            checked::<8, _>(
                section(b"UV0 ")?,
                n,
                |b| Vec2::from(f32s::<2>(&b)),
                |t| t.is_finite(),
                finite,
            )
        })
        .transpose()?;
    let joints = (attributes & JOINTS != 0)
        .then(|| {
            Reader::whole::<8, _>(section(b"JNT ")?, n, |b| {
                [0, 2, 4, 6].map(|k| u16::from_le_bytes([b[k], b[k + 1]]))
            })
        })
        .transpose()?
        .map(|(v, _)| v);
    let weights = (attributes & WEIGHTS != 0)
        .then(|| {
            checked::<16, _>(
                section(b"WGT ")?,
                n,
                |b| f32s::<4>(&b),
                |w| w.iter().all(|x| x.is_finite() && *x >= 0.0),
                "a weight is negative or not finite",
            )
        })
        .transpose()?;
    let tangents = (attributes & TANGENTS != 0)
        .then(|| {
            checked::<16, _>(
                section(b"TAN ")?,
                n,
                |b| Vec4::from(f32s::<4>(&b)),
                |t| t.is_finite(),
                finite,
            )
        })
        .transpose()?;
    let further = if attributes & FURTHER != 0 {
        read_further(section(b"ATTR")?, n)?
    } else {
        Vec::new()
    };
    let mesh = IndexedMesh {
        positions,
        normals,
        uvs,
        joints,
        weights,
        tangents,
        attributes: further,
        indices: Vec::new(),
    };
    mesh.validate_vertex_table()
        .map_err(|e| MrmError::Attributes(e.to_string()))?;
    Ok(mesh)
}

/// The `n` records of `N` bytes of a section, decoded, each passing `ok`; the first that does
/// not is `problem` at its offset.
fn checked<const N: usize, T>(
    section: Section<'_>,
    n: usize,
    decode: impl Fn([u8; N]) -> T,
    ok: impl Fn(&T) -> bool,
    problem: &'static str,
) -> Result<Vec<T>, MrmError> {
    let (v, r) = Reader::whole::<N, _>(section, n, decode)?;
    match v.iter().position(|t| !ok(t)) {
        Some(k) => Err(r.invalid(N * k, problem)),
        None => Ok(v),
    }
}

/// The further attributes of `n` vertices (`ATTR`): a count, then per attribute its name,
/// id, scalar type, component count, two zero bytes and `n` records.
fn read_further(section: Section<'_>, n: usize) -> Result<Vec<VertexAttribute>, MrmError> {
    let mut r = Reader::new(section);
    let count = r.u32()? as usize;
    if count > MAX_FURTHER {
        return Err(r.invalid(0, "more than 32 further attributes"));
    }
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        let name = r.string()?;
        let id = r.u64()?;
        let at = r.offset() - r.start();
        let [scalar, components, pad0, pad1] = r.array::<4>()?;
        let format = Scalar::from_code(scalar)
            .map(|scalar| AttributeFormat { scalar, components })
            .filter(|f| f.is_valid() && pad0 == 0 && pad1 == 0)
            .ok_or_else(|| r.invalid(at as usize, "an unknown attribute format"))?;
        let data = r.bytes(n.saturating_mul(format.size()))?.to_vec();
        out.push(VertexAttribute {
            name,
            id,
            format,
            data,
        });
    }
    r.finish()?;
    Ok(out)
}

/// The counts a mesh header declares.
pub(super) struct Counts {
    pub(super) vertices: usize,
    pub(super) base: usize,
    pub(super) indices: usize,
    pub(super) steps: usize,
    pub(super) corners: usize,
    pub(super) pairs: usize,
}

/// The first of `values` at or past `n`: a maximum first (which vectorises), the search only
/// when there is one.
fn first_out_of_range<V: Copy + Into<u32>>(values: &[V], n: usize) -> Option<usize> {
    let max = values.iter().map(|&v| v.into()).max()?;
    if (max as usize) < n {
        return None;
    }
    values.iter().position(|&v| v.into() as usize >= n)
}

/// The records of one layout with the field widths `fields`, checked so that every cache
/// and refinement walk stays in bounds: indices and pairs name existing vertices; each step
/// removes live triangles (at most as many as its header's count holds), never below the
/// base, has at most as many pairs as a corner record's selector names, and rewrites
/// corners of the triangles that stay, naming one of its own pairs; the per-step counts add
/// up to the sections' lengths.
fn read_records<V, H, C, const VB: usize, const HB: usize, const CB: usize>(
    sections: &[Section<'_>],
    counts: &Counts,
    fields: Fields,
    vertex: impl Fn([u8; VB]) -> V,
    header: impl Fn([u8; HB]) -> H,
    corner: impl Fn([u8; CB]) -> C,
) -> Result<Records<V, H, C>, MrmError>
where
    V: Copy + Into<u32>,
    H: Header,
    C: Corner,
{
    let section = |tag: &[u8; 4]| section(sections, tag);
    let (indices, r) = Reader::whole::<VB, _>(section(b"IDX ")?, counts.indices, &vertex)?;
    if let Some(k) = first_out_of_range(&indices, counts.vertices) {
        return Err(r.invalid(VB * k, "an index names a vertex past the vertex table"));
    }
    let (steps, rs) = Reader::whole::<HB, _>(section(b"STEP")?, counts.steps, header)?;
    let (corners, rc) = Reader::whole::<CB, _>(section(b"CORN")?, counts.corners, corner)?;
    let pair_values = counts.pairs.saturating_mul(2);
    let (raw, rp) = Reader::whole::<VB, _>(section(b"PAIR")?, pair_values, &vertex)?;
    if let Some(k) = first_out_of_range(&raw, counts.vertices) {
        return Err(rp.invalid(VB * k, "a pair names a vertex past the vertex table"));
    }
    let pairs: Vec<[V; 2]> = raw.chunks_exact(2).map(|p| [p[0], p[1]]).collect();
    let records = Records {
        indices,
        steps,
        corners,
        pairs,
        fields,
    };
    let (mut live, mut c, mut p) = (counts.indices / 3, 0usize, 0usize);
    for (s, (nc, np, removed)) in records.headers().enumerate() {
        if removed > live - counts.base || np > fields.max_pairs() {
            return Err(rs.invalid(
                HB * s,
                "a step removes past the base or has more pairs than a corner record names",
            ));
        }
        live -= removed;
        let (Some(step_corners), true) = (
            records.corners.get(c..c + nc),
            p + np <= records.pairs.len(),
        ) else {
            return Err(rs.invalid(HB * s, "a step names more corners or pairs than there are"));
        };
        for (k, &rec) in step_corners.iter().enumerate() {
            if records.corner_slot(rec) >= 3 * live || records.corner_pair(rec) >= np {
                return Err(rc.invalid(CB * (c + k), "a corner record is out of range"));
            }
        }
        c += nc;
        p += np;
    }
    if live != counts.base || c != records.corners.len() || p != records.pairs.len() {
        return Err(rs.invalid(0, "the steps do not add up to the records"));
    }
    Ok(records)
}

fn read_view(section: Section<'_>, vertices: usize, steps: usize) -> Result<ViewData, MrmError> {
    let mut r = Reader::new(section);
    let diagonal = r.f32()?;
    if !(diagonal.is_finite() && diagonal > 0.0) {
        return Err(r.invalid(0, "the diagonal is not finite and positive"));
    }
    let at = r.offset() - section.offset;
    let moved = match r.u8()? {
        1 => Moved::Narrow(r.items::<4, _>(steps, |b| {
            [
                u16::from_le_bytes([b[0], b[1]]),
                u16::from_le_bytes([b[2], b[3]]),
            ]
        })?),
        0 => Moved::Wide(r.items::<8, _>(steps, |b| {
            [
                u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                u32::from_le_bytes([b[4], b[5], b[6], b[7]]),
            ]
        })?),
        _ => return Err(r.invalid(at as usize, "unknown vertex width")),
    };
    if (0..steps).any(|i| {
        moved
            .get(i)
            .is_none_or(|m| m.iter().any(|&v| v as usize >= vertices))
    }) {
        return Err(r.invalid(
            at as usize,
            "a collapse names a vertex past the vertex table",
        ));
    }
    let centre = r.items::<3, _>(steps, |b| b.map(|c| c as i8))?;
    let at = (r.offset() - section.offset) as usize;
    let radius = r.items::<2, _>(steps, u16::from_le_bytes)?;
    let error = r.items::<2, _>(steps, u16::from_le_bytes)?;
    let cone = r.items::<3, _>(steps, |b| b)?;
    r.finish()?;
    // Finite in the mesh's units too: a radius times the diagonal must not overflow.
    let bad = |x: &u16| {
        let v = error_from_u16(*x);
        !(v.is_finite() && v >= 0.0 && (v * diagonal).is_finite())
    };
    if radius.iter().any(bad) || error.iter().any(bad) {
        return Err(r.invalid(at, "a bound is not finite"));
    }
    Ok(ViewData {
        moved,
        centre,
        radius,
        error,
        cone,
        diagonal,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::multires::records::{classic, error_to_u16, permissive};

    /// A mesh of 60 vertices over `records` (of [`permissive`]'s triangles).
    fn mesh_of(records: &crate::multires::records::Unpacked, base: u32) -> ProgressiveMesh {
        let positions = (0..60)
            .map(|i| Vec3::new(i as f32, (i % 7) as f32, (i % 3) as f32))
            .collect();
        ProgressiveMesh {
            vertices: IndexedMesh::new(positions, Vec::new()),
            base_triangles: base,
            records: Layout::new(records, 60).expect("the records fit"),
            errors: vec![error_to_u16(0.01), error_to_u16(0.02)],
            view: None,
        }
    }

    /// `bytes` (a progressive-mesh file) written again as format `version` with its
    /// sections passed through `edit`.
    fn rewritten(bytes: &[u8], version: u32, edit: impl FnOnce(&mut Sections)) -> Vec<u8> {
        let read = super::super::container::read(bytes, 0, FORMAT_VERSION, &SECTIONS).unwrap();
        let mut sections: Sections = read.iter().map(|s| (s.tag, s.bytes.to_vec())).collect();
        edit(&mut sections);
        super::super::container::write(version, &sections)
    }

    fn without_fields(sections: &mut Sections) {
        sections.retain(|(tag, _)| tag != b"FLDS");
    }

    fn with_fields(fields: &[u8]) -> impl FnOnce(&mut Sections) + '_ {
        move |sections| {
            for (tag, bytes) in sections {
                if tag == b"FLDS" {
                    *bytes = fields.to_vec();
                }
            }
        }
    }

    /// What reading `bytes` gives: the error's section and message, or the mesh's fields.
    fn outcome(bytes: &[u8]) -> Result<Fields, (String, &'static str)> {
        match super::super::read_progressive(bytes) {
            Ok(pm) => Ok(pm.records.fields()),
            Err(MrmError::Invalid { section, what, .. }) => Err((section, what)),
            Err(MrmError::MissingSection(section)) => Err((section, "missing")),
            Err(e) => panic!("{e}"),
        }
    }

    #[test]
    fn a_step_with_many_pairs_round_trips_with_its_fields() {
        let pm = mesh_of(&permissive(), 3);
        assert_eq!(
            pm.records.fields(),
            Fields {
                pair_bits: 4,
                removed_bits: 3
            }
        );
        let bytes = super::super::write_progressive(&pm);
        assert_eq!(
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
            FORMAT_VERSION
        );
        let sections = super::super::sections(&bytes).unwrap();
        assert!(sections.contains(&("FLDS".into(), 2)), "{sections:?}");
        let back = super::super::read_progressive(&bytes).unwrap();
        assert_eq!(back, pm);
        assert_eq!(back.records.removed(), [6, 1]);
        assert_eq!(super::super::write_progressive(&back), bytes);
        // A cache walks it.
        let mut cache = crate::multires::PolygonCache::new(&back);
        cache.set_level(&back, 2);
        assert_eq!(cache.indices().len(), 9);
        assert_eq!(&cache.indices()[..3], &[50, 51, 42]);
    }

    #[test]
    fn a_file_before_version_4_has_the_classic_fields() {
        let pm = mesh_of(&classic(), 6);
        assert_eq!(pm.records.fields(), Fields::CLASSIC);
        let v4 = super::super::write_progressive(&pm);
        let v3 = rewritten(&v4, 3, without_fields);
        assert_eq!(outcome(&v3), Ok(Fields::CLASSIC));
        assert_eq!(super::super::read_progressive(&v3).unwrap(), pm);
        // Written again, it is a current file with the classic widths.
        assert_eq!(super::super::write_progressive(&pm), v4);
        let fields = Fields::CLASSIC;
        assert_eq!(
            rewritten(
                &v4,
                FORMAT_VERSION,
                with_fields(&[fields.pair_bits, fields.removed_bits])
            ),
            v4
        );
        // Records that need wider fields than a version 3 file has are refused.
        let wide = super::super::write_progressive(&mesh_of(&permissive(), 3));
        let err = outcome(&rewritten(&wide, 3, without_fields)).unwrap_err();
        assert_eq!(err.0, "STEP", "{err:?}");
        // And a version 3 file has no FLDS.
        let err = outcome(&rewritten(&v4, 3, |_| {})).unwrap_err();
        assert_eq!(
            err,
            ("FLDS".into(), "a FLDS section before format version 4")
        );
    }

    #[test]
    fn a_version_4_file_needs_valid_fields() {
        let good = super::super::write_progressive(&mesh_of(&permissive(), 3));
        assert_eq!(
            outcome(&rewritten(&good, 4, without_fields)),
            Err(("FLDS".into(), "missing"))
        );
        for (fields, what) in [
            (&[0, 3][..], "the pair selector width is not 1 to 8 bits"),
            (&[9, 3], "the pair selector width is not 1 to 8 bits"),
            (
                &[4, 1],
                "the removed-triangle count width is not 2 to 8 bits",
            ),
            (
                &[4, 9],
                "the removed-triangle count width is not 2 to 8 bits",
            ),
            (
                &[8, 8],
                "the field widths leave 16-bit step headers no corner count",
            ),
            (&[4, 3, 0], "bytes left over at the end of the section"),
        ] {
            let bytes = rewritten(&good, 4, with_fields(fields));
            assert_eq!(outcome(&bytes), Err(("FLDS".into(), what)), "{fields:?}");
        }
        assert!(matches!(
            super::super::read_progressive(&rewritten(&good, 4, with_fields(&[4]))),
            Err(MrmError::Truncated { .. })
        ));
        // Other valid widths than the writer's decode other records, which are checked.
        for fields in [[1, 2], [4, 2], [2, 3], [5, 3], [4, 4]] {
            let bytes = rewritten(&good, 4, with_fields(&fields));
            assert!(outcome(&bytes).is_err(), "{fields:?}");
        }
        assert!(outcome(&rewritten(&good, 4, with_fields(&[4, 3]))).is_ok());
    }
}
