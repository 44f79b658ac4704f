//! Stanford PLY meshes: ASCII and binary (either byte order), any element layout; reads
//! vertex positions, normals and texture coordinates and polygonal faces.

use std::path::Path;

use super::LoadError;
use crate::math::{vec2, vec3, Vec3};
use crate::scene::shapes::TriangleData;

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
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
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
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Scalar,
    /// For list properties, the type of the count.
    list: Option<Scalar>,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// Reads values one by one from the body in the file's encoding.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    format: Format,
    tokens: std::iter::Peekable<std::str::SplitAsciiWhitespace<'a>>,
}

impl Reader<'_> {
    fn read(&mut self, kind: Scalar) -> Result<f64, String> {
        if self.format == Format::Ascii {
            let t = self.tokens.next().ok_or("file ends early")?;
            return t.parse::<f64>().map_err(|_| format!("'{t}' is not a number"));
        }
        let n = kind.size();
        let bytes = self.data.get(self.pos..self.pos + n).ok_or("file ends early (truncated binary body)")?;
        self.pos += n;
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(bytes);
        if self.format == Format::Big {
            b[..n].reverse();
        }
        Ok(match kind {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(b),
        })
    }
}

pub fn load_ply(path: &Path) -> Result<TriangleData, LoadError> {
    let data = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
    let err = |m: String| LoadError::at(path, 0, m);
    let header_end = data
        .windows(10)
        .position(|w| w == b"end_header")
        .ok_or_else(|| err("not a PLY file (no end_header)".into()))?;
    let header = std::str::from_utf8(&data[..header_end]).map_err(|_| err("header is not text".into()))?;
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err(err("not a PLY file (missing 'ply' magic)".into()));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for (i, l) in lines.enumerate() {
        let line = i + 2;
        let parts: Vec<&str> = l.split_whitespace().collect();
        match parts.as_slice() {
            ["format", f, _] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Little,
                    "binary_big_endian" => Format::Big,
                    other => return Err(LoadError::at(path, line, format!("unknown format '{other}'"))),
                })
            }
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count.parse().map_err(|_| LoadError::at(path, line, format!("bad element count '{count}'")))?,
                props: Vec::new(),
            }),
            ["property", "list", c, k, name] => {
                let e = elements.last_mut().ok_or_else(|| LoadError::at(path, line, "property before any element"))?;
                let (c, k) = (Scalar::parse(c), Scalar::parse(k));
                let (Some(c), Some(k)) = (c, k) else {
                    return Err(LoadError::at(path, line, "unknown list property type"));
                };
                e.props.push(Property { name: name.to_string(), kind: k, list: Some(c) });
            }
            ["property", k, name] => {
                let e = elements.last_mut().ok_or_else(|| LoadError::at(path, line, "property before any element"))?;
                let kind = Scalar::parse(k)
                    .ok_or_else(|| LoadError::at(path, line, format!("unknown property type '{k}'")))?;
                e.props.push(Property { name: name.to_string(), kind, list: None });
            }
            _ => {}
        }
    }
    let format = format.ok_or_else(|| err("missing format line".into()))?;
    let mut body = header_end + "end_header".len();
    // Skip the line break after end_header (\n or \r\n).
    while body < data.len() && (data[body] == b'\r' || data[body] == b'\n') {
        body += 1;
        if data[body - 1] == b'\n' {
            break;
        }
    }
    let text_body = if format == Format::Ascii {
        std::str::from_utf8(&data[body..]).map_err(|_| err("ASCII body is not text".into()))?
    } else {
        ""
    };
    let mut r = Reader { data: &data, pos: body, format, tokens: text_body.split_ascii_whitespace().peekable() };
    let mut out = TriangleData::default();
    let (mut has_n, mut has_uv) = (false, false);
    for e in &elements {
        // Guard absurd counts before allocating (a truncated or hostile header).
        let min_bytes = if format == Format::Ascii {
            1
        } else {
            e.props.iter().map(|p| p.list.unwrap_or(p.kind).size()).sum::<usize>().max(1)
        };
        if e.count.saturating_mul(min_bytes) > data.len() {
            return Err(err(format!("element '{}' claims {} entries, more than the file can hold", e.name, e.count)));
        }
        for _ in 0..e.count {
            let mut vals = [f64::NAN; 8]; // x y z nx ny nz u v
            for p in &e.props {
                if let Some(ct) = p.list {
                    let n = r.read(ct).map_err(&err)? as usize;
                    let mut idx = Vec::with_capacity(n);
                    for _ in 0..n {
                        idx.push(r.read(p.kind).map_err(&err)?);
                    }
                    if e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index") {
                        if n < 3 {
                            continue;
                        }
                        let nv = out.positions.len();
                        let ids: Vec<u32> = idx.iter().map(|&v| v as u32).collect();
                        if let Some(bad) = ids.iter().find(|&&i| i as usize >= nv) {
                            return Err(err(format!("face refers to vertex {bad}, but only {nv} vertices exist")));
                        }
                        let pts: Vec<Vec3> = ids.iter().map(|&i| out.positions[i as usize]).collect();
                        for [a, b, c] in super::obj::triangulate(&pts) {
                            out.indices.push([ids[a], ids[b], ids[c]]);
                        }
                    }
                    continue;
                }
                let v = r.read(p.kind).map_err(&err)?;
                if e.name == "vertex" {
                    let slot = match p.name.as_str() {
                        "x" => 0,
                        "y" => 1,
                        "z" => 2,
                        "nx" => 3,
                        "ny" => 4,
                        "nz" => 5,
                        "u" | "s" | "texture_u" | "texture_s" => 6,
                        "v" | "t" | "texture_v" | "texture_t" => 7,
                        _ => continue,
                    };
                    vals[slot] = v;
                }
            }
            if e.name == "vertex" {
                let p = vec3(vals[0] as f32, vals[1] as f32, vals[2] as f32);
                if !p.is_finite() {
                    return Err(err(format!("vertex {} has a missing or non-finite position", out.positions.len())));
                }
                out.positions.push(p);
                has_n |= !vals[3].is_nan();
                has_uv |= !vals[6].is_nan();
                out.normals.push(vec3(vals[3] as f32, vals[4] as f32, vals[5] as f32));
                out.uvs.push(vec2(vals[6] as f32, 1.0 - vals[7] as f32));
            }
        }
    }
    if !has_n {
        out.normals.clear();
    }
    if !has_uv {
        out.uvs.clear();
    }
    Ok(out)
}
