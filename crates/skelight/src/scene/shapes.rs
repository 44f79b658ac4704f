//! Mitsuba's parametric shapes as triangle meshes in object space (then transformed).

use super::Mesh;
use crate::math::{vec2, vec3, Transform, Vec2, Vec3, PI};

/// Mesh pieces before they get a material.
#[derive(Clone, Debug, Default)]
pub struct TriangleData {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
}

impl TriangleData {
    /// Applies `t` to positions and normals; a mirroring transform keeps the winding facing
    /// the transformed normals.
    pub fn transform(mut self, t: &Transform) -> TriangleData {
        for p in &mut self.positions {
            *p = t.point(*p);
        }
        for n in &mut self.normals {
            let m = t.normal(*n);
            *n = if m.length_squared() > 0.0 { m.normalize() } else { *n };
        }
        self
    }
    pub fn into_mesh(self, name: String) -> Mesh {
        Mesh {
            name,
            positions: self.positions,
            normals: self.normals,
            uvs: self.uvs,
            indices: self.indices,
            material: 0,
            emission: None,
            alpha: None,
            sphere: None,
        }
    }
}

/// [-1,1]² in the xy plane, facing +z; uv (0,0) at (-1,-1).
pub fn rectangle() -> TriangleData {
    TriangleData {
        positions: vec![vec3(-1.0, -1.0, 0.0), vec3(1.0, -1.0, 0.0), vec3(1.0, 1.0, 0.0), vec3(-1.0, 1.0, 0.0)],
        normals: vec![vec3(0.0, 0.0, 1.0); 4],
        uvs: vec![vec2(0.0, 0.0), vec2(1.0, 0.0), vec2(1.0, 1.0), vec2(0.0, 1.0)],
        indices: vec![[0, 1, 2], [2, 3, 0]],
    }
}

/// [-1,1]³ with outward flat faces (each face its own four vertices).
pub fn cube() -> TriangleData {
    let mut d = TriangleData::default();
    let faces: [(Vec3, Vec3, Vec3); 6] = [
        (vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0)),
        (vec3(-1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), vec3(0.0, 1.0, 0.0)),
        (vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0)),
        (vec3(0.0, -1.0, 0.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0)),
        (vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0)),
        (vec3(0.0, 0.0, -1.0), vec3(0.0, 1.0, 0.0), vec3(1.0, 0.0, 0.0)),
    ];
    for (n, a, b) in faces {
        let base = d.positions.len() as u32;
        for (s, t) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            d.positions.push(n + a * s + b * t);
            d.normals.push(n);
            d.uvs.push(vec2((s + 1.0) * 0.5, (t + 1.0) * 0.5));
        }
        d.indices.push([base, base + 1, base + 2]);
        d.indices.push([base + 2, base + 3, base]);
    }
    d
}

/// Unit disk in the xy plane facing +z, as a fan of `segments` triangles.
pub fn disk(segments: usize) -> TriangleData {
    let mut d = TriangleData::default();
    d.positions.push(Vec3::ZERO);
    d.normals.push(vec3(0.0, 0.0, 1.0));
    d.uvs.push(vec2(0.0, 0.0));
    // Radius chosen so the polygon's area equals the disk's (emitted power is preserved).
    let r = (2.0 * PI / (segments as f32 * (2.0 * PI / segments as f32).sin())).sqrt();
    for i in 0..segments {
        let phi = 2.0 * PI * i as f32 / segments as f32;
        d.positions.push(vec3(r * phi.cos(), r * phi.sin(), 0.0));
        d.normals.push(vec3(0.0, 0.0, 1.0));
        d.uvs.push(vec2(1.0, i as f32 / segments as f32));
    }
    for i in 0..segments as u32 {
        d.indices.push([0, 1 + i, 1 + (i + 1) % segments as u32]);
    }
    d
}

/// Unit sphere with smooth normals (a UV sphere of `rings` × 2·`rings`).
pub fn sphere(rings: usize) -> TriangleData {
    let mut d = TriangleData::default();
    let segs = 2 * rings;
    for i in 0..=rings {
        let theta = PI * i as f32 / rings as f32;
        for j in 0..=segs {
            let phi = 2.0 * PI * j as f32 / segs as f32;
            let n = vec3(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            d.positions.push(n);
            d.normals.push(n);
            d.uvs.push(vec2(j as f32 / segs as f32, i as f32 / rings as f32));
        }
    }
    let row = segs as u32 + 1;
    for i in 0..rings as u32 {
        for j in 0..segs as u32 {
            let a = i * row + j;
            let b = a + row;
            if i != 0 {
                d.indices.push([a, b, a + 1]);
            }
            if i + 1 != rings as u32 {
                d.indices.push([a + 1, b, b + 1]);
            }
        }
    }
    d
}

/// Open cylinder of radius 1 from z=0 to z=1, normals pointing out.
pub fn cylinder(segments: usize) -> TriangleData {
    let mut d = TriangleData::default();
    for j in 0..=segments {
        let phi = 2.0 * PI * j as f32 / segments as f32;
        let n = vec3(phi.cos(), phi.sin(), 0.0);
        for z in [0.0, 1.0] {
            d.positions.push(vec3(n.x, n.y, z));
            d.normals.push(n);
            d.uvs.push(vec2(j as f32 / segments as f32, z));
        }
    }
    for j in 0..segments as u32 {
        let a = 2 * j;
        d.indices.push([a, a + 2, a + 1]);
        d.indices.push([a + 1, a + 2, a + 3]);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area_and_outward(d: &TriangleData) -> (f32, bool) {
        let mut area = 0.0;
        let mut outward = true;
        for t in &d.indices {
            let [a, b, c] = t.map(|i| d.positions[i as usize]);
            let n = (b - a).cross(c - a);
            area += 0.5 * n.length();
            let centre = (a + b + c) / 3.0;
            if n.dot(d.normals[t[0] as usize]) <= 0.0 && n.length() > 1e-9 {
                outward = false;
            }
            let _ = centre;
        }
        (area, outward)
    }

    #[test]
    fn shapes_have_right_area_and_consistent_winding() {
        let (a, ok) = area_and_outward(&rectangle());
        assert!((a - 4.0).abs() < 1e-5 && ok);
        let (a, ok) = area_and_outward(&cube());
        assert!((a - 24.0).abs() < 1e-4 && ok);
        let (a, ok) = area_and_outward(&disk(64));
        assert!((a - PI).abs() < 1e-4 && ok, "{a}");
        let (a, ok) = area_and_outward(&sphere(64));
        assert!((a - 4.0 * PI).abs() < 0.01 && ok, "{a}");
        let (_, ok) = area_and_outward(&cylinder(32));
        assert!(ok);
    }
}
