//! Whole multiresolution assets ([`BakedMesh`]) as `.mrm` files, and back, checked.

use super::container::{self, Reader, Section, f32s};
use super::progressive::{self, Counts, section};
use super::{BakedMesh, BakedSkin, BuildInfo, FORMAT_VERSION, MrmError, MrmFile, within};
use crate::bounds::Obb;
use crate::mesh::LoadLimits;
use crate::multires::{BuildOptions, CollapseOperator};
use crate::regions::{FrontEvent, MergedRoot, Partition, Region, RegionMesh};
use crate::skin::SkinRegionKind;
use glam::{Mat3, Mat4, Vec3};

/// The sections of a file of assets, in order.
pub(super) const FILE_SECTIONS: [([u8; 4], bool); 3] =
    [(*b"SRC ", true), (*b"KEYS", true), (*b"ASET", true)];

/// The sections of one asset (a container nested in `ASET`), in order.
const ENTRY_SECTIONS: [([u8; 4], bool); 14] = [
    (*b"HEAD", true),
    (*b"POS ", true),
    (*b"NRM ", false),
    (*b"UV0 ", false),
    (*b"JNT ", false),
    (*b"WGT ", false),
    (*b"TAN ", false),
    (*b"ATTR", false),
    (*b"PART", true),
    (*b"OBBS", true),
    (*b"RGNS", true),
    (*b"SKIN", false),
    (*b"VARI", false),
    // From version 5: the merged root, when the asset has one.
    (*b"ROOT", false),
];

/// The sections of the merged root (a container nested in `ROOT`), in order.
const ROOT_SECTIONS: [([u8; 4], bool); 9] = [
    (*b"RHED", true),
    (*b"GLOB", true),
    (*b"IDX ", true),
    (*b"STEP", true),
    (*b"CORN", true),
    (*b"PAIR", true),
    (*b"FLDS", true),
    (*b"ERRS", true),
    (*b"KEPT", true),
];

/// The sections of one region (a container nested in `RGNS`), in order.
const REGION_SECTIONS: [([u8; 4], bool); 10] = [
    (*b"RGN ", true),
    (*b"GLOB", true),
    (*b"IDX ", true),
    (*b"STEP", true),
    (*b"CORN", true),
    (*b"PAIR", true),
    // Required from version 4 (as a progressive mesh's).
    (*b"FLDS", false),
    (*b"ERRS", true),
    (*b"VIEW", false),
    (*b"LIST", true),
];

/// Bytes of one stored box: centre, three axes, half extents.
const OBB_BYTES: usize = 60;

fn put_u32(out: &mut Vec<u8>, x: usize) {
    out.extend_from_slice(&(x as u32).to_le_bytes());
}

fn put_str(out: &mut Vec<u8>, s: &str) {
    put_u32(out, s.len());
    out.extend_from_slice(s.as_bytes());
}

fn put_f32s(out: &mut Vec<u8>, xs: &[f32]) {
    out.extend(xs.iter().flat_map(|x| x.to_le_bytes()));
}

