//! Reading triangle meshes: Wavefront OBJ, OFF and PLY (ASCII and binary).
//! Polygons are split into fans; meshes without normals get area-weighted
//! ones; meshes without texture coordinates get a box projection. Errors
//! name the file and the line or element that is wrong.

use crate::content::ContentError;
use crate::math::Vec3;
use crate::mesh::{Mesh, UvProjection};
use std::collections::HashMap;
use std::path::Path;

/// A mesh file that could not be read.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct MeshError {
    /// The file.
    pub path: String,
    /// What is wrong with it.
    pub message: String,
}

/// The file extensions [`read_mesh`] understands.
pub const MESH_EXTENSIONS: [&str; 3] = ["obj", "off", "ply"];

/// Reads an OBJ, OFF or PLY file (by extension) into a valid mesh with
/// normals and texture coordinates.
pub fn read_mesh(path: &Path) -> Result<Mesh, MeshError> {
    let fail = |message: String| MeshError {
        path: path.display().to_string(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| fail(format!("cannot read: {e}")))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_lowercase)
        .unwrap_or_default();
    let mut mesh = match ext.as_str() {
        "obj" => parse_obj(&String::from_utf8_lossy(&bytes)),
        "off" => parse_off(&String::from_utf8_lossy(&bytes)),
        "ply" => parse_ply(&bytes),
        _ => Err(ContentError(format!(
            "unknown mesh format (expected one of {})",
            MESH_EXTENSIONS.join(", ")
        ))),
    }
    .map_err(|e| fail(e.0))?;
    finish(&mut mesh).map_err(|e| fail(e.0))?;
    Ok(mesh)
}

/// The mesh as Wavefront OBJ text, with texture coordinates and normals
/// (one `v`/`vt`/`vn` triple per vertex), readable by [`read_mesh`] and by
/// other tools.
pub fn obj_text(mesh: &Mesh) -> String {
    use std::fmt::Write;
    let mut out = String::with_capacity(mesh.positions.len() * 80);
    for p in &mesh.positions {
        let _ = writeln!(out, "v {} {} {}", p.x, p.y, p.z);
    }
    for [u, v] in &mesh.uvs {
        let _ = writeln!(out, "vt {u} {v}");
    }
    for n in &mesh.normals {
        let _ = writeln!(out, "vn {} {} {}", n.x, n.y, n.z);
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        let _ = writeln!(out, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}");
    }
    out
}

/// Fills in what a file left out (normals, UVs) and validates.
fn finish(mesh: &mut Mesh) -> Result<(), ContentError> {
    if mesh.triangles.is_empty() {
        return Err("no faces".into());
    }
    if mesh.normals.len() != mesh.positions.len() {
        mesh.compute_normals();
    }
    if mesh.uvs.len() != mesh.positions.len() {
        mesh.project_uvs(UvProjection::Box);
    }
    mesh.validate().map_err(|e| ContentError(e.0))
}

/// Triangle fan of a polygon.
fn fan(poly: &[u32], out: &mut Vec<[u32; 3]>) {
    for k in 1..poly.len().saturating_sub(1) {
        out.push([poly[0], poly[k], poly[k + 1]]);
    }
}

fn parse_floats<const N: usize>(parts: &mut std::str::SplitWhitespace) -> Option<[f32; N]> {
    let mut v = [0f32; N];
    for x in v.iter_mut() {
        *x = parts.next()?.parse().ok()?;
    }
    Some(v)
}

