//! PLY point clouds (positions and colours), read and written.
//!
//! The reader takes ascii and binary_little_endian files with any scalar property types; it reads
//! the `vertex` element's x, y, z and, when present, red, green, blue, and skips other elements.

use crate::error::{Error, Result};
use glam::DVec3;
use std::path::Path;

/// Write points with colours as a binary little-endian PLY.
pub fn write_points(path: &Path, points: &[(DVec3, [u8; 3])]) -> Result<()> {
    crate::util::write_atomic(path, |w| {
        writeln!(
            w,
            "ply\nformat binary_little_endian 1.0\nelement vertex {}",
            points.len()
        )?;
        writeln!(w, "property float x\nproperty float y\nproperty float z")?;
        writeln!(
            w,
            "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header"
        )?;
        for (p, c) in points {
            for v in p.to_array() {
                w.write_all(&(v as f32).to_le_bytes())?;
            }
            w.write_all(c)?;
        }
        Ok(())
    })
}

#[derive(Clone, Copy, Debug, PartialEq)]
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
    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }
    fn decode_le(self, b: &[u8]) -> f64 {
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    }
}

#[derive(Debug)]
struct Property {
    name: String,
    /// `Some(count type)` for a list property.
    list: Option<Scalar>,
    ty: Scalar,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    BinaryLe,
}

/// Where the header ends and what it declares.
fn parse_header(path: &Path, buf: &[u8]) -> Result<(Encoding, Vec<Element>, usize)> {
    const END: &[u8] = b"end_header";
    let end = buf
        .windows(END.len())
        .position(|w| w == END)
        .ok_or_else(|| Error::format(path, "not a PLY file: no end_header line"))?;
    let mut body = end + END.len();
    // The header's last line ends with \n (or \r\n).
    if buf.get(body) == Some(&b'\r') {
        body += 1;
    }
    if buf.get(body) != Some(&b'\n') {
        return Err(Error::format(
            path,
            "PLY header: end_header is not followed by a newline",
        ));
    }
    body += 1;
    let text = std::str::from_utf8(&buf[..end])
        .map_err(|_| Error::format(path, "PLY header is not text"))?;
    let mut lines = text.lines().map(str::trim);
    if lines.next() != Some("ply") {
        return Err(Error::format(
            path,
            "not a PLY file: it does not start with 'ply'",
        ));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in lines {
        let toks: Vec<&str> = line.split_whitespace().collect();
        let bad = |what: &str| Error::format(path, format!("PLY header: {what}: '{line}'"));
        match toks.first().copied() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                encoding = Some(match toks.get(1).copied() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::BinaryLe,
                    Some(other) => {
                        return Err(Error::format(
                            path,
                            format!(
                            "PLY format '{other}' is not supported (ascii or binary_little_endian)"
                        ),
                        ))
                    }
                    None => return Err(bad("format line without a format")),
                })
            }
            Some("element") => {
                let (Some(name), Some(count)) = (toks.get(1), toks.get(2)) else {
                    return Err(bad("element line needs a name and a count"));
                };
                let count = count
                    .parse()
                    .map_err(|_| bad("element count is not a number"))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| bad("property before any element"))?;
                let scalar = |t: Option<&&str>| {
                    t.and_then(|t| Scalar::parse(t))
                        .ok_or_else(|| bad("unknown property type"))
                };
                let prop = if toks.get(1) == Some(&"list") {
                    Property {
                        list: Some(scalar(toks.get(2))?),
                        ty: scalar(toks.get(3))?,
                        name: toks
                            .get(4)
                            .ok_or_else(|| bad("list property without a name"))?
                            .to_string(),
                    }
                } else {
                    Property {
                        list: None,
                        ty: scalar(toks.get(1))?,
                        name: toks
                            .get(2)
                            .ok_or_else(|| bad("property without a name"))?
                            .to_string(),
                    }
                };
                el.props.push(prop);
            }
            Some(_) => return Err(bad("unknown header line")),
        }
    }
    let encoding = encoding.ok_or_else(|| Error::format(path, "PLY header has no format line"))?;
    Ok((encoding, elements, body))
}