fn u32s(xs: &[u32]) -> Vec<u8> {
    xs.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The file bytes of `file`.
pub(super) fn write(file: &MrmFile) -> Vec<u8> {
    let entries: Vec<Vec<u8>> = file.meshes.iter().map(|(_, m)| write_entry(m)).collect();
    let mut keys = Vec::new();
    put_u32(&mut keys, file.meshes.len());
    for ((key, _), bytes) in file.meshes.iter().zip(&entries) {
        put_str(&mut keys, key);
        keys.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
    }
    container::write(
        FORMAT_VERSION,
        &[
            (*b"SRC ", build_bytes(&file.build)),
            (*b"KEYS", keys),
            (*b"ASET", entries.concat()),
        ],
    )
}

fn build_bytes(b: &BuildInfo) -> Vec<u8> {
    let o = &b.options;
    let mut out = Vec::new();
    out.extend_from_slice(&b.source_hash.to_le_bytes());
    put_str(&mut out, &b.source_name);
    put_str(&mut out, &b.partition);
    put_str(&mut out, &b.writer);
    out.push(u8::from(b.rigid_delta.is_some()));
    out.extend_from_slice(&b.rigid_delta.unwrap_or(0.0).to_le_bytes());
    out.extend_from_slice(&(o.min_triangles as u64).to_le_bytes());
    out.extend_from_slice(&o.max_error.to_le_bytes());
    for x in [
        o.border_weight,
        o.min_normal_cos,
        o.regularization,
        o.local_weight,
        o.weight_exponent,
    ] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.push(u8::from(o.view_dependent));
    out.extend_from_slice(&o.pair_distance.to_le_bytes());
    out.push(match o.operator {
        CollapseOperator::Edge => 0,
        CollapseOperator::Triangle => 1,
    });
    for x in [o.normal_weight, o.uv_weight, o.color_weight] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&o.weld_distance.to_le_bytes());
    out.push(u8::from(o.permissive));
    out.extend_from_slice(&o.root_ratio.to_le_bytes());
    out
}

fn write_entry(m: &BakedMesh) -> Vec<u8> {
    let regions = m.regions.regions();
    let source = m.regions.source_vertices();
    let (attributes, vertex_sections) = progressive::vertex_sections(&source);
    let mut head = Vec::new();
    put_u32(&mut head, m.regions.vertex_count());
    head.extend_from_slice(&[
        attributes,
        u8::from(m.skin.is_some()),
        u8::from(m.variable.is_some()),
        0,
    ]);
    put_u32(&mut head, regions.len());
    let mut sections = vec![(*b"HEAD", head)];
    sections.extend(vertex_sections);
    sections.push((*b"PART", u32s(m.regions.partition().region_of())));
    let mut obbs = Vec::with_capacity(OBB_BYTES * m.obbs.len());
    for b in &m.obbs {
        put_f32s(&mut obbs, &b.center.to_array());
        put_f32s(&mut obbs, &b.axes.to_cols_array());
        put_f32s(&mut obbs, &b.half_extents.to_array());
    }
    sections.push((*b"OBBS", obbs));
    let bodies: Vec<Vec<u8>> = regions.iter().map(write_region).collect();
    let mut rgns = Vec::new();
    put_u32(&mut rgns, bodies.len());
    for b in &bodies {
        rgns.extend_from_slice(&(b.len() as u64).to_le_bytes());
    }
    rgns.extend(bodies.concat());
    sections.push((*b"RGNS", rgns));
    if let Some(skin) = &m.skin {
        sections.push((*b"SKIN", skin_bytes(skin)));
    }
    if let Some(variable) = &m.variable {
        sections.push((*b"VARI", progressive::write(variable)));
    }
    if let Some(root) = m.regions.root() {
        sections.push((*b"ROOT", write_root(root)));
    }
    container::write(FORMAT_VERSION, &sections)
}

fn write_root(root: &MergedRoot) -> Vec<u8> {
    let pm = &root.mesh;
    let (narrow, indices, steps, corners, pairs) = progressive::layout_counts(&pm.records);
    let mut head = Vec::new();
    for x in [
        root.global.len(),
        pm.base_triangles as usize,
        indices,
        steps,
        corners,
        pairs,
        root.kept.len(),
    ] {
        put_u32(&mut head, x);
    }
    head.extend_from_slice(&[narrow, 0, 0, 0]);
    let mut sections = vec![(*b"RHED", head), (*b"GLOB", u32s(&root.global))];
    progressive::record_sections(&mut sections, pm);
    sections.push((*b"KEPT", u32s(&root.kept)));
    container::write(FORMAT_VERSION, &sections)
}