/// OBJ: `v`, `vt`, `vn`, `f` with `v`, `v/vt`, `v//vn`, `v/vt/vn` corners and
/// negative (relative) indices. Corners with different attribute triples
/// become separate vertices. Other statements are ignored.
fn parse_obj(text: &str) -> Result<Mesh, ContentError> {
    let (mut pos, mut tex, mut nor) = (Vec::new(), Vec::new(), Vec::new());
    let mut mesh = Mesh::default();
    let mut corners: HashMap<(usize, Option<usize>, Option<usize>), u32> = HashMap::new();
    let (mut any_tex, mut any_nor) = (true, true);
    for (line_no, line) in text.lines().enumerate() {
        let bad = |what: &str| format!("line {}: {what}", line_no + 1);
        let mut parts = line.split_whitespace();
        match parts.next() {
            Some("v") => pos.push(Vec3::from(
                parse_floats::<3>(&mut parts).ok_or_else(|| bad("bad vertex"))?,
            )),
            Some("vt") => {
                let [u, v] =
                    parse_floats::<2>(&mut parts).ok_or_else(|| bad("bad texture coordinate"))?;
                tex.push([u, v]);
            }
            Some("vn") => nor.push(
                Vec3::from(parse_floats::<3>(&mut parts).ok_or_else(|| bad("bad normal"))?)
                    .normalised(),
            ),
            Some("f") => {
                let mut poly = Vec::new();
                for corner in parts {
                    let mut fields = corner.split('/');
                    let resolve = |s: Option<&str>, n: usize| -> Result<Option<usize>, String> {
                        match s {
                            None | Some("") => Ok(None),
                            Some(s) => {
                                let i: i64 = s.parse().map_err(|_| bad("bad face index"))?;
                                let idx = if i < 0 { n as i64 + i } else { i - 1 };
                                if idx < 0 || idx as usize >= n {
                                    return Err(bad(&format!("face index {i} out of range")));
                                }
                                Ok(Some(idx as usize))
                            }
                        }
                    };
                    let v = resolve(fields.next(), pos.len())?
                        .ok_or_else(|| bad("empty face corner"))?;
                    let t = resolve(fields.next(), tex.len())?;
                    let n = resolve(fields.next(), nor.len())?;
                    any_tex &= t.is_some();
                    any_nor &= n.is_some();
                    let next = mesh.positions.len() as u32;
                    let id = *corners.entry((v, t, n)).or_insert_with(|| {
                        mesh.positions.push(pos[v]);
                        mesh.uvs.push(t.map_or([0.0, 0.0], |t| tex[t]));
                        mesh.normals.push(n.map_or(Vec3::Z, |n| nor[n]));
                        next
                    });
                    poly.push(id);
                }
                // Exporters write edges as two-corner faces; like other
                // readers, skip them: they have no surface.
                if poly.len() >= 3 {
                    fan(&poly, &mut mesh.triangles);
                }
            }
            _ => {}
        }
    }
    // Attributes count only when every corner had them.
    if !any_tex {
        mesh.uvs.clear();
    }
    if !any_nor {
        mesh.normals.clear();
    }
    Ok(mesh)
}

/// OFF (and COFF/NOFF headers): counts, vertices, then `n i0 i1 ...` faces.
/// `#` comments are skipped.
fn parse_off(text: &str) -> Result<Mesh, ContentError> {
    let mut tokens = text
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .flat_map(str::split_whitespace);
    let header = tokens.next().ok_or("empty file")?;
    if !header.ends_with("OFF") {
        return Err(format!("not an OFF file (header {header:?})").into());
    }
    let mut number = |what: &str| -> Result<f64, String> {
        tokens
            .next()
            .ok_or_else(|| format!("ends early, reading {what}"))?
            .parse::<f64>()
            .map_err(|_| format!("bad number reading {what}"))
    };
    let (nv, nf) = (
        number("vertex count")? as usize,
        number("face count")? as usize,
    );
    number("edge count")?;
    let mut mesh = Mesh::default();
    let colours = header.starts_with('C');
    let normals = header.starts_with('N');
    for i in 0..nv {
        let what = format!("vertex {i}");
        let p = Vec3::new(
            number(&what)? as f32,
            number(&what)? as f32,
            number(&what)? as f32,
        );
        mesh.positions.push(p);
        if normals {
            for _ in 0..3 {
                number(&what)?;
            }
        }
        if colours {
            for _ in 0..4 {
                number(&what)?;
            }
        }
    }
    for i in 0..nf {
        let what = format!("face {i}");
        let n = number(&what)? as usize;
        let mut poly = Vec::with_capacity(n);
        for _ in 0..n {
            let v = number(&what)? as usize;
            if v >= nv {
                return Err(format!("face {i} indexes vertex {v} of {nv}").into());
            }
            poly.push(v as u32);
        }
        fan(&poly, &mut mesh.triangles);
        // A face may carry a colour after its indices; it ends at the line,
        // which the token stream cannot see, so colour faces are not read.
    }
    Ok(mesh)
}

/// A PLY property's scalar type.
#[derive(Clone, Copy, Debug)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn read(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! get {
            ($t:ty) => {{
                let a = b[..std::mem::size_of::<$t>()].try_into().unwrap();
                (if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16),
            Scalar::U16 => get!(u16),
            Scalar::I32 => get!(i32),
            Scalar::U32 => get!(u32),
            Scalar::F32 => get!(f32),
            Scalar::F64 => get!(f64),
        }
    }
}

/// A PLY property: a scalar, or a list with a count type.
#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: Scalar,
    list_count: Option<Scalar>,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

