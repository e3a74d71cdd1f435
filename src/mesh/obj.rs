//! Wavefront OBJ import and export.
//!
//! Import reads `v`, `vt`, `vn` and `f` lines and ignores every other statement (`o`, `g`,
//! `s`, `usemtl`, `l`, ...). OBJ indexes positions, texture coordinates and normals
//! separately; an [`IndexedMesh`] has one index per vertex, so every distinct
//! `(v, vt, vn)` combination becomes one vertex. Where a UV or normal seam runs, several
//! vertices therefore share one position, which is what the simplifier expects (see
//! [`weld_positions`](super::weld_positions)).

use super::{IndexedMesh, LoadLimits, MeshError, MeshResult};
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::io::{self, BufWriter, Write};
use std::ops::Range;
use std::path::Path;

/// Marks a corner that has no texture coordinate or normal index.
const NONE: u32 = u32::MAX;

/// One face corner: 0-based indices into the `v`, `vt` and `vn` lists ([`NONE`] if absent).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct Corner {
    v: u32,
    vt: u32,
    vn: u32,
}

/// Reads and parses an OBJ file within the default [`LoadLimits`]; see [`parse_obj`].
///
/// Bytes that are not UTF-8 (in comments or material names, say) are replaced, not rejected.
///
/// # Errors
/// [`MeshError::Io`] when the file cannot be read, otherwise the errors of
/// [`parse_obj_with_limits`].
pub fn load_obj(path: &Path) -> MeshResult<IndexedMesh> {
    let limits = LoadLimits::default();
    parse_obj_with_limits(&String::from_utf8_lossy(&limits.read_file(path)?), &limits)
}

/// Parses OBJ text into an indexed triangle mesh.
///
/// Faces may use `v`, `v/vt`, `v//vn` or `v/vt/vn` corners, with 1-based or negative
/// (relative) indices; lines may end in `\n`, `\r\n` or `\r`, and a UTF-8 byte order mark
/// is skipped. Convex polygons are fans from their first corner; concave ones are ear-clipped
/// in their plane (up to [`MAX_CONCAVE_CORNERS`] corners). When no face corner refers to a `vt` or
/// `vn`, vertex `i` of the mesh is exactly the `i`-th `v` line, unreferenced ones included.
/// Otherwise the mesh has one vertex per distinct corner combination, in order of first use.
/// If only some corners have a texture coordinate the others get `(0, 0)`; if only some have a
/// normal, normals are dropped for the whole mesh (a zero normal would be worse than none).
///
/// The mesh is not validated; call [`IndexedMesh::validate`] before using it.
///
/// Parsed within the default [`LoadLimits`]; see [`parse_obj_with_limits`].
///
/// # Errors
/// [`MeshError::Parse`] naming the line of a malformed statement, a non-finite number, a face
/// with fewer than three corners, a concave face of more than [`MAX_CONCAVE_CORNERS`]
/// corners, or an index that is zero or refers to no vertex; [`MeshError::LimitExceeded`] as
/// [`parse_obj_with_limits`].
///
/// # Example
/// ```
/// use bevy_aslod::mesh::parse_obj;
///
/// let mesh = parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")?;
/// assert_eq!(mesh.vertex_count(), 4);
/// assert_eq!(mesh.indices, vec![0, 1, 2, 0, 2, 3]);
/// # Ok::<(), bevy_aslod::mesh::MeshError>(())
/// ```
pub fn parse_obj(text: &str) -> MeshResult<IndexedMesh> {
    parse_obj_with_limits(text, &LoadLimits::default())
}

