//! Wavefront OBJ (+ MTL): polygons are ear-clipped (non-convex faces exist in real files),
//! vertices are shared per (v, vt, vn) triple as Mitsuba does, and v is flipped so that
//! uv (0,0) is the top-left texel.

use std::collections::HashMap;
use std::path::Path;

use super::LoadError;
use crate::color::Rgb;
use crate::math::{vec2, vec3, Vec2, Vec3};
use crate::scene::shapes::TriangleData;

/// A face corner's (position, texture coordinate, normal) indices: equal keys share a vertex.
type VertexKey = (usize, Option<usize>, Option<usize>);

/// One group of faces sharing a material.
#[derive(Debug, Default)]
pub struct ObjGroup {
    pub material: Option<String>,
    pub data: TriangleData,
    /// Whether the file gave normals for these faces.
    pub has_normals: bool,
}

/// A material from an MTL file (the subset renderers agree on).
#[derive(Clone, Debug, Default)]
pub struct MtlMaterial {
    pub name: String,
    pub kd: Option<Rgb>,
    pub ks: Option<Rgb>,
    pub ke: Option<Rgb>,
    pub ns: Option<f32>,
    pub ni: Option<f32>,
    pub d: Option<f32>,
    pub map_kd: Option<String>,
    pub map_d: Option<String>,
    pub map_bump: Option<String>,
}

#[derive(Debug, Default)]
pub struct ObjFile {
    pub groups: Vec<ObjGroup>,
    pub materials: Vec<MtlMaterial>,
}

fn parse_f32s<const N: usize>(path: &Path, line: usize, parts: &[&str]) -> Result<[f32; N], LoadError> {
    let mut out = [0.0f32; N];
    for (i, o) in out.iter_mut().enumerate() {
        let s = parts.get(i).ok_or_else(|| LoadError::at(path, line, format!("expected {N} numbers")))?;
        *o = s.parse().map_err(|_| LoadError::at(path, line, format!("'{s}' is not a number")))?;
        if !o.is_finite() {
            return Err(LoadError::at(path, line, format!("'{s}' is not finite")));
        }
    }
    Ok(out)
}

/// Keyword and arguments of an OBJ/MTL line, without its comment; `None` for blank lines.
fn statement(raw: &str) -> Option<(&str, Vec<&str>)> {
    let mut it = raw.split('#').next().unwrap_or("").split_whitespace();
    let kw = it.next()?;
    Some((kw, it.collect()))
}

/// Resolves a 1-based or negative OBJ index against `count` elements.
fn resolve(path: &Path, line: usize, s: &str, count: usize, what: &str) -> Result<usize, LoadError> {
    let i: i64 = s.parse().map_err(|_| LoadError::at(path, line, format!("bad {what} index '{s}'")))?;
    let r = if i > 0 { i - 1 } else { count as i64 + i };
    if i == 0 || r < 0 || r >= count as i64 {
        return Err(LoadError::at(path, line, format!("{what} index {i} out of range (have {count})")));
    }
    Ok(r as usize)
}