/// Reads one scalar at a time from the body, in either encoding.
struct Body<'a> {
    path: &'a Path,
    encoding: Encoding,
    buf: &'a [u8],
    pos: usize,
    tokens: std::str::SplitAsciiWhitespace<'a>,
}

impl Body<'_> {
    fn scalar(&mut self, ty: Scalar, element: &str, index: usize) -> Result<f64> {
        let truncated = || {
            Error::format(
                self.path,
                format!("truncated: {element} {index} is incomplete (the file ends early)"),
            )
        };
        match self.encoding {
            Encoding::BinaryLe => {
                let b = self
                    .buf
                    .get(self.pos..self.pos + ty.size())
                    .ok_or_else(truncated)?;
                self.pos += ty.size();
                Ok(ty.decode_le(b))
            }
            Encoding::Ascii => {
                let tok = self.tokens.next().ok_or_else(truncated)?;
                let v: f64 = tok.parse().map_err(|_| {
                    Error::format(
                        self.path,
                        format!("{element} {index}: '{tok}' is not a number"),
                    )
                })?;
                if !ty.is_float() && v.fract() != 0.0 {
                    return Err(Error::format(
                        self.path,
                        format!("{element} {index}: '{tok}' is not an integer"),
                    ));
                }
                Ok(v)
            }
        }
    }
}

/// Read the vertices (x, y, z and, if present, red, green, blue) of a PLY file. Points without
/// colour are white; float colours in [0, 1] are scaled to 0-255.
pub fn read_points(path: &Path) -> Result<Vec<(DVec3, [u8; 3])>> {
    Ok(read(path, false)?.vertices)
}

/// A PLY file's vertices and faces (polygons fanned into triangles).
#[derive(Clone, Debug, Default)]
pub struct PlyData {
    pub vertices: Vec<(DVec3, [u8; 3])>,
    pub triangles: Vec<[u32; 3]>,
}

/// Read vertices and the `face` element's `vertex_indices` (or `vertex_index`).
pub fn read_mesh(path: &Path) -> Result<PlyData> {
    read(path, true)
}

fn read(path: &Path, with_faces: bool) -> Result<PlyData> {
    // Not a FIFO or a device (a json's ply_file_path could name one): those could be endless.
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::format(path, "not a regular file"));
    }
    let buf = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(path, &buf, with_faces)
}

