//! Portals a user names: planar polygons (a door's opening, a window, the gap of a door left
//! ajar) through which light reaches the rest of the scene, read from a file, as Cycles,
//! pbrt-v4 and Mitsuba 3 let users place portals for the sky, here for any light.
//!
//! At a vertex x every portal triangle on the side x reflects into is a candidate, picked
//! with probability q_i proportional to about the solid angle it subtends at x (A·|cos θ|/d²,
//! cheap), and a direction is drawn uniformly within its solid angle Ω_i (Arvo 1995, in f64;
//! Ω_i by Van Oosterom and Strackee's formula); a triangle too small to sample that way
//! (Ω_i < [`MIN_SOLID_ANGLE`]) is sampled uniformly by area instead. The density of a
//! direction ω is exact: Σ over every triangle the line x + tω (t > 0) crosses of q_i·p_i(ω),
//! with p_i = 1/Ω_i (or t²/(|cos θ|·A_i) for an area-sampled one): a line crossing two
//! triangles (a folded portal, two portals one behind the other) counts both.
//!
//! With [`NamedPortals::by_area`], points are drawn uniformly by area over the facing
//! triangles instead (triangles picked by area, density t²/(|cos θ|·A) over every crossed
//! triangle), for comparison.
//!
//! The file is JSON or OBJ, in the scene's world space (after every transform the scene
//! applies), read by [`NamedPortals::load`]:
//! - JSON: `{"portals": [{"name": "door gap", "quad": [[x,y,z], [x,y,z], [x,y,z], [x,y,z]]},
//!   {"name": "window", "triangles": [[[x,y,z], [x,y,z], [x,y,z]], …]}]}` (a quad's corners in
//!   order around it, split along its first diagonal);
//! - OBJ: `v` and `f` lines (polygons as fans); each `o` or `g` starts a new portal.

use std::path::Path;

use crate::math::{vec3, Vec3};
use crate::sampling::Rng;

/// Portal triangles a vertex considers at most (a few quads in practice; the array a vertex
/// keeps is this long).
pub const MAX_TRIANGLES: usize = 16;
/// Below this solid angle (steradians) a triangle is sampled by area: spherical sampling
/// loses its precision on slivers of the sphere.
pub const MIN_SOLID_ANGLE: f64 = 1e-6;
/// How close to a triangle's plane, relative to its size, a point sees it edge-on.
const PLANE_EPSILON: f32 = 1e-4;
/// Largest portal file read (bytes): a handful of quads takes a few hundred.
const MAX_FILE_BYTES: u64 = 1 << 20;

/// A portal as a file gives it: its name and triangles.
pub type Portal = (String, Vec<[Vec3; 3]>);

/// One portal triangle.
#[derive(Clone, Copy, Debug)]
pub struct PortalTriangle {
    pub v: [Vec3; 3],
    pub area: f32,
    pub normal: Vec3,
    pub centroid: Vec3,
    /// Which named portal it belongs to.
    pub portal: u16,
}

/// The portals a user named.
#[derive(Clone, Debug)]
pub struct NamedPortals {
    pub names: Vec<String>,
    pub triangles: Vec<PortalTriangle>,
    /// Draw points uniformly by area on the portals (triangles picked by area), as Cycles'
    /// and the first portalpt's did, instead of directions by solid angle: for measuring
    /// what solid-angle sampling buys.
    pub by_area: bool,
}