/// [`parse_obj`] within `limits`: a first pass counts the `v`, `vt` and `vn` lines (each
/// list at most [`vertices`](LoadLimits::vertices)) and the triangles the faces make (at
/// most [`triangles`](LoadLimits::triangles)) before anything is stored.
///
/// # Errors
/// As [`parse_obj`], and [`MeshError::LimitExceeded`] naming the limit the text exceeds.
///
/// # Example
/// ```
/// use bevy_aslod::mesh::{LoadLimits, MeshError, parse_obj_with_limits};
///
/// let limits = LoadLimits { triangles: 1, ..LoadLimits::default() };
/// let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
/// let e = parse_obj_with_limits(quad, &limits).unwrap_err();
/// assert!(matches!(e, MeshError::LimitExceeded { limit: "triangles", value: 2, .. }));
/// ```
pub fn parse_obj_with_limits(text: &str, limits: &LoadLimits) -> MeshResult<IndexedMesh> {
    let mut counts = [0u64; 3];
    let mut triangle_count = 0u64;
    for raw in lines(text) {
        let content = raw.split_once('#').map_or(raw, |(before, _)| before);
        let mut tokens = content.split_whitespace();
        match tokens.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            // A face of n corners is n − 2 triangles (one with fewer is an error below).
            Some("f") => triangle_count += (tokens.count() as u64).saturating_sub(2),
            _ => {}
        }
    }
    for count in counts {
        LoadLimits::check("vertices", count, limits.vertices)?;
    }
    LoadLimits::check("triangles", triangle_count, limits.triangles)?;

    let mut positions: Vec<Vec3> = Vec::new();
    let mut texcoords: Vec<Vec2> = Vec::new();
    let mut normals: Vec<Vec3> = Vec::new();
    // Every face's corners, and its line, so that a range error found at the end can name it.
    let mut corners: Vec<Corner> = Vec::new();
    let mut faces: Vec<(Range<usize>, usize)> = Vec::new();

    for (line_index, raw) in lines(text).enumerate() {
        let line_number = line_index + 1;
        let err = |message: String| MeshError::parse("OBJ", format!("line {line_number}"), message);
        let content = raw.split_once('#').map_or(raw, |(before, _)| before);
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        match keyword {
            "v" => positions.push(Vec3::from(
                parse_floats::<3>(&mut tokens, 3, "v").map_err(err)?,
            )),
            "vt" => texcoords.push(Vec2::from(
                parse_floats::<2>(&mut tokens, 1, "vt").map_err(err)?,
            )),
            "vn" => normals.push(Vec3::from(
                parse_floats::<3>(&mut tokens, 3, "vn").map_err(err)?,
            )),
            "f" => {
                let start = corners.len();
                for token in tokens {
                    corners.push(
                        parse_corner(token, [positions.len(), texcoords.len(), normals.len()])
                            .map_err(err)?,
                    );
                }
                if corners.len() - start < 3 {
                    return Err(err(format!(
                        "a face needs at least 3 vertices, found {}",
                        corners.len() - start
                    )));
                }
                faces.push((start..corners.len(), line_number));
            }
            _ => {}
        }
    }

    // Positive indices may refer forward, so ranges are checked once every list is complete.
    for (range, line) in &faces {
        for c in &corners[range.clone()] {
            let checks = [
                ("v", c.v, positions.len()),
                ("vt", c.vt, texcoords.len()),
                ("vn", c.vn, normals.len()),
            ];
            for (what, index, len) in checks {
                if index != NONE && index as usize >= len {
                    return Err(MeshError::parse(
                        "OBJ",
                        format!("line {line}"),
                        format!(
                            "face refers to {what} {}, but the file has only {len} {what} lines",
                            u64::from(index) + 1
                        ),
                    ));
                }
            }
        }
    }
    let mut triangles: Vec<[Corner; 3]> = Vec::with_capacity(triangle_count as usize);
    for (range, line) in &faces {
        let face = &corners[range.clone()];
        let points: Vec<Vec3> = face.iter().map(|c| positions[c.v as usize]).collect();
        let order = triangulate(&points)
            .map_err(|message| MeshError::parse("OBJ", format!("line {line}"), message))?;
        triangles.extend(order.iter().map(|t| t.map(|k| face[k])));
    }

    let any_vt = triangles.iter().flatten().any(|c| c.vt != NONE);
    let any_vn = triangles.iter().flatten().any(|c| c.vn != NONE);
    if !any_vt && !any_vn {
        let indices = triangles.iter().flatten().map(|c| c.v).collect();
        return Ok(IndexedMesh::new(positions, indices));
    }

    let all_vn = triangles.iter().flatten().all(|c| c.vn != NONE);
    if any_vn && !all_vn {
        log::warn!("OBJ: only some face corners have normals; dropping normals");
    }
    let keep_vn = all_vn;

    let mut mesh = IndexedMesh {
        uvs: any_vt.then(Vec::new),
        normals: keep_vn.then(Vec::new),
        ..IndexedMesh::default()
    };
    let mut vertex_of: HashMap<Corner, u32> = HashMap::new();
    mesh.indices.reserve(triangles.len() * 3);
    for &c in triangles.iter().flatten() {
        let key = Corner {
            vn: if keep_vn { c.vn } else { NONE },
            ..c
        };
        let next = mesh.positions.len() as u32;
        let vertex = *vertex_of.entry(key).or_insert_with(|| {
            mesh.positions.push(positions[c.v as usize]);
            if let Some(uvs) = &mut mesh.uvs {
                uvs.push(texcoords.get(c.vt as usize).copied().unwrap_or(Vec2::ZERO));
            }
            if let Some(ns) = &mut mesh.normals {
                ns.push(normals[c.vn as usize]);
            }
            next
        });
        mesh.indices.push(vertex);
    }
    Ok(mesh)
}