/// The merged root of an asset whose regions are `regions` (checked: its vertices in the
/// source's table, one kept level per region, each one of that region's levels);
/// `vertex_bytes` per vertex copied, as the regions count them.
fn read_root(
    s: Section<'_>,
    version: u32,
    source: &crate::mesh::IndexedMesh,
    vertex_bytes: usize,
    regions: &[Region],
    tally: &mut Tally<'_>,
) -> Result<MergedRoot, MrmError> {
    let sections = container::read(s.bytes, s.offset, version, &ROOT_SECTIONS)?;
    let mut r = Reader::new(section(&sections, b"RHED")?);
    let local = r.u32()? as usize;
    let counts = Counts {
        vertices: local,
        base: r.u32()? as usize,
        indices: r.u32()? as usize,
        steps: r.u32()? as usize,
        corners: r.u32()? as usize,
        pairs: r.u32()? as usize,
    };
    let kept_count = r.u32()? as usize;
    let [narrow, _, _, _] = r.array::<4>()?;
    r.finish()?;
    if kept_count != regions.len() {
        return Err(r.invalid(24, "the kept level count differs from the region count"));
    }
    tally.add(local, vertex_bytes, counts.indices / 3)?;
    let (global, vertices) = read_global(&sections, local, source)?;
    let mesh = progressive::read_mesh(&sections, &r, version, vertices, &counts, narrow, 0)?;
    let (kept, rk) =
        Reader::whole::<4, _>(section(&sections, b"KEPT")?, kept_count, u32::from_le_bytes)?;
    if let Some(k) = kept
        .iter()
        .zip(regions)
        .position(|(&level, region)| level as usize >= region.mesh.level_count())
    {
        return Err(rk.invalid(4 * k, "a kept level is past its region's levels"));
    }
    Ok(MergedRoot { mesh, global, kept })
}

fn write_region(r: &Region) -> Vec<u8> {
    let pm = &r.mesh;
    let (narrow, indices, steps, corners, pairs) = progressive::layout_counts(&pm.records);
    let mut head = Vec::new();
    for x in [
        r.global.len(),
        r.own_vertices,
        pm.base_triangles as usize,
        indices,
        steps,
        corners,
        pairs,
    ] {
        put_u32(&mut head, x);
    }
    head.extend_from_slice(&[narrow, u8::from(pm.view.is_some()), 0, 0]);
    put_f32s(&mut head, &r.bounds.0.to_array());
    put_f32s(&mut head, &r.bounds.1.to_array());
    for x in [
        r.border.len(),
        r.fin_prone.len(),
        r.neighbors.len(),
        r.position_of.len(),
        r.front_events.len(),
    ] {
        put_u32(&mut head, x);
    }
    let mut sections = vec![(*b"RGN ", head), (*b"GLOB", u32s(&r.global))];
    progressive::record_sections(&mut sections, pm);
    let mut list = Vec::new();
    for xs in [&r.border, &r.fin_prone, &r.neighbors, &r.position_of] {
        list.extend(u32s(xs));
    }
    for e in &r.front_events {
        list.extend(u32s(&[e.step, e.region, e.corner, e.before, e.after]));
    }
    sections.push((*b"LIST", list));
    container::write(FORMAT_VERSION, &sections)
}

fn skin_bytes(s: &BakedSkin) -> Vec<u8> {
    let mut out = Vec::new();
    put_u32(&mut out, s.inverse_bindposes.len());
    put_u32(&mut out, s.kinds.len());
    for k in &s.kinds {
        let (tag, [a, b]) = match *k {
            SkinRegionKind::Rigid { bone } => (0u8, [bone, 0]),
            SkinRegionKind::Deformable { bones } => (1u8, bones),
        };
        out.extend_from_slice(&[tag, 0]);
        out.extend_from_slice(&a.to_le_bytes());
        out.extend_from_slice(&b.to_le_bytes());
    }
    for m in &s.inverse_bindposes {
        put_f32s(&mut out, &m.to_cols_array());
    }
    put_u32(&mut out, s.more_than_two);
    put_u32(&mut out, s.normalised);
    put_u32(&mut out, s.joint_names.len());
    for name in &s.joint_names {
        put_str(&mut out, name);
    }
    out
}