/// Solid angle of the triangle (a, b, c) seen from the origin (Van Oosterom & Strackee 1983).
fn solid_angle(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let (la, lb, lc) = (norm(a), norm(b), norm(c));
    let num = dot(a, cross(b, c)).abs();
    let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
    let omega = 2.0 * num.atan2(den);
    if omega.is_finite() {
        omega.max(0.0)
    } else {
        0.0
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = norm(a);
    if l > 0.0 {
        scale(a, 1.0 / l)
    } else {
        a
    }
}
fn f64s(v: Vec3) -> [f64; 3] {
    [v.x as f64, v.y as f64, v.z as f64]
}

/// A direction drawn uniformly within the spherical triangle of unit vectors (a, b, c)
/// (Arvo 1995, "Stratified sampling of spherical triangles", Fig. 2), given its area.
fn sample_spherical_triangle(a: [f64; 3], b: [f64; 3], c: [f64; 3], area: f64, u: [f64; 2]) -> [f64; 3] {
    // The angle at a between the great arcs ab and ac, and at b and c likewise.
    let angle =
        |p: [f64; 3], q: [f64; 3], r: [f64; 3]| dot(unit(cross(p, q)), unit(cross(p, r))).clamp(-1.0, 1.0).acos();
    let alpha = angle(a, b, c);
    let cos_c = dot(a, b).clamp(-1.0, 1.0);
    let (sin_alpha, cos_alpha) = alpha.sin_cos();
    // The sub-triangle of area u0·area and its third vertex c' on the arc ac.
    let a_hat = u[0] * area;
    let (s, t) = (a_hat - alpha).sin_cos();
    let uu = t - cos_alpha;
    let vv = s + sin_alpha * cos_c;
    let den = (vv * s + uu * t) * sin_alpha;
    let q = if den != 0.0 { (((vv * t - uu * s) * cos_alpha - vv) / den).clamp(-1.0, 1.0) } else { 1.0 };
    let c_perp = unit(sub(c, scale(a, dot(c, a))));
    let c2 = [
        q * a[0] + (1.0 - q * q).sqrt() * c_perp[0],
        q * a[1] + (1.0 - q * q).sqrt() * c_perp[1],
        q * a[2] + (1.0 - q * q).sqrt() * c_perp[2],
    ];
    // A point on the arc from b to c', uniform in the sub-triangle's area.
    let z = 1.0 - u[1] * (1.0 - dot(c2, b));
    let z = z.clamp(-1.0, 1.0);
    let perp = unit(sub(c2, scale(b, dot(c2, b))));
    let r = (1.0 - z * z).max(0.0).sqrt();
    unit([z * b[0] + r * perp[0], z * b[1] + r * perp[1], z * b[2] + r * perp[2]])
}

/// Where the line x + t·w (t > 0) crosses triangle `v`: t, or `None` (Möller–Trumbore, in
/// f64 so that directions drawn towards a triangle's interior are found inside it).
fn crossing(v: &[Vec3; 3], x: Vec3, w: Vec3) -> Option<f64> {
    let (o, d) = (f64s(x), f64s(w));
    let p0 = f64s(v[0]);
    let e1 = sub(f64s(v[1]), p0);
    let e2 = sub(f64s(v[2]), p0);
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = sub(o, p0);
    let b1 = dot(tv, pv) * inv;
    if !(0.0..=1.0).contains(&b1) {
        return None;
    }
    let qv = cross(tv, e1);
    let b2 = dot(d, qv) * inv;
    if b2 < 0.0 || b1 + b2 > 1.0 {
        return None;
    }
    let t = dot(e2, qv) * inv;
    (t > 0.0).then_some(t)
}

impl NamedPortals {
    /// Builds portals from named lists of triangles, checking each: finite corners, a
    /// positive area, and at most [`MAX_TRIANGLES`] in all.
    pub fn new(portals: Vec<Portal>) -> Result<NamedPortals, String> {
        let mut names = Vec::new();
        let mut triangles = Vec::new();
        for (name, tris) in portals {
            let portal = names.len() as u16;
            if tris.is_empty() {
                return Err(format!("portal '{name}' has no triangle"));
            }
            for (i, v) in tris.iter().enumerate() {
                if v.iter().any(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite())) {
                    return Err(format!("portal '{name}', triangle {}: a corner is not a finite number", i + 1));
                }
                let area = 0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length();
                let size = (v[1] - v[0]).length().max((v[2] - v[0]).length());
                if !(area > 1e-6 * size * size) || !area.is_finite() {
                    return Err(format!("portal '{name}', triangle {}: its corners are collinear (no area)", i + 1));
                }
                let normal = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
                let centroid = (v[0] + v[1] + v[2]) * (1.0 / 3.0);
                triangles.push(PortalTriangle { v: *v, area, normal, centroid, portal });
            }
            names.push(name);
        }
        if triangles.is_empty() {
            return Err("no portal in the file".into());
        }
        if triangles.len() > MAX_TRIANGLES {
            return Err(format!(
                "{} triangles: at most {MAX_TRIANGLES} (a portal is an opening: a few quads, each two triangles)",
                triangles.len()
            ));
        }
        Ok(NamedPortals { names, triangles, by_area: false })
    }

    /// Reads a portal file (JSON or OBJ, by its extension; see the module's doc). Errors name
    /// the file and what is wrong.
    pub fn load(path: &Path) -> Result<NamedPortals, String> {
        let shown = path.display();
        let meta = std::fs::metadata(path).map_err(|e| format!("portal file '{shown}': {e}"))?;
        if !meta.is_file() {
            return Err(format!("portal file '{shown}' is not a regular file"));
        }
        if meta.len() > MAX_FILE_BYTES {
            return Err(format!("portal file '{shown}' is {} bytes: at most {MAX_FILE_BYTES}", meta.len()));
        }
        let text = std::fs::read_to_string(path).map_err(|e| format!("portal file '{shown}': {e}"))?;
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        let portals = match ext.as_deref() {
            Some("json") => parse_json(&text),
            Some("obj") => parse_obj(&text),
            _ => Err("its extension is neither .json nor .obj".into()),
        };
        portals.and_then(NamedPortals::new).map_err(|why| format!("portal file '{shown}': {why}"))
    }

    /// The portal mixture at `x`, for a vertex reflecting into the hemisphere around
    /// `side` (the geometric normal turned towards the incoming direction): every triangle
    /// with a corner above that hemisphere's plane, weighted by about its solid angle,
    /// A·|cos θ|/d² from its centroid (capped at 2π; a selection weight need not be exact,
    /// only fixed at x), or by its area with [`NamedPortals::by_area`]; `None` when none is.
    pub fn at(&self, x: Vec3, side: Vec3) -> Option<NamedVertex<'_>> {
        self.at_weighted(x, side, |_| 1.0)
    }

    /// [`NamedPortals::at`] with each triangle's weight multiplied by `portal_weight` of its
    /// portal (0 leaves the portal out): how a point's blend of regions weighs the portals
    /// on their routes.
    pub fn at_weighted(&self, x: Vec3, side: Vec3, portal_weight: impl Fn(u16) -> f32) -> Option<NamedVertex<'_>> {
        let mut weights = [0.0f32; MAX_TRIANGLES];
        let mut total = 0.0f32;
        for (i, t) in self.triangles.iter().enumerate() {
            let scale = portal_weight(t.portal);
            if scale <= 0.0 || !t.v.iter().any(|&p| (p - x).dot(side) > 0.0) {
                continue;
            }
            // A point in the triangle's plane (a wall flush with a portal) would draw
            // directions in that plane, which no line crosses: density 0 for a drawn
            // direction. Such triangles are left to the BSDF.
            if t.normal.dot(t.v[0] - x).abs() <= PLANE_EPSILON * t.area.sqrt() {
                continue;
            }
            weights[i] = scale
                * if self.by_area {
                    t.area
                } else {
                    let d = t.centroid - x;
                    let d2 = d.length_squared();
                    let w = t.area * t.normal.dot(d).abs() / (d2 * d2.sqrt());
                    if w.is_finite() {
                        w.min(2.0 * std::f32::consts::PI)
                    } else {
                        0.0
                    }
                };
            total += weights[i];
        }
        (total > 0.0 && total.is_finite()).then_some(NamedVertex { portals: self, x, weights, total })
    }
}