/// The lines of `text`, ended by `\n`, `\r\n` or a lone `\r` (old Mac files), after a
/// UTF-8 byte order mark if it starts with one.
fn lines(text: &str) -> impl Iterator<Item = &str> {
    let mut rest = text.strip_prefix('\u{feff}').unwrap_or(text);
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let (line, after) = match rest.find(['\r', '\n']) {
            Some(i) if rest[i..].starts_with("\r\n") => (&rest[..i], &rest[i + 2..]),
            Some(i) => (&rest[..i], &rest[i + 1..]),
            None => (rest, ""),
        };
        rest = after;
        Some(line)
    })
}

/// The most corners of a concave face that are triangulated (ear clipping costs up to the
/// cube of the corners, so a bound keeps reading linear in the file); convex faces of any
/// size are fans.
pub const MAX_CONCAVE_CORNERS: usize = 256;

/// Triangles of one polygon face, as corner positions in `points`, in the face's winding.
/// A convex (or flat-degenerate) face is a fan from its first corner; a concave one is
/// ear-clipped in its own plane, so that no triangle lies outside its outline.
///
/// # Errors
/// A concave face of more than [`MAX_CONCAVE_CORNERS`] corners.
fn triangulate(points: &[Vec3]) -> Result<Vec<[usize; 3]>, String> {
    let n = points.len();
    let fan = || (1..n - 1).map(|i| [0, i, i + 1]).collect();
    if n == 3 {
        return Ok(fan());
    }
    // Newell's normal, and the face projected on the plane across its largest component.
    let mut normal = Vec3::ZERO;
    for (i, a) in points.iter().enumerate() {
        let b = points[(i + 1) % n];
        normal += Vec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    let axis = normal.abs().max_position();
    if !normal.is_finite() || normal[axis] == 0.0 {
        return Ok(fan());
    }
    let (u, v) = match axis {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    };
    let sign = normal[axis].signum();
    let flat: Vec<Vec2> = points
        .iter()
        .map(|p| Vec2::new(p[u], p[v]) * Vec2::new(1.0, sign))
        .collect();
    // Counter-clockwise now: a corner is convex where its turn is positive.
    let turn = |a: usize, b: usize, c: usize| (flat[b] - flat[a]).perp_dot(flat[c] - flat[b]);
    if (0..n).all(|i| turn((i + n - 1) % n, i, (i + 1) % n) >= 0.0) {
        return Ok(fan());
    }
    if n > MAX_CONCAVE_CORNERS {
        return Err(format!(
            "a concave face of {n} corners; at most {MAX_CONCAVE_CORNERS} are triangulated"
        ));
    }
    let inside = |p: Vec2, [a, b, c]: [usize; 3]| {
        let (a, b, c) = (flat[a], flat[b], flat[c]);
        (b - a).perp_dot(p - a) > 0.0
            && (c - b).perp_dot(p - b) > 0.0
            && (a - c).perp_dot(p - c) > 0.0
    };
    let mut ring: Vec<usize> = (0..n).collect();
    let mut out = Vec::with_capacity(n - 2);
    let mut i = 0;
    let mut failures = 0;
    while ring.len() > 3 {
        let m = ring.len();
        let tri = [ring[(i + m - 1) % m], ring[i % m], ring[(i + 1) % m]];
        let ear = turn(tri[0], tri[1], tri[2]) > 0.0
            && ring
                .iter()
                .all(|&k| tri.contains(&k) || !inside(flat[k], tri));
        // A ring with no ear left (a self-intersecting face) clips anyway, so the face keeps
        // its corners - 2 triangles.
        if ear || failures >= m {
            out.push(tri);
            let removed = i % m;
            ring.remove(removed);
            failures = 0;
            // Next, the corner before the clipped one: its angle changed.
            i = if removed == 0 { m - 2 } else { removed - 1 };
        } else {
            failures += 1;
            i = (i + 1) % m;
        }
    }
    out.push([ring[0], ring[1], ring[2]]);
    Ok(out)
}

/// Parses up to `N` floats (at least `required`; missing optional ones are 0). Extra numbers,
/// such as a `w` or the vertex colours some tools append to `v`, are ignored.
fn parse_floats<'a, const N: usize>(
    tokens: &mut impl Iterator<Item = &'a str>,
    required: usize,
    keyword: &str,
) -> Result<[f32; N], String> {
    let mut out = [0.0; N];
    for (i, slot) in out.iter_mut().enumerate() {
        let Some(token) = tokens.next() else {
            if i < required {
                return Err(format!("`{keyword}` needs {required} numbers, found {i}"));
            }
            break;
        };
        let value: f32 = token
            .parse()
            .map_err(|_| format!("`{keyword}`: `{token}` is not a number"))?;
        if !value.is_finite() {
            return Err(format!("`{keyword}`: non-finite number `{token}`"));
        }
        *slot = value;
    }
    Ok(out)
}