pub fn load_obj(path: &Path) -> Result<ObjFile, LoadError> {
    let text = super::read_text(path)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let (mut v, mut vt, mut vn) = (Vec::<Vec3>::new(), Vec::<Vec2>::new(), Vec::<Vec3>::new());
    let mut file = ObjFile::default();
    let mut current: Option<String> = None;
    let mut groups: Vec<(ObjGroup, HashMap<VertexKey, u32>)> = Vec::new();
    let mut group_of: HashMap<Option<String>, usize> = HashMap::new();
    for (ln, raw) in text.lines().enumerate() {
        let line = ln + 1;
        let Some((kw, parts)) = statement(raw) else { continue };
        match kw {
            "v" => v.push(Vec3::from(parse_f32s::<3>(path, line, &parts)?)),
            "vt" => {
                let [a] = parse_f32s::<1>(path, line, &parts)?;
                let b = if parts.len() > 1 { parse_f32s::<1>(path, line, &parts[1..])?[0] } else { 0.0 };
                vt.push(vec2(a, 1.0 - b));
            }
            "vn" => vn.push(Vec3::from(parse_f32s::<3>(path, line, &parts)?)),
            "usemtl" => current = Some(parts.join(" ")),
            "mtllib" => {
                let name = parts.join(" ");
                // A missing library is warned (many exported OBJs name one they lack).
                match super::confined_file(dir, dir, &name) {
                    Ok(p) => file.materials.extend(load_mtl(&p)?),
                    Err(e) if e.contains("not found") => {
                        eprintln!("warning: {}:{line}: material library {e}", path.display())
                    }
                    Err(e) => return Err(LoadError::at(path, line, e)),
                }
            }
            "f" => {
                if parts.len() < 3 {
                    return Err(LoadError::at(path, line, "a face needs at least 3 vertices"));
                }
                let gi = *group_of.entry(current.clone()).or_insert_with(|| {
                    groups.push((ObjGroup { material: current.clone(), ..Default::default() }, HashMap::new()));
                    groups.len() - 1
                });
                let (group, dedup) = &mut groups[gi];
                let mut poly = Vec::with_capacity(parts.len());
                for p in &parts {
                    let mut f = p.split('/');
                    let vi = resolve(path, line, f.next().unwrap_or(""), v.len(), "vertex")?;
                    let ti = match f.next() {
                        Some(s) if !s.is_empty() => Some(resolve(path, line, s, vt.len(), "texture coordinate")?),
                        _ => None,
                    };
                    let ni = match f.next() {
                        Some(s) if !s.is_empty() => Some(resolve(path, line, s, vn.len(), "normal")?),
                        _ => None,
                    };
                    let key = (vi, ti, ni);
                    let idx = *dedup.entry(key).or_insert_with(|| {
                        let d = &mut group.data;
                        d.positions.push(v[vi]);
                        d.uvs.push(ti.map(|t| vt[t]).unwrap_or_default());
                        d.normals.push(ni.map(|n| vn[n]).unwrap_or_default());
                        group.has_normals |= ni.is_some();
                        (d.positions.len() - 1) as u32
                    });
                    poly.push(idx);
                }
                let pts: Vec<Vec3> = poly.iter().map(|&i| group.data.positions[i as usize]).collect();
                for [a, b, c] in triangulate(&pts) {
                    group.data.indices.push([poly[a], poly[b], poly[c]]);
                }
            }
            _ => {}
        }
    }
    for (mut g, _) in groups {
        if vt.is_empty() {
            g.data.uvs.clear();
        }
        if !g.has_normals {
            g.data.normals.clear();
        }
        file.groups.push(g);
    }
    Ok(file)
}