/// The mixture over the portal triangles at one vertex.
pub struct NamedVertex<'a> {
    portals: &'a NamedPortals,
    x: Vec3,
    /// Each triangle's selection weight (0 for those not considered).
    weights: [f32; MAX_TRIANGLES],
    total: f32,
}

impl NamedVertex<'_> {
    /// The solid angle of triangle `t` at x when it is drawn by solid angle, or `None` when
    /// it is drawn by area (by choice, or too small: [`MIN_SOLID_ANGLE`]). Exact (f64): it
    /// is the density's normalisation.
    #[inline]
    fn drawn_solid_angle(&self, t: &PortalTriangle) -> Option<f64> {
        if self.portals.by_area {
            return None;
        }
        let o = f64s(self.x);
        let [a, b, c] = t.v.map(|p| sub(f64s(p), o));
        Some(solid_angle(a, b, c)).filter(|&omega| omega >= MIN_SOLID_ANGLE)
    }

    /// The solid-angle density of unit direction `w`: Σ over the triangles the line crosses
    /// of q_i·p_i(w).
    pub fn pdf(&self, w: Vec3) -> f32 {
        let mut sum = 0.0f64;
        for (i, t) in self.portals.triangles.iter().enumerate() {
            let weight = self.weights[i];
            if weight <= 0.0 {
                continue;
            }
            let Some(dist) = crossing(&t.v, self.x, w) else { continue };
            let q = (weight / self.total) as f64;
            sum += match self.drawn_solid_angle(t) {
                Some(omega) => q / omega,
                None => {
                    let cos = (t.normal.dot(w) as f64).abs();
                    if cos > 0.0 {
                        q * dist * dist / (cos * t.area as f64)
                    } else {
                        0.0
                    }
                }
            };
        }
        sum as f32
    }

    /// How far along `w` the nearest portal triangle lies, if the line crosses one.
    pub fn distance_to_portal(&self, w: Vec3) -> Option<f32> {
        self.portals.triangles.iter().filter_map(|t| crossing(&t.v, self.x, w)).map(|t| t as f32).reduce(f32::min)
    }

    /// Draws a direction: a triangle by its weight, then a direction uniformly within its
    /// solid angle, or towards a point uniform by area on it.
    pub fn sample(&self, rng: &mut Rng) -> Vec3 {
        let mut pick = rng.next_f32() * self.total;
        let n = self.portals.triangles.len();
        let mut chosen = (0..n).rev().find(|&i| self.weights[i] > 0.0).unwrap_or(0);
        for i in 0..n {
            let w = self.weights[i];
            if w > 0.0 && pick < w {
                chosen = i;
                break;
            }
            pick -= w;
        }
        let t = &self.portals.triangles[chosen];
        let u = [rng.next_f32() as f64, rng.next_f32() as f64];
        match self.drawn_solid_angle(t) {
            Some(omega) => {
                let o = f64s(self.x);
                let [a, b, c] = t.v.map(|p| unit(sub(f64s(p), o)));
                let d = sample_spherical_triangle(a, b, c, omega, u);
                vec3(d[0] as f32, d[1] as f32, d[2] as f32).normalize()
            }
            None => {
                let s = u[0].sqrt() as f32;
                let (b1, b2) = (1.0 - s, (u[1] as f32) * s);
                let y = t.v[0] * (1.0 - b1 - b2) + t.v[1] * b1 + t.v[2] * b2;
                (y - self.x).normalize()
            }
        }
    }
}