/// Reads a file of assets (the sections `FILE_SECTIONS`), checking everything.
pub(super) fn read(bytes: &[u8], limits: &LoadLimits) -> Result<MrmFile, MrmError> {
    let version = container::peek(bytes).map_or(FORMAT_VERSION, |(v, _)| v);
    let sections = container::read(bytes, 0, FORMAT_VERSION, &FILE_SECTIONS)?;
    let build = read_build(section(&sections, b"SRC ")?, version)?;
    let mut r = Reader::new(section(&sections, b"KEYS")?);
    let count = r.u32()? as usize;
    within("keys", count, limits.keys)?;
    let mut keys: Vec<(String, u64)> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for _ in 0..count {
        let at = (r.offset() - r.start()) as usize;
        let key = r.string()?;
        if key.is_empty() || !seen.insert(key.clone()) {
            return Err(r.invalid(at, "a key is empty or repeated"));
        }
        keys.push((key, r.u64()?));
    }
    r.finish()?;
    let aset = section(&sections, b"ASET")?;
    let mut at = 0u64;
    let mut meshes = Vec::with_capacity(keys.len());
    // The limits hold for the whole file: every asset's vertices, triangles and decoded bytes
    // together.
    let mut tally = Tally {
        limits,
        vertices: 0,
        triangles: 0,
        decoded: 0,
    };
    for (key, length) in keys {
        let end = at
            .checked_add(length)
            .filter(|&e| e <= aset.bytes.len() as u64);
        let Some(end) = end else {
            return Err(r.invalid(0, "the entries' lengths exceed the ASET section"));
        };
        let slice = &aset.bytes[at as usize..end as usize];
        meshes.push((
            key,
            read_entry(slice, aset.offset + at, version, &mut tally)?,
        ));
        at = end;
    }
    if at != aset.bytes.len() as u64 {
        return Err(r.invalid(0, "the entries' lengths do not add up to the ASET section"));
    }
    Ok(MrmFile { build, meshes })
}

/// The sections of every entry (`key: TAG`) and, summed over its regions, of the regions
/// (`key: RGNS/TAG`), with their sizes, after checking every container.
pub(super) fn entry_sections(bytes: &[u8]) -> Result<Vec<(String, u64)>, MrmError> {
    let version = container::peek(bytes).map_or(FORMAT_VERSION, |(v, _)| v);
    let sections = container::read(bytes, 0, FORMAT_VERSION, &FILE_SECTIONS)?;
    let mut r = Reader::new(section(&sections, b"KEYS")?);
    let aset = section(&sections, b"ASET")?;
    let (mut out, mut at) = (Vec::new(), 0u64);
    for _ in 0..r.u32()? {
        let key = r.string()?;
        let length = r.u64()?;
        let slice = at
            .checked_add(length)
            .and_then(|end| aset.bytes.get(at as usize..usize::try_from(end).ok()?))
            .ok_or_else(|| r.invalid(0, "the entries' lengths exceed the ASET section"))?;
        let entry = container::read(slice, aset.offset + at, version, &ENTRY_SECTIONS)?;
        let mut inner: Vec<(String, u64)> = Vec::new();
        for s in &entry {
            let tag = container::tag_name(s.tag);
            out.push((format!("{key}: {tag}"), s.bytes.len() as u64));
            if &s.tag != b"RGNS" {
                continue;
            }
            let mut rr = Reader::new(*s);
            let count = rr.u32()? as usize;
            let lengths = rr.items::<8, _>(count, u64::from_le_bytes)?;
            let mut from = rr.offset() - s.offset;
            for length in lengths {
                let region = from
                    .checked_add(length)
                    .and_then(|end| s.bytes.get(from as usize..usize::try_from(end).ok()?))
                    .ok_or_else(|| rr.invalid(4, "the regions' lengths exceed the RGNS section"))?;
                for t in container::read(region, s.offset + from, version, &REGION_SECTIONS)? {
                    let name = format!("{key}: RGNS/{}", container::tag_name(t.tag));
                    match inner.iter_mut().find(|(n, _)| *n == name) {
                        Some(sum) => sum.1 += t.bytes.len() as u64,
                        None => inner.push((name, t.bytes.len() as u64)),
                    }
                }
                from += length;
            }
        }
        out.extend(inner);
        at += length;
    }
    Ok(out)
}

