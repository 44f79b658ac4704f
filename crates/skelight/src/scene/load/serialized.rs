//! Mitsuba's `.serialized` meshes: a table of zlib-compressed shapes (format versions 3, 4).

use std::io::Read;
use std::path::Path;

use super::LoadError;
use crate::math::{vec2, vec3};
use crate::scene::shapes::TriangleData;

const HAS_NORMALS: u32 = 0x0001;
const HAS_TEXCOORDS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const SINGLE_PRECISION: u32 = 0x1000;
const DOUBLE_PRECISION: u32 = 0x2000;

struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let s = self
            .data
            .get(self.pos..self.pos.checked_add(n).ok_or("size overflow")?)
            .ok_or("shape data ends early (truncated)")?;
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn vec3(&mut self, double: bool) -> Result<crate::math::Vec3, String> {
        Ok(vec3(self.real(double)?, self.real(double)?, self.real(double)?))
    }
    fn real(&mut self, double: bool) -> Result<f32, String> {
        Ok(if double {
            f64::from_le_bytes(self.take(8)?.try_into().unwrap()) as f32
        } else {
            f32::from_le_bytes(self.take(4)?.try_into().unwrap())
        })
    }
}

/// Number of shapes in the file.
pub fn shape_count(path: &Path) -> Result<usize, LoadError> {
    let data = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
    Ok(offsets(path, &data)?.len())
}

fn offsets(path: &Path, data: &[u8]) -> Result<Vec<u64>, LoadError> {
    let err = |m: &str| LoadError::at(path, 0, m.to_string());
    if data.len() < 8 || u16::from_le_bytes([data[0], data[1]]) != 0x041C {
        return Err(err("not a Mitsuba serialized mesh (bad magic number)"));
    }
    let version = u16::from_le_bytes([data[2], data[3]]);
    let n = u32::from_le_bytes(data[data.len() - 4..].try_into().unwrap()) as usize;
    let entry = if version >= 4 { 8 } else { 4 };
    let table = n
        .checked_mul(entry)
        .and_then(|t| t.checked_add(4))
        .filter(|&t| t <= data.len())
        .ok_or_else(|| err("shape table does not fit in the file (truncated?)"))?;
    let start = data.len() - table;
    Ok((0..n)
        .map(|i| {
            let b = &data[start + i * entry..start + (i + 1) * entry];
            if entry == 8 {
                u64::from_le_bytes(b.try_into().unwrap())
            } else {
                u32::from_le_bytes(b.try_into().unwrap()) as u64
            }
        })
        .collect())
}

pub fn load_serialized(path: &Path, index: usize) -> Result<TriangleData, LoadError> {
    let data = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
    let table = offsets(path, &data)?;
    let err = |m: String| LoadError::at(path, 0, format!("shape {index}: {m}"));
    let &off = table.get(index).ok_or_else(|| err(format!("index out of range (file has {} shapes)", table.len())))?;
    let off = off as usize;
    let head = data.get(off..off + 4).ok_or_else(|| err("offset beyond the end of the file".into()))?;
    let version = u16::from_le_bytes([head[2], head[3]]);
    let mut raw = Vec::new();
    flate2::read::ZlibDecoder::new(&data[off + 4..])
        .read_to_end(&mut raw)
        .or_else(|e| if raw.is_empty() { Err(e) } else { Ok(0) })
        .map_err(|e| err(format!("cannot decompress: {e}")))?;
    let mut c = Cursor { data: &raw, pos: 0 };
    let flags = c.u32().map_err(&err)?;
    if version >= 4 {
        // Shape name, NUL-terminated.
        while c.take(1).map_err(&err)?[0] != 0 {}
    }
    let nv = c.u64().map_err(&err)? as usize;
    let nt = c.u64().map_err(&err)? as usize;
    // Mitsuba reads a shape with neither precision flag as single precision (files written
    // by Mitsuba 0.5 for the path-guiding literature have such shapes); both flags is an error.
    let double = flags & DOUBLE_PRECISION != 0;
    if double && flags & SINGLE_PRECISION != 0 {
        return Err(err("both the single and the double precision flags are set".into()));
    }
    let real = if double { 8 } else { 4 };
    let need = nv.saturating_mul(3 * real) + nt.saturating_mul(12);
    if need > raw.len() {
        return Err(err(format!("claims {nv} vertices and {nt} triangles, more than the data holds")));
    }
    let mut d = TriangleData::default();
    for _ in 0..nv {
        d.positions.push(c.vec3(double).map_err(&err)?);
    }
    if flags & HAS_NORMALS != 0 {
        for _ in 0..nv {
            d.normals.push(c.vec3(double).map_err(&err)?);
        }
    }
    if flags & HAS_TEXCOORDS != 0 {
        for _ in 0..nv {
            // Stored in Mitsuba's own convention already (no flip).
            d.uvs.push(vec2(c.real(double).map_err(&err)?, c.real(double).map_err(&err)?));
        }
    }
    if flags & HAS_COLORS != 0 {
        c.take(nv * 3 * real).map_err(&err)?;
    }
    let wide = nv > u32::MAX as usize;
    for _ in 0..nt {
        let mut t = [0u32; 3];
        for v in &mut t {
            *v = if wide { c.u64().map_err(&err)? as u32 } else { c.u32().map_err(&err)? };
            if *v as usize >= nv {
                return Err(err(format!("triangle refers to vertex {v}, but only {nv} exist")));
            }
        }
        d.indices.push(t);
    }
    Ok(d)
}