/// `{"portals": [{"name": …, "quad": [4 corners]} | {"name": …, "triangles": [[3 corners], …]}]}`.
fn parse_json(text: &str) -> Result<Vec<Portal>, String> {
    use serde_json::Value;
    let root: Value = serde_json::from_str(text).map_err(|e| format!("not valid JSON: {e}"))?;
    let list = root.get("portals").and_then(Value::as_array).ok_or("no \"portals\" list at its top level")?;
    let point = |v: &Value, what: &str| -> Result<Vec3, String> {
        let a = v.as_array().filter(|a| a.len() == 3).ok_or(format!("{what}: a corner is not [x, y, z]"))?;
        let c: Vec<f64> = a.iter().filter_map(Value::as_f64).collect();
        if c.len() != 3 {
            return Err(format!("{what}: a corner's coordinates are not all numbers"));
        }
        Ok(vec3(c[0] as f32, c[1] as f32, c[2] as f32))
    };
    let mut portals = Vec::new();
    for (k, p) in list.iter().enumerate() {
        let name = p.get("name").and_then(Value::as_str).map_or(format!("portal {}", k + 1), str::to_string);
        let mut tris = Vec::new();
        if let Some(quad) = p.get("quad") {
            let corners =
                quad.as_array().filter(|a| a.len() == 4).ok_or(format!("'{name}': \"quad\" is not 4 corners"))?;
            let c: Vec<Vec3> = corners.iter().map(|v| point(v, &name)).collect::<Result<_, _>>()?;
            tris.push([c[0], c[1], c[2]]);
            tris.push([c[0], c[2], c[3]]);
        }
        if let Some(list) = p.get("triangles") {
            let list = list.as_array().ok_or(format!("'{name}': \"triangles\" is not a list"))?;
            for t in list {
                let corners =
                    t.as_array().filter(|a| a.len() == 3).ok_or(format!("'{name}': a triangle is not 3 corners"))?;
                let c: Vec<Vec3> = corners.iter().map(|v| point(v, &name)).collect::<Result<_, _>>()?;
                tris.push([c[0], c[1], c[2]]);
            }
        }
        if tris.is_empty() {
            return Err(format!("'{name}' has neither \"quad\" nor \"triangles\""));
        }
        portals.push((name, tris));
    }
    Ok(portals)
}