/// The build information of a file of format `version` (attribute weights from version 3;
/// older files were built without them).
fn read_build(s: Section<'_>, version: u32) -> Result<BuildInfo, MrmError> {
    let mut r = Reader::new(s);
    let source_hash = r.u64()?;
    let source_name = r.string()?;
    let partition = r.string()?;
    let writer = r.string()?;
    let has_delta = r.u8()?;
    let delta = r.f32()?;
    let options = BuildOptions {
        min_triangles: usize::try_from(r.u64()?).unwrap_or(usize::MAX),
        max_error: r.f32()?,
        border_weight: r.f64()?,
        min_normal_cos: r.f64()?,
        regularization: r.f64()?,
        local_weight: r.f64()?,
        weight_exponent: r.f64()?,
        view_dependent: r.u8()? != 0,
        pair_distance: r.f32()?,
        operator: match r.u8()? {
            0 => CollapseOperator::Edge,
            1 => CollapseOperator::Triangle,
            _ => {
                return Err(r.invalid(
                    r.offset() as usize - 1 - s.offset as usize,
                    "unknown collapse operator",
                ));
            }
        },
        normal_weight: 0.0,
        uv_weight: 0.0,
        color_weight: 0.0,
        weld_distance: 0.0,
        permissive: false,
        root_ratio: 0.0,
    };
    let mut options = options;
    if version >= 3 {
        options.normal_weight = r.f64()?;
        options.uv_weight = r.f64()?;
        options.color_weight = r.f64()?;
    }
    if version >= 4 {
        options.weld_distance = r.f32()?;
        options.permissive = r.u8()? != 0;
    }
    if version >= 5 {
        options.root_ratio = r.f32()?;
    }
    r.finish()?;
    Ok(BuildInfo {
        source_name,
        source_hash,
        partition,
        writer,
        rigid_delta: (has_delta != 0).then_some(delta),
        options,
    })
}