/// Parses a face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`. `counts` are the numbers of `v`,
/// `vt` and `vn` lines read so far, which negative indices are relative to.
fn parse_corner(token: &str, counts: [usize; 3]) -> Result<Corner, String> {
    const NAMES: [&str; 3] = ["v", "vt", "vn"];
    let mut out = [NONE; 3];
    let mut parts = token.split('/');
    for (slot, (name, count)) in out.iter_mut().zip(NAMES.iter().zip(counts)) {
        match parts.next() {
            Some("") if *name != "v" => {}
            Some(part) => *slot = resolve_index(part, count, name)?,
            None => break,
        }
    }
    if parts.next().is_some() {
        return Err(format!("malformed face corner `{token}`"));
    }
    Ok(Corner {
        v: out[0],
        vt: out[1],
        vn: out[2],
    })
}

/// Turns a 1-based or negative (relative) OBJ index into a 0-based one.
fn resolve_index(part: &str, count: usize, name: &str) -> Result<u32, String> {
    let index: i64 = part
        .parse()
        .map_err(|_| format!("face corner: `{part}` is not a {name} index"))?;
    let resolved = match index {
        0 => {
            return Err(format!(
                "{name} index 0 is invalid (OBJ indices start at 1)"
            ));
        }
        i if i > 0 => i - 1,
        // -1 is the most recent line, so the index counts back from the current length.
        i => {
            let r = count as i64 + i;
            if r < 0 {
                return Err(format!(
                    "relative {name} index {i} reaches before the first of {count} {name} lines"
                ));
            }
            r
        }
    };
    // NONE is reserved, so the largest usable index is one below it.
    u32::try_from(resolved)
        .ok()
        .filter(|&r| r != NONE)
        .ok_or_else(|| format!("{name} index {index} is too large"))
}

/// Writes a mesh as OBJ: `v` lines (`v x y z r g b` where the mesh has vertex colours,
/// [`COLOR_ID`](super::COLOR_ID)), then `vt` and `vn` lines where the mesh has them, then one
/// `f` line per triangle with 1-based indices (`a`, `a/a`, `a//a` or `a/a/a`).
///
/// Coordinates are written in Rust's shortest round-trip form, so [`parse_obj`] reads back
/// exactly the same floats.
///
/// # Errors
/// An [`io::ErrorKind::InvalidInput`] error when an attribute does not have one entry per
/// position or an index is out of range, and any error of the writer.
pub fn write_obj(mesh: &IndexedMesh, w: &mut impl Write) -> io::Result<()> {
    write_obj_groups(mesh, &[(String::new(), 0..mesh.triangle_count())], w)
}