/// Splits a simple polygon (possibly non-convex, any orientation in 3D) into triangles by
/// ear clipping in the plane of its Newell normal. Returns indices into `pts`.
pub fn triangulate(pts: &[Vec3]) -> Vec<[usize; 3]> {
    let n = pts.len();
    if n < 3 {
        return Vec::new();
    }
    if n == 3 {
        return vec![[0, 1, 2]];
    }
    let mut normal = Vec3::ZERO;
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        normal += vec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    if normal.length_squared() == 0.0 {
        return (1..n - 1).map(|i| [0, i, i + 1]).collect();
    }
    let frame = crate::math::Frame::from_normal(normal.normalize());
    let p2: Vec<Vec2> = pts
        .iter()
        .map(|p| {
            let l = frame.to_local(*p);
            vec2(l.x, l.y)
        })
        .collect();
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    let mut idx: Vec<usize> = (0..n).collect();
    let mut out = Vec::with_capacity(n - 2);
    let mut guard = 0;
    while idx.len() > 3 && guard < 4 * n * n {
        guard += 1;
        let m = idx.len();
        let mut clipped = false;
        for k in 0..m {
            let (i0, i1, i2) = (idx[(k + m - 1) % m], idx[k], idx[(k + 1) % m]);
            let (a, b, c) = (p2[i0], p2[i1], p2[i2]);
            // Counter-clockwise in the Newell frame means convex.
            if cross(a, b, c) <= 0.0 {
                continue;
            }
            let inside = idx.iter().any(|&j| {
                if j == i0 || j == i1 || j == i2 {
                    return false;
                }
                let p = p2[j];
                cross(a, b, p) >= 0.0 && cross(b, c, p) >= 0.0 && cross(c, a, p) >= 0.0
            });
            if !inside {
                out.push([i0, i1, i2]);
                idx.remove(k);
                clipped = true;
                break;
            }
        }
        if !clipped {
            // Degenerate input (self-intersecting or collinear): finish with a fan.
            break;
        }
    }
    for i in 1..idx.len().saturating_sub(1) {
        out.push([idx[0], idx[i], idx[i + 1]]);
    }
    out
}

pub fn load_mtl(path: &Path) -> Result<Vec<MtlMaterial>, LoadError> {
    let text = super::read_text(path)?;
    let mut out: Vec<MtlMaterial> = Vec::new();
    for (ln, raw) in text.lines().enumerate() {
        let line = ln + 1;
        let Some((kw, parts)) = statement(raw) else { continue };
        if kw == "newmtl" {
            out.push(MtlMaterial { name: parts.join(" "), ..Default::default() });
            continue;
        }
        let Some(m) = out.last_mut() else { continue };
        let rgb3 = |parts: &[&str]| -> Result<Rgb, LoadError> {
            if parts.len() == 1 {
                let [a] = parse_f32s::<1>(path, line, parts)?;
                return Ok(Rgb::splat(a));
            }
            Ok(Rgb::from_array(parse_f32s::<3>(path, line, parts)?))
        };
        let map = |parts: &[&str]| parts.last().map(|s| s.to_string());
        match kw {
            "Kd" => m.kd = Some(rgb3(&parts)?),
            "Ks" => m.ks = Some(rgb3(&parts)?),
            "Ke" => m.ke = Some(rgb3(&parts)?),
            "Ns" => m.ns = Some(parse_f32s::<1>(path, line, &parts)?[0]),
            "Ni" => m.ni = Some(parse_f32s::<1>(path, line, &parts)?[0]),
            "d" => m.d = Some(parse_f32s::<1>(path, line, &parts)?[0]),
            "Tr" => m.d = Some(1.0 - parse_f32s::<1>(path, line, &parts)?[0]),
            "map_Kd" => m.map_kd = map(&parts),
            "map_d" => m.map_d = map(&parts),
            "map_bump" | "bump" | "map_Bump" => m.map_bump = map(&parts),
            _ => {}
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(pts: &[Vec3], tris: &[[usize; 3]]) -> f32 {
        tris.iter().map(|t| 0.5 * (pts[t[1]] - pts[t[0]]).cross(pts[t[2]] - pts[t[0]]).length()).sum()
    }

    #[test]
    fn ear_clipping_handles_non_convex_polygons() {
        // An L-shaped hexagon (area 3) in the xz plane, clockwise when seen from +y.
        let l = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)];
        let pts: Vec<Vec3> = l.iter().map(|&(x, z)| vec3(x, 5.0, z)).collect();
        let tris = triangulate(&pts);
        assert_eq!(tris.len(), 4);
        assert!((area(&pts, &tris) - 3.0).abs() < 1e-5);
        // A fan from vertex 0 would cover the notch and overshoot the area; ours does not.
        let rev: Vec<Vec3> = pts.iter().rev().copied().collect();
        assert!((area(&rev, &triangulate(&rev)) - 3.0).abs() < 1e-5);
    }
}