fn read_entry(
    bytes: &[u8],
    base: u64,
    version: u32,
    tally: &mut Tally<'_>,
) -> Result<BakedMesh, MrmError> {
    let limits = tally.limits;
    let sections = container::read(bytes, base, version, &ENTRY_SECTIONS)?;
    let mut r = Reader::new(section(&sections, b"HEAD")?);
    let n = r.u32()? as usize;
    let [attributes, has_skin, has_variable, _] = r.array::<4>()?;
    let region_count = r.u32()? as usize;
    r.finish()?;
    if has_skin > 1 || has_variable > 1 {
        return Err(r.invalid(4, "unknown flags"));
    }
    tally.vertices = tally.vertices.saturating_add(n);
    within("vertices", tally.vertices, limits.vertices)?;
    let present = |tag: &[u8; 4]| sections.iter().any(|s| &s.tag == tag);
    if present(b"SKIN") != (has_skin != 0) || present(b"VARI") != (has_variable != 0) {
        return Err(r.invalid(4, "a section is missing or present against the flags"));
    }
    let source = progressive::read_vertices(&sections, &r, n, attributes)?;
    if region_count == 0 || region_count > n {
        return Err(r.invalid(8, "the region count is zero or above the vertex count"));
    }

    let (region_of, rp) =
        Reader::whole::<4, _>(section(&sections, b"PART")?, n, u32::from_le_bytes)?;
    let mut sizes = vec![0usize; region_count];
    for (v, &id) in region_of.iter().enumerate() {
        let Some(size) = sizes.get_mut(id as usize) else {
            return Err(rp.invalid(4 * v, "a vertex names a region past the region count"));
        };
        *size += 1;
    }
    if sizes.contains(&0) {
        return Err(rp.invalid(0, "a region has no vertex"));
    }

    let (obbs, ro) =
        Reader::whole::<OBB_BYTES, _>(section(&sections, b"OBBS")?, region_count, |b| {
            let f = f32s::<15>(&b);
            Obb {
                center: Vec3::from_slice(&f[0..3]),
                axes: Mat3::from_cols_slice(&f[3..12]),
                half_extents: Vec3::from_slice(&f[12..15]),
            }
        })?;
    let finite = |o: &Obb| o.center.is_finite() && o.axes.is_finite() && o.half_extents.is_finite();
    if let Some(k) = obbs.iter().position(|o| !finite(o)) {
        return Err(ro.invalid(OBB_BYTES * k, "a box is not finite"));
    }
    // Zero extents are a flat region's (or one whose triangles meet at a point, which real
    // files have); a negative one bounds nothing.
    if let Some(k) = obbs.iter().position(|o| o.half_extents.min_element() < 0.0) {
        return Err(ro.invalid(OBB_BYTES * k + 48, "a box has a negative extent"));
    }

    let rgns = section(&sections, b"RGNS")?;
    let mut rr = Reader::new(rgns);
    if rr.u32()? as usize != region_count {
        return Err(rr.invalid(0, "the region count differs from the header's"));
    }
    let lengths = rr.items::<8, _>(region_count, u64::from_le_bytes)?;
    let mut at = rr.offset() - rgns.offset;
    let mut regions = Vec::with_capacity(region_count);
    let vertex_bytes = source.memory_bytes() / n.max(1);
    for length in lengths {
        let end = at
            .checked_add(length)
            .filter(|&e| e <= rgns.bytes.len() as u64);
        let Some(end) = end else {
            return Err(rr.invalid(4, "the regions' lengths exceed the RGNS section"));
        };
        let slice = &rgns.bytes[at as usize..end as usize];
        regions.push(read_region(
            slice,
            rgns.offset + at,
            version,
            &source,
            vertex_bytes,
            tally,
        )?);
        at = end;
    }
    if at != rgns.bytes.len() as u64 {
        return Err(rr.invalid(4, "the regions' lengths do not add up to the RGNS section"));
    }
    // What refers from one region into another stays in range: the regions named, the
    // corners a front event rewrites and the vertices it writes there.
    for (i, region) in regions.iter().enumerate() {
        let at = rgns.offset;
        let bad = |what| MrmError::Invalid {
            section: format!("RGNS region {i}"),
            offset: at,
            what,
        };
        if region.neighbors.iter().any(|&k| k as usize >= region_count) {
            return Err(bad("a neighbour is past the region count"));
        }
        for e in &region.front_events {
            let Some(target) = regions.get(e.region as usize) else {
                return Err(bad("a front event names a region past the region count"));
            };
            let corners = 3 * target.mesh.max_triangles();
            let vertices = target.global.len() as u32;
            if e.corner as usize >= corners || e.before >= vertices || e.after >= vertices {
                return Err(bad("a front event is out of its region's range"));
            }
        }
    }

    let skin = if has_skin != 0 {
        if source.joints.is_none() || source.weights.is_none() {
            return Err(r.invalid(4, "a skinned asset without joints or weights"));
        }
        Some(read_skin(
            section(&sections, b"SKIN")?,
            region_count,
            limits,
        )?)
    } else {
        None
    };
    let variable = if has_variable != 0 {
        let s = section(&sections, b"VARI")?;
        let nested = container::read(s.bytes, s.offset, version, &progressive::SECTIONS)?;
        Some(progressive::read(&nested, version, limits)?)
    } else {
        None
    };
    let root = match sections.iter().find(|s| &s.tag == b"ROOT") {
        Some(&s) => Some(read_root(
            s,
            version,
            &source,
            vertex_bytes,
            &regions,
            tally,
        )?),
        None => None,
    };
    Ok(BakedMesh {
        regions: RegionMesh::from_parts(
            Partition::from_region_of(region_of, region_count),
            regions,
            n,
            root,
        ),
        obbs,
        skin,
        variable,
    })
}