/// Writes a mesh as OBJ like [`write_obj`], with its triangles split into named groups.
///
/// Each `(name, range)` writes `g name` followed by the triangles in `range` (triangle, not
/// index, numbers). An empty name writes no `g` line. Whitespace in a name becomes `_`, since
/// OBJ would read it as several groups. Triangles outside every range are not written;
/// overlapping ranges write their triangles twice.
///
/// # Errors
/// An [`io::ErrorKind::InvalidInput`] error when a range reaches past the last triangle, an
/// attribute does not have one entry per position or an index is out of range, and any error
/// of the writer.
pub fn write_obj_groups(
    mesh: &IndexedMesh,
    groups: &[(String, Range<usize>)],
    w: &mut impl Write,
) -> io::Result<()> {
    check_writable(mesh, groups)?;
    let mut out = BufWriter::new(w);
    writeln!(
        out,
        "# bevy_aslod: {} vertices, {} triangles",
        mesh.vertex_count(),
        mesh.triangle_count()
    )?;
    // Vertex colours go on the `v` lines (`v x y z r g b`, the extension MeshLab and Blender
    // read); OBJ has no alpha.
    let colors = mesh
        .attribute(super::COLOR_ID)
        .and_then(|c| c.to_f32::<4>())
        .filter(|c| c.len() == mesh.positions.len());
    for (k, p) in mesh.positions.iter().enumerate() {
        match colors.as_ref().map(|c| c[k]) {
            Some([r, g, b, _]) => writeln!(out, "v {} {} {} {r} {g} {b}", p.x, p.y, p.z)?,
            None => writeln!(out, "v {} {} {}", p.x, p.y, p.z)?,
        }
    }
    for t in mesh.uvs.iter().flatten() {
        writeln!(out, "vt {} {}", t.x, t.y)?;
    }
    for n in mesh.normals.iter().flatten() {
        writeln!(out, "vn {} {} {}", n.x, n.y, n.z)?;
    }
    let (has_vt, has_vn) = (mesh.uvs.is_some(), mesh.normals.is_some());
    for (name, range) in groups {
        if !name.is_empty() {
            let name: String = name
                .chars()
                .map(|c| if c.is_whitespace() { '_' } else { c })
                .collect();
            writeln!(out, "g {name}")?;
        }
        for tri in mesh.indices[3 * range.start..3 * range.end].chunks_exact(3) {
            out.write_all(b"f")?;
            for &i in tri {
                let i = u64::from(i) + 1;
                match (has_vt, has_vn) {
                    (false, false) => write!(out, " {i}")?,
                    (true, false) => write!(out, " {i}/{i}")?,
                    (false, true) => write!(out, " {i}//{i}")?,
                    (true, true) => write!(out, " {i}/{i}/{i}")?,
                }
            }
            out.write_all(b"\n")?;
        }
    }
    out.flush()
}

/// Rejects what would write a broken file (or slice out of bounds).
fn check_writable(mesh: &IndexedMesh, groups: &[(String, Range<usize>)]) -> io::Result<()> {
    let invalid = |message: String| io::Error::new(io::ErrorKind::InvalidInput, message);
    let n = mesh.vertex_count();
    let lens = [
        ("normals", mesh.normals.as_ref().map(Vec::len)),
        ("uvs", mesh.uvs.as_ref().map(Vec::len)),
    ];
    for (name, len) in lens {
        if let Some(len) = len.filter(|&len| len != n) {
            return Err(invalid(format!("{len} {name} for {n} positions")));
        }
    }
    if let Some(&i) = mesh.indices.iter().find(|&&i| i as usize >= n) {
        return Err(invalid(format!("index {i} out of range ({n} vertices)")));
    }
    let triangles = mesh.triangle_count();
    if let Some((name, range)) = groups
        .iter()
        .find(|(_, r)| r.start > r.end || r.end > triangles)
    {
        return Err(invalid(format!(
            "group `{name}`: triangles {range:?} out of range ({triangles} triangles)"
        )));
    }
    Ok(())
}