/// A PLY file's vertices (and, with `with_faces`, its faces) from its bytes, as [`read_points`]
/// and [`read_mesh`] read them (`path` names the file in errors).
pub fn parse(path: &Path, buf: &[u8], with_faces: bool) -> Result<PlyData> {
    let (encoding, elements, body_start) = parse_header(path, buf)?;
    let body = &buf[body_start..];
    let text = match encoding {
        Encoding::Ascii => std::str::from_utf8(body)
            .map_err(|_| Error::format(path, "ascii PLY body is not text"))?,
        Encoding::BinaryLe => "",
    };
    let mut r = Body {
        path,
        encoding,
        buf: body,
        pos: 0,
        tokens: text.split_ascii_whitespace(),
    };
    let vertex = elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| Error::format(path, "PLY has no vertex element"))?;
    let find = |n: &str| {
        elements[vertex]
            .props
            .iter()
            .position(|p| p.name == n && p.list.is_none())
    };
    let (Some(ix), Some(iy), Some(iz)) = (find("x"), find("y"), find("z")) else {
        return Err(Error::format(
            path,
            "PLY vertices have no x, y, z properties",
        ));
    };
    let colour = match (find("red"), find("green"), find("blue")) {
        (Some(r), Some(g), Some(b)) => Some([r, g, b]),
        _ => None,
    };
    let face = elements.iter().position(|e| e.name == "face");
    if with_faces && face.is_none() {
        return Err(Error::format(path, "PLY has no face element: not a mesh"));
    }
    // A corrupt count must not make us allocate before the data runs out.
    let min_vertex_bytes: usize = match encoding {
        Encoding::BinaryLe => elements[vertex]
            .props
            .iter()
            .map(|p| p.list.unwrap_or(p.ty).size())
            .sum(),
        Encoding::Ascii => 2 * elements[vertex].props.len(),
    };
    // (+1: the last ascii value needs no separator after it.)
    if elements[vertex].count.saturating_mul(min_vertex_bytes) > body.len() + 1 {
        return Err(Error::format(
            path,
            format!(
                "truncated: the header declares {} vertices but the body has only {} bytes",
                elements[vertex].count,
                body.len()
            ),
        ));
    }
    let last = if with_faces {
        vertex.max(face.unwrap_or(0))
    } else {
        vertex
    };
    let mut out = PlyData {
        vertices: Vec::with_capacity(elements[vertex].count),
        triangles: Vec::new(),
    };
    let mut values = Vec::new();
    let mut polygon: Vec<u32> = Vec::new();
    for (e, el) in elements[..=last].iter().enumerate() {
        let is_vertex = e == vertex;
        let is_face = with_faces && Some(e) == face;
        if el.props.is_empty() && el.count > 0 {
            // Records without properties take no bytes: a count of them says nothing, and
            // looping over a corrupt 2^64 of them would never end.
            return Err(Error::format(
                path,
                format!(
                    "element '{}' declares {} records but no properties",
                    el.name, el.count
                ),
            ));
        }
        for i in 0..el.count {
            values.clear();
            for p in &el.props {
                match p.list {
                    None => values.push(r.scalar(p.ty, &el.name, i)?),
                    Some(count_ty) => {
                        let n = r.scalar(count_ty, &el.name, i)?;
                        if !(0.0..=1e6).contains(&n) {
                            return Err(Error::format(
                                path,
                                format!("{} {i}: list length {n} is not plausible", el.name),
                            ));
                        }
                        let indices =
                            is_face && matches!(p.name.as_str(), "vertex_indices" | "vertex_index");
                        polygon.clear();
                        for _ in 0..n as usize {
                            let v = r.scalar(p.ty, &el.name, i)?;
                            if indices {
                                polygon.push(v as u32);
                            }
                        }
                        for k in 1..polygon.len().saturating_sub(1) {
                            out.triangles.push([polygon[0], polygon[k], polygon[k + 1]]);
                        }
                        values.push(n);
                    }
                }
            }
            if !is_vertex {
                continue;
            }
            let xyz = DVec3::new(values[ix], values[iy], values[iz]);
            if !xyz.is_finite() {
                return Err(Error::format(path, format!("vertex {i} is not finite")));
            }
            let rgb = match colour {
                None => [255; 3],
                Some(c) => c.map(|k| {
                    let v = if el.props[k].ty.is_float() {
                        values[k] * 255.0
                    } else {
                        values[k]
                    };
                    v.round().clamp(0.0, 255.0) as u8
                }),
            };
            out.vertices.push((xyz, rgb));
        }
    }
    let n = out.vertices.len() as u32;
    if let Some(t) = out.triangles.iter().find(|t| t.iter().any(|&v| v >= n)) {
        return Err(Error::format(
            path,
            format!(
                "a face uses vertex {} but there are only {n}",
                t.iter().max().unwrap()
            ),
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_with_double_and_faces_before_vertices() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.ply");
        std::fs::write(
            &p,
            "ply\nformat ascii 1.0\ncomment x\nelement face 1\nproperty list uchar int vertex_indices\n\
             element vertex 2\nproperty double x\nproperty double y\nproperty double z\n\
             property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n\
             3 0 1 1\n0.1 0.2 0.3 1 2 3\n-1 2.5 1e3 255 0 7\n",
        )
        .unwrap();
        let pts = read_points(&p).unwrap();
        assert_eq!(pts.len(), 2);
        assert_eq!(pts[0], (DVec3::new(0.1, 0.2, 0.3), [1, 2, 3]));
        assert_eq!(pts[1], (DVec3::new(-1.0, 2.5, 1000.0), [255, 0, 7]));
    }

    #[test]
    fn rejects_big_endian_and_truncation() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.ply");
        std::fs::write(
            &p,
            "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n",
        )
        .unwrap();
        assert!(read_points(&p)
            .unwrap_err()
            .to_string()
            .contains("binary_big_endian"));
        let pts = vec![(DVec3::new(1.0, 2.0, 3.0), [4, 5, 6]); 3];
        write_points(&p, &pts).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 2]).unwrap();
        assert!(read_points(&p)
            .unwrap_err()
            .to_string()
            .contains("truncated"));
    }
}