/// What a file's assets ask for so far, against the limits: their source vertices, and
/// their regions' triangles and copied vertices. (What else an asset holds, records, lists
/// and view data, is read from bytes of the file of about its size.)
struct Tally<'a> {
    limits: &'a LoadLimits,
    vertices: usize,
    triangles: usize,
    decoded: usize,
}

impl Tally<'_> {
    /// Counts a region of `local` vertices of `vertex_bytes` each (a region copies its
    /// vertices from the source) and `triangles` triangles, before it is read.
    fn add(&mut self, local: usize, vertex_bytes: usize, triangles: usize) -> Result<(), MrmError> {
        self.triangles = self.triangles.saturating_add(triangles);
        let bytes = local.saturating_mul(vertex_bytes);
        self.decoded = self.decoded.saturating_add(bytes);
        within("triangles", self.triangles, self.limits.triangles)?;
        within("decoded_bytes", self.decoded, self.limits.decoded_bytes)
    }
}

/// The `GLOB` section of a region or of the root: `local` source vertex ids, each within
/// the source's vertex table, and those vertices.
fn read_global(
    sections: &[Section<'_>],
    local: usize,
    source: &crate::mesh::IndexedMesh,
) -> Result<(Vec<u32>, crate::mesh::IndexedMesh), MrmError> {
    let (global, rg) =
        Reader::whole::<4, _>(section(sections, b"GLOB")?, local, u32::from_le_bytes)?;
    if let Some(k) = global
        .iter()
        .position(|&g| g as usize >= source.vertex_count())
    {
        return Err(rg.invalid(4 * k, "a vertex names one past the source's vertex table"));
    }
    let vertices = source.subset(&global);
    Ok((global, vertices))
}

fn read_region(
    bytes: &[u8],
    base: u64,
    version: u32,
    source: &crate::mesh::IndexedMesh,
    vertex_bytes: usize,
    tally: &mut Tally<'_>,
) -> Result<Region, MrmError> {
    let sections = container::read(bytes, base, version, &REGION_SECTIONS)?;
    let mut r = Reader::new(section(&sections, b"RGN ")?);
    let local = r.u32()? as usize;
    let own_vertices = r.u32()? as usize;
    let counts = Counts {
        vertices: local,
        base: r.u32()? as usize,
        indices: r.u32()? as usize,
        steps: r.u32()? as usize,
        corners: r.u32()? as usize,
        pairs: r.u32()? as usize,
    };
    let [narrow, has_view, _, _] = r.array::<4>()?;
    let lo = Vec3::new(r.f32()?, r.f32()?, r.f32()?);
    let hi = Vec3::new(r.f32()?, r.f32()?, r.f32()?);
    let list_counts: [usize; 5] =
        [r.u32()?, r.u32()?, r.u32()?, r.u32()?, r.u32()?].map(|x| x as usize);
    r.finish()?;
    if own_vertices == 0 || own_vertices > local {
        return Err(r.invalid(4, "the own vertex count is zero or above the local one"));
    }
    tally.add(local, vertex_bytes, counts.indices / 3)?;
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(r.invalid(32, "the bounds are not finite"));
    }
    if lo.cmpgt(hi).any() {
        return Err(r.invalid(32, "the bounds' minimum is above their maximum"));
    }
    let (global, vertices) = read_global(&sections, local, source)?;
    let mesh = progressive::read_mesh(&sections, &r, version, vertices, &counts, narrow, has_view)?;

    let mut rl = Reader::new(section(&sections, b"LIST")?);
    let [nb, nf, nn, np, ne] = list_counts;
    let border = rl.items::<4, _>(nb, u32::from_le_bytes)?;
    let fin_prone = rl.items::<4, _>(nf, u32::from_le_bytes)?;
    let neighbors = rl.items::<4, _>(nn, u32::from_le_bytes)?;
    let position_of = rl.items::<4, _>(np, u32::from_le_bytes)?;
    let front_events = rl.items::<20, _>(ne, |b| {
        let x: [u32; 5] = std::array::from_fn(|i| {
            u32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
        });
        FrontEvent {
            step: x[0],
            region: x[1],
            corner: x[2],
            before: x[3],
            after: x[4],
        }
    })?;
    rl.finish()?;
    let triangles = counts.indices / 3;
    if border
        .iter()
        .chain(&fin_prone)
        .any(|&t| t as usize >= triangles)
    {
        return Err(rl.invalid(0, "a border triangle is past the region's triangles"));
    }
    if !(position_of.is_empty() || position_of.len() == local)
        || position_of.iter().any(|&v| v as usize >= local)
    {
        return Err(rl.invalid(4 * (nb + nf + nn), "a position link is out of range"));
    }
    Ok(Region {
        mesh,
        global,
        border,
        fin_prone,
        front_events,
        neighbors,
        own_vertices,
        bounds: (lo, hi),
        position_of,
    })
}