/// Values of one element instance: scalars and lists by property index.
type Row = Vec<Vec<f64>>;

/// A source of PLY values, ASCII or binary.
enum PlyBody<'a> {
    Ascii(std::str::SplitWhitespace<'a>),
    Binary {
        data: &'a [u8],
        at: usize,
        big_endian: bool,
    },
}

impl PlyBody<'_> {
    fn value(&mut self, kind: Scalar) -> Result<f64, ContentError> {
        match self {
            PlyBody::Ascii(tokens) => tokens
                .next()
                .ok_or("ends early")?
                .parse()
                .map_err(|_| "bad number".into()),
            PlyBody::Binary {
                data,
                at,
                big_endian,
            } => {
                let end = *at + kind.size();
                let bytes = data.get(*at..end).ok_or("ends early")?;
                *at = end;
                Ok(kind.read(bytes, *big_endian))
            }
        }
    }

    fn row(&mut self, e: &Element) -> Result<Row, ContentError> {
        e.properties
            .iter()
            .map(|p| match p.list_count {
                None => Ok(vec![self.value(p.kind)?]),
                Some(count) => {
                    let n = self.value(count)? as usize;
                    (0..n).map(|_| self.value(p.kind)).collect()
                }
            })
            .collect()
    }
}

/// PLY: the `vertex` element's `x y z` (and `nx ny nz`, `u v`/`s t`/
/// `texture_u texture_v` when present) and the `face` element's
/// `vertex_indices`/`vertex_index` lists. ASCII and binary in either byte order.
fn parse_ply(bytes: &[u8]) -> Result<Mesh, ContentError> {
    let header_end = bytes
        .windows(10)
        .position(|w| w == b"end_header")
        .ok_or("no end_header: not a PLY file")?;
    let header = String::from_utf8_lossy(&bytes[..header_end]);
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err("does not start with \"ply\"".into());
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in lines {
        let parts: Vec<&str> = line.split_whitespace().collect();
        match parts.as_slice() {
            ["format", f, _] => format = Some(f.to_string()),
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count
                    .parse()
                    .map_err(|_| format!("bad element count in {line:?}"))?,
                properties: vec![],
            }),
            ["property", "list", count, kind, name] => {
                let e = elements.last_mut().ok_or("property before any element")?;
                e.properties.push(Property {
                    name: name.to_string(),
                    kind: Scalar::parse(kind).ok_or_else(|| format!("unknown type {kind}"))?,
                    list_count: Some(
                        Scalar::parse(count).ok_or_else(|| format!("unknown type {count}"))?,
                    ),
                });
            }
            ["property", kind, name] => {
                let e = elements.last_mut().ok_or("property before any element")?;
                e.properties.push(Property {
                    name: name.to_string(),
                    kind: Scalar::parse(kind).ok_or_else(|| format!("unknown type {kind}"))?,
                    list_count: None,
                });
            }
            _ => {}
        }
    }
    // The body starts after the newline that ends the header.
    let mut body_start = header_end + 10;
    while body_start < bytes.len() && bytes[body_start] != b'\n' {
        body_start += 1;
    }
    let body = &bytes[(body_start + 1).min(bytes.len())..];
    let mut reader = match format.as_deref() {
        Some("ascii") => PlyBody::Ascii(
            std::str::from_utf8(body)
                .map_err(|_| "ASCII body is not text")?
                .split_whitespace(),
        ),
        Some("binary_little_endian") => PlyBody::Binary {
            data: body,
            at: 0,
            big_endian: false,
        },
        Some("binary_big_endian") => PlyBody::Binary {
            data: body,
            at: 0,
            big_endian: true,
        },
        other => return Err(format!("unknown format {other:?}").into()),
    };
    let mut mesh = Mesh::default();
    let (mut normals, mut uvs) = (Vec::new(), Vec::new());
    for e in &elements {
        let index = |names: &[&str]| {
            e.properties
                .iter()
                .position(|p| names.contains(&p.name.as_str()))
        };
        let xyz = [index(&["x"]), index(&["y"]), index(&["z"])];
        let nxyz = [index(&["nx"]), index(&["ny"]), index(&["nz"])];
        let uv = [
            index(&["u", "s", "texture_u"]),
            index(&["v", "t", "texture_v"]),
        ];
        let faces = index(&["vertex_indices", "vertex_index"]);
        for i in 0..e.count {
            let row = reader.row(e).map_err(|m| format!("{} {i}: {m}", e.name))?;
            if e.name == "vertex" {
                let get = |k: Option<usize>| k.map(|k| row[k][0] as f32);
                let [Some(x), Some(y), Some(z)] = xyz.map(get) else {
                    return Err("vertex element without x, y, z".into());
                };
                mesh.positions.push(Vec3::new(x, y, z));
                if let [Some(x), Some(y), Some(z)] = nxyz.map(get) {
                    normals.push(Vec3::new(x, y, z).normalised());
                }
                if let [Some(u), Some(v)] = uv.map(get) {
                    uvs.push([u, v]);
                }
            } else if e.name == "face" {
                let k = faces.ok_or("face element without vertex_indices")?;
                let poly: Vec<u32> = row[k].iter().map(|&v| v as u32).collect();
                if let Some(&v) = poly.iter().find(|&&v| v as usize >= mesh.positions.len()) {
                    return Err(
                        format!("face {i} indexes vertex {v} of {}", mesh.positions.len()).into(),
                    );
                }
                fan(&poly, &mut mesh.triangles);
            }
        }
    }
    if normals.len() == mesh.positions.len() {
        mesh.normals = normals;
    }
    if uvs.len() == mesh.positions.len() {
        mesh.uvs = uvs;
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    const SQUARE: [Vec3; 4] = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];

    #[test]
    fn the_same_square_reads_from_every_format() {
        let dir = tempfile::tempdir().unwrap();
        let obj = write(
            dir.path(),
            "q.obj",
            b"# a square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 -1/-1\n",
        );
        let off = write(
            dir.path(),
            "q.off",
            b"OFF\n# comment\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
        );
        let ascii_ply = write(
            dir.path(),
            "q.ply",
            b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
        );
        let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n".to_vec();
        for p in SQUARE {
            for c in p.to_array() {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        bin.push(4);
        for i in 0u32..4 {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        let bin_ply = write(dir.path(), "b.ply", &bin);
        for path in [obj, off, ascii_ply, bin_ply] {
            let m = read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.positions, SQUARE.to_vec(), "{}", path.display());
            assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
            assert!(m.normals.iter().all(|&n| n == Vec3::Z));
            assert_eq!(m.uvs[2], [1.0, 1.0]);
        }
    }

    #[test]
    fn obj_two_corner_faces_are_skipped_not_fatal() {
        let dir = tempfile::tempdir().unwrap();
        let path = write(
            dir.path(),
            "e.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\nf 1 2 3\n",
        );
        let mesh = read_mesh(&path).unwrap();
        assert_eq!(mesh.triangles.len(), 1);
        let only_edges = write(dir.path(), "f.obj", b"v 0 0 0\nv 1 0 0\nf 1 2\n");
        assert!(
            read_mesh(&only_edges).is_err(),
            "no triangle at all is still an error"
        );
    }

    #[test]
    fn obj_text_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = crate::primitives::Primitive::Torus { minor: 0.4 }.mesh();
        let path = write(dir.path(), "t.obj", obj_text(&mesh).as_bytes());
        let back = read_mesh(&path).unwrap();
        // The reader numbers vertices in order of use; compare corner by corner.
        assert_eq!(back.triangles.len(), mesh.triangles.len());
        for (tb, tm) in back.triangles.iter().zip(&mesh.triangles) {
            for (&i, &j) in tb.iter().zip(tm) {
                let (i, j) = (i as usize, j as usize);
                let same = back.positions[i] == mesh.positions[j]
                    && back.uvs[i] == mesh.uvs[j]
                    && (back.normals[i] - mesh.normals[j]).length() < 1e-5;
                assert!(same, "corner {j} differs after the round trip");
            }
        }
    }

    #[test]
    fn broken_files_name_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let cases: [(&str, &[u8], &str); 5] = [
            (
                "a.obj",
                b"v 0 0 0\nv 1 0 0\nf 1 2 7\n",
                "line 3: face index 7 out of range",
            ),
            ("b.obj", b"v 0 0\n", "line 1: bad vertex"),
            (
                "c.off",
                b"OFF\n3 1 0\n0 0 0\n1 0 0\n",
                "ends early, reading vertex 2",
            ),
            (
                "d.ply",
                b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
                "no end_header",
            ),
            ("e.stl", b"solid", "unknown mesh format"),
        ];
        for (name, bytes, message) in cases {
            let err = read_mesh(&write(dir.path(), name, bytes))
                .unwrap_err()
                .to_string();
            assert!(err.contains(name) && err.contains(message), "{err}");
        }
    }
}