/// OBJ `v` and `f` lines; `o` and `g` start portals; everything else is ignored.
fn parse_obj(text: &str) -> Result<Vec<Portal>, String> {
    let mut vertices: Vec<Vec3> = Vec::new();
    let mut portals: Vec<Portal> = Vec::new();
    let mut name = "portal 1".to_string();
    let mut current: Vec<[Vec3; 3]> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f32> = words
                    .take(3)
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .map_err(|_| format!("line {line_no}: a vertex's coordinates are not numbers"))?;
                if c.len() != 3 {
                    return Err(format!("line {line_no}: a vertex needs x, y and z"));
                }
                vertices.push(vec3(c[0], c[1], c[2]));
            }
            Some("f") => {
                let mut corners = Vec::new();
                for w in words {
                    let index: i64 = w
                        .split('/')
                        .next()
                        .and_then(|i| i.parse().ok())
                        .ok_or(format!("line {line_no}: '{w}' is not a vertex index"))?;
                    let resolved = if index < 0 { vertices.len() as i64 + index } else { index - 1 };
                    let v = usize::try_from(resolved)
                        .ok()
                        .and_then(|i| vertices.get(i))
                        .ok_or(format!("line {line_no}: vertex {index} does not exist"))?;
                    corners.push(*v);
                }
                if corners.len() < 3 {
                    return Err(format!("line {line_no}: a face needs 3 corners or more"));
                }
                for i in 1..corners.len() - 1 {
                    current.push([corners[0], corners[i], corners[i + 1]]);
                }
            }
            Some("o") | Some("g") => {
                if !current.is_empty() {
                    portals.push((std::mem::take(&mut name), std::mem::take(&mut current)));
                }
                let rest: Vec<&str> = words.collect();
                name = if rest.is_empty() { format!("portal {}", portals.len() + 1) } else { rest.join(" ") };
            }
            _ => {}
        }
    }
    if !current.is_empty() {
        portals.push((name, current));
    }
    Ok(portals)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform_direction(rng: &mut Rng) -> Vec3 {
        crate::sampling::uniform_sphere(rng.next_2d())
    }

    /// A door-like opening (a long thin quad, as veach-door's gap) and, behind it and
    /// overlapping it as seen from the test points, a second quad folded at an angle: lines
    /// through the first often cross the second too.
    fn folded() -> NamedPortals {
        NamedPortals::new(vec![
            (
                "gap".into(),
                vec![
                    [vec3(0.0, 0.0, 0.0), vec3(0.3, 0.0, 0.0), vec3(0.3, 0.0, 2.0)],
                    [vec3(0.0, 0.0, 0.0), vec3(0.3, 0.0, 2.0), vec3(0.0, 0.0, 2.0)],
                ],
            ),
            (
                "behind".into(),
                vec![
                    [vec3(-0.5, 1.0, 0.2), vec3(0.8, 1.4, 0.2), vec3(0.8, 1.4, 1.6)],
                    [vec3(-0.5, 1.0, 0.2), vec3(0.8, 1.4, 1.6), vec3(-0.5, 1.0, 1.6)],
                    // A sliver, far away: sampled by area.
                    [vec3(0.1, 40.0, 0.9), vec3(0.1004, 40.0, 0.9), vec3(0.1, 40.0, 0.9004)],
                ],
            ),
        ])
        .expect("valid portals")
    }

    /// The points the tests look from: in front of the gap, off its planes.
    const POINTS: [[f32; 3]; 3] = [[0.4, -1.3, 0.7], [-0.3, -0.9, 1.2], [0.2, -0.4, 0.5]];

    /// The mixture's density integrates to one over the sphere (E[p·4π] = 1 for uniform
    /// directions), within four standard errors; a density counting only the first triangle
    /// a line crosses does not (seen failing).
    #[test]
    fn named_portal_density_integrates_to_one() {
        density_integrates_to_one(folded());
        density_integrates_to_one(NamedPortals { by_area: true, ..folded() });
    }

    fn density_integrates_to_one(portals: NamedPortals) {
        let mut rng = Rng::new(11, 0, 0);
        for p in POINTS {
            let x = vec3(p[0], p[1], p[2]);
            let v = portals.at(x, vec3(0.0, 1.0, 0.0)).expect("portals in front");
            let n = 400_000;
            let (mut sum, mut sq, mut several) = (0.0f64, 0.0f64, 0);
            for _ in 0..n {
                let w = uniform_direction(&mut rng);
                let f = v.pdf(w) as f64 * 4.0 * std::f64::consts::PI;
                sum += f;
                sq += f * f;
                several += usize::from(portals.triangles.iter().filter(|t| crossing(&t.v, x, w).is_some()).count() > 1);
            }
            let mean = sum / n as f64;
            let se = ((sq / n as f64 - mean * mean) / n as f64).sqrt();
            println!("from {x:?}: ∫p dω = {mean:.4} ± {se:.4}; {several} of {n} lines cross two triangles");
            assert!(several > n / 200, "too few lines cross two triangles to test the sum");
            assert!((mean - 1.0).abs() < 4.0 * se, "from {x:?}: ∫p dω = {mean} ± {se}");
        }
    }

    /// Drawn directions follow the density: χ² of the directions' histogram over a 16×32
    /// grid in (cos θ, φ) against the density integrated over each cell (midpoint rule on
    /// sub-cells), at the 99.99 % quantile. A triangle pick off by 10 %, or a density counting
    /// only the first crossed triangle, fails (both seen).
    #[test]
    fn named_portal_draws_follow_their_density() {
        draws_follow_their_density(folded());
        draws_follow_their_density(NamedPortals { by_area: true, ..folded() });
    }

    fn draws_follow_their_density(portals: NamedPortals) {
        let mut rng = Rng::new(12, 0, 0);
        let (nt, np) = (16usize, 32usize);
        let cell = |w: Vec3| {
            let i = (((1.0 - w.z) * 0.5 * nt as f32) as usize).min(nt - 1);
            let phi = w.y.atan2(w.x).rem_euclid(2.0 * std::f32::consts::PI);
            let j = ((phi / (2.0 * std::f32::consts::PI) * np as f32) as usize).min(np - 1);
            i * np + j
        };
        for p in POINTS {
            let x = vec3(p[0], p[1], p[2]);
            let v = portals.at(x, vec3(0.0, 1.0, 0.0)).expect("portals in front");
            let draws = 200_000usize;
            let mut observed = vec![0.0f64; nt * np];
            for _ in 0..draws {
                let w = v.sample(&mut rng);
                assert!(v.pdf(w) > 0.0, "a drawn direction has density 0");
                observed[cell(w)] += 1.0;
            }
            // Expected counts: ∫_cell p dω by the midpoint rule on 64×64 sub-cells of each
            // cell (equal solid angles in (cos θ, φ)): deterministic, so that the χ² sees the
            // draws' noise alone.
            let k = 64usize;
            let d_omega = 4.0 * std::f64::consts::PI / (nt * np * k * k) as f64;
            let mut expected = vec![0.0f64; nt * np];
            for (c, e) in expected.iter_mut().enumerate() {
                let (i, j) = (c / np, c % np);
                for a in 0..k {
                    let z = 1.0 - 2.0 * (i as f64 + (a as f64 + 0.5) / k as f64) / nt as f64;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    for b in 0..k {
                        let phi = 2.0 * std::f64::consts::PI * (j as f64 + (b as f64 + 0.5) / k as f64) / np as f64;
                        let w = vec3((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                        *e += v.pdf(w) as f64 * d_omega * draws as f64;
                    }
                }
            }
            let (mut chi2, mut dof) = (0.0, 0usize);
            for (o, e) in observed.iter().zip(&expected) {
                if *e >= 20.0 {
                    chi2 += (o - e) * (o - e) / e;
                    dof += 1;
                }
            }
            // 99.99 % quantile of χ²(dof), Wilson–Hilferty.
            let k = dof.saturating_sub(1) as f64;
            let limit = k * (1.0 - 2.0 / (9.0 * k) + 3.719 * (2.0 / (9.0 * k)).sqrt()).powi(3);
            println!("from {x:?}: χ² = {chi2:.1} over {dof} cells (limit {limit:.1})");
            assert!(dof >= 10, "too few cells");
            assert!(chi2 < limit, "from {x:?}: χ² = {chi2} over {dof} cells");
        }
    }

    /// Spherical triangle sampling covers its triangle: E[1/p] over draws is the solid angle
    /// of the portals considered, as Van Oosterom–Strackee gives it.
    #[test]
    fn solid_angle_agrees_with_draws() {
        let portals = NamedPortals::new(vec![(
            "quad".into(),
            vec![
                [vec3(-1.0, 2.0, -1.0), vec3(1.0, 2.0, -1.0), vec3(1.0, 2.0, 1.0)],
                [vec3(-1.0, 2.0, -1.0), vec3(1.0, 2.0, 1.0), vec3(-1.0, 2.0, 1.0)],
            ],
        )])
        .expect("valid");
        let v = portals.at(Vec3::ZERO, vec3(0.0, 1.0, 0.0)).expect("in front");
        // A 2×2 square at distance 2 seen from its axis: Ω = 4·atan(a²/(d·√(d² + 2a²))), a = 1, d = 2.
        let exact = 4.0 * (1.0f64 / (2.0 * 6.0f64.sqrt())).atan();
        let omega: f64 = portals.triangles.iter().filter_map(|t| v.drawn_solid_angle(t)).sum();
        assert!((omega - exact).abs() < 1e-9 * exact, "Ω {omega} against {exact}");
        let mut rng = Rng::new(5, 0, 0);
        for _ in 0..10_000 {
            let w = v.sample(&mut rng);
            assert!((v.pdf(w) as f64 - 1.0 / exact).abs() < 1e-3 / exact, "p = {} off 1/Ω", v.pdf(w));
        }
    }

    /// A point in a portal's plane (a wall flush with it) is not offered that portal: its
    /// drawn directions would lie in the plane, where the density is 0.
    #[test]
    fn points_in_a_portals_plane_are_not_offered_it() {
        let portals = folded();
        assert!(portals.at(vec3(0.5, 0.0, 1.0), vec3(0.0, 0.0, 1.0)).is_none_or(|v| v.weights[..2] == [0.0, 0.0]));
        assert!(portals.at(vec3(0.5, -0.01, 1.0), vec3(0.0, 1.0, 0.0)).is_some());
    }

    #[test]
    fn bad_portal_files_are_named() {
        let dir = std::env::temp_dir().join(format!("skelight-portals-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cases = [
            ("a.json", "{", "not valid JSON"),
            ("b.json", "{\"portals\": []}", "no portal"),
            ("c.json", "{\"portals\": [{\"quad\": [[0,0,0],[1,0,0],[1,1,0]]}]}", "not 4 corners"),
            ("d.json", "{\"portals\": [{\"quad\": [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]}]}", "collinear"),
            ("e.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n", "vertex 3 does not exist"),
            ("f.txt", "", "neither .json nor .obj"),
            ("g.obj", "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "not a finite number"),
        ];
        for (name, text, why) in cases {
            let path = dir.join(name);
            std::fs::write(&path, text).unwrap();
            let err = NamedPortals::load(&path).expect_err(name);
            assert!(err.contains(name) && err.contains(why), "{name}: {err}");
        }
        let err = NamedPortals::load(&dir.join("missing.json")).expect_err("missing");
        assert!(err.contains("missing.json"), "{err}");
        let err = NamedPortals::load(&dir).expect_err("a folder");
        assert!(err.contains("not a regular file"), "{err}");
        std::fs::write(dir.join("ok.obj"), "o door\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        let ok = NamedPortals::load(&dir.join("ok.obj")).expect("a quad");
        assert_eq!((ok.names.as_slice(), ok.triangles.len()), (&["door".to_string()][..], 2));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