fn read_skin(
    s: Section<'_>,
    region_count: usize,
    limits: &LoadLimits,
) -> Result<BakedSkin, MrmError> {
    let mut r = Reader::new(s);
    let joints = r.u32()? as usize;
    within("joints", joints, limits.joints)?;
    if joints == 0 || joints > usize::from(u16::MAX) + 1 {
        return Err(r.invalid(0, "the joint count is zero or above 65,536"));
    }
    if r.u32()? as usize != region_count {
        return Err(r.invalid(4, "the kinds do not match the region count"));
    }
    let at = (r.offset() - s.offset) as usize;
    let raw = r.items::<6, _>(region_count, |b| {
        (
            b[0],
            u16::from_le_bytes([b[2], b[3]]),
            u16::from_le_bytes([b[4], b[5]]),
        )
    })?;
    let mut kinds = Vec::with_capacity(region_count);
    for (k, (tag, a, b)) in raw.into_iter().enumerate() {
        let kind = match tag {
            0 if b == 0 => SkinRegionKind::Rigid { bone: a },
            1 if a < b => SkinRegionKind::Deformable { bones: [a, b] },
            _ => {
                return Err(r.invalid(
                    at + 6 * k,
                    "a region kind is unknown or its bones unordered",
                ));
            }
        };
        if usize::from(a.max(b)) >= joints {
            return Err(r.invalid(at + 6 * k, "a region's bone is past the joint count"));
        }
        kinds.push(kind);
    }
    let at = (r.offset() - s.offset) as usize;
    let inverse_bindposes = r.items::<64, _>(joints, |b| Mat4::from_cols_array(&f32s::<16>(&b)))?;
    if let Some(k) = inverse_bindposes.iter().position(|m| !m.is_finite()) {
        return Err(r.invalid(at + 64 * k, "an inverse bind matrix is not finite"));
    }
    let more_than_two = r.u32()? as usize;
    let normalised = r.u32()? as usize;
    let names = r.u32()? as usize;
    if names != 0 && names != joints {
        return Err(r.invalid(
            (r.offset() - s.offset) as usize - 4,
            "a joint name count other than 0 or the joint count",
        ));
    }
    let mut joint_names = Vec::new();
    for _ in 0..names {
        joint_names.push(r.string()?);
    }
    r.finish()?;
    Ok(BakedSkin {
        kinds,
        inverse_bindposes,
        joint_names,
        more_than_two,
        normalised,
    })
}
