//! Vectors, affine transforms and orthonormal frames (single precision, like the renderer).

use std::ops::{Add, AddAssign, Div, Index, IndexMut, Mul, MulAssign, Neg, Sub};

pub const PI: f32 = std::f32::consts::PI;
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
pub const INV_2PI: f32 = 0.5 * std::f32::consts::FRAC_1_PI;
pub const INV_4PI: f32 = 0.25 * std::f32::consts::FRAC_1_PI;

/// A 3-vector used for points, directions and normals alike.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3 {
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

#[inline]
pub const fn vec3(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3 { x, y, z }
}

impl Vec3 {
    pub const ZERO: Vec3 = vec3(0.0, 0.0, 0.0);
    pub const fn splat(v: f32) -> Vec3 {
        vec3(v, v, v)
    }
    #[inline]
    pub fn dot(self, o: Vec3) -> f32 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline]
    pub fn cross(self, o: Vec3) -> Vec3 {
        vec3(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)
    }
    #[inline]
    pub fn length_squared(self) -> f32 {
        self.dot(self)
    }
    #[inline]
    pub fn length(self) -> f32 {
        self.length_squared().sqrt()
    }
    #[inline]
    pub fn normalize(self) -> Vec3 {
        self * (1.0 / self.length())
    }
    #[inline]
    pub fn mul_elem(self, o: Vec3) -> Vec3 {
        vec3(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    #[inline]
    pub fn min(self, o: Vec3) -> Vec3 {
        vec3(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }
    #[inline]
    pub fn max(self, o: Vec3) -> Vec3 {
        vec3(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }
    #[inline]
    pub fn abs(self) -> Vec3 {
        vec3(self.x.abs(), self.y.abs(), self.z.abs())
    }
    #[inline]
    pub fn max_component(self) -> f32 {
        self.x.max(self.y).max(self.z)
    }
    /// Index (0, 1, 2) of the largest component.
    #[inline]
    pub fn max_axis(self) -> usize {
        if self.x >= self.y && self.x >= self.z {
            0
        } else if self.y >= self.z {
            1
        } else {
            2
        }
    }
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
    /// Reflection of `self` (pointing away from the surface) about `n`.
    #[inline]
    pub fn reflect(self, n: Vec3) -> Vec3 {
        n * (2.0 * self.dot(n)) - self
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    #[inline]
    fn add(self, o: Vec3) -> Vec3 {
        vec3(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl AddAssign for Vec3 {
    #[inline]
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}
impl Sub for Vec3 {
    type Output = Vec3;
    #[inline]
    fn sub(self, o: Vec3) -> Vec3 {
        vec3(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl Mul<f32> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn mul(self, s: f32) -> Vec3 {
        vec3(self.x * s, self.y * s, self.z * s)
    }
}
impl Mul<Vec3> for f32 {
    type Output = Vec3;
    #[inline]
    fn mul(self, v: Vec3) -> Vec3 {
        v * self
    }
}
impl MulAssign<f32> for Vec3 {
    #[inline]
    fn mul_assign(&mut self, s: f32) {
        *self = *self * s;
    }
}
impl Div<f32> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn div(self, s: f32) -> Vec3 {
        self * (1.0 / s)
    }
}
impl Neg for Vec3 {
    type Output = Vec3;
    #[inline]
    fn neg(self) -> Vec3 {
        vec3(-self.x, -self.y, -self.z)
    }
}
impl Index<usize> for Vec3 {
    type Output = f32;
    #[inline]
    fn index(&self, i: usize) -> &f32 {
        match i {
            0 => &self.x,
            1 => &self.y,
            _ => &self.z,
        }
    }
}

impl IndexMut<usize> for Vec3 {
    #[inline]
    fn index_mut(&mut self, i: usize) -> &mut f32 {
        match i {
            0 => &mut self.x,
            1 => &mut self.y,
            _ => &mut self.z,
        }
    }
}

impl From<[f32; 3]> for Vec3 {
    fn from(a: [f32; 3]) -> Vec3 {
        vec3(a[0], a[1], a[2])
    }
}

/// A 2-vector: texture coordinates and sample pairs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec2 {
    pub x: f32,
    pub y: f32,
}

#[inline]
pub const fn vec2(x: f32, y: f32) -> Vec2 {
    Vec2 { x, y }
}

impl Add for Vec2 {
    type Output = Vec2;
    fn add(self, o: Vec2) -> Vec2 {
        vec2(self.x + o.x, self.y + o.y)
    }
}
impl Sub for Vec2 {
    type Output = Vec2;
    fn sub(self, o: Vec2) -> Vec2 {
        vec2(self.x - o.x, self.y - o.y)
    }
}
impl Mul<f32> for Vec2 {
    type Output = Vec2;
    fn mul(self, s: f32) -> Vec2 {
        vec2(self.x * s, self.y * s)
    }
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Aabb::EMPTY
    }
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };
    #[inline]
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    #[inline]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }
    #[inline]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    /// Whether the box holds no point: `EMPTY`, or an intersection of disjoint boxes (which
    /// can be inverted along any axis, not only x).
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }
    /// The points in both boxes (empty if they are disjoint).
    #[inline]
    pub fn intersection(self, o: Aabb) -> Aabb {
        Aabb { min: self.min.max(o.min), max: self.max.min(o.max) }
    }
    /// Half the surface area (all the SAH needs).
    #[inline]
    pub fn half_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }
    /// Radius of the bounding sphere around the centre.
    pub fn bounding_radius(&self) -> f32 {
        self.extent().length() * 0.5
    }
}

/// Right-handed orthonormal frame; `n` is the local +z axis.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// Frame around a unit normal (Duff et al. 2017 branchless construction).
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = vec3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = vec3(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }
    /// Frame with `n` as normal and `s` projected from a tangent hint.
    pub fn from_normal_tangent(n: Vec3, tangent: Vec3) -> Frame {
        let s = tangent - n * n.dot(tangent);
        let len = s.length();
        if !(len > 1e-6) || !len.is_finite() {
            return Frame::from_normal(n);
        }
        let s = s / len;
        Frame { s, t: n.cross(s), n }
    }
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        vec3(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// The affine part of a [`Transform`] in single precision, for per-sample use (camera rays):
/// `point(v) = origin + x·v.x + y·v.y + z·v.z`. A projective last row is ignored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine {
    pub origin: Vec3,
    pub x: Vec3,
    pub y: Vec3,
    pub z: Vec3,
}

impl Affine {
    pub fn of(m: &[[f64; 4]; 4]) -> Affine {
        let column = |j: usize| vec3(m[0][j] as f32, m[1][j] as f32, m[2][j] as f32);
        Affine { origin: column(3), x: column(0), y: column(1), z: column(2) }
    }
    #[inline]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
    #[inline]
    pub fn point(&self, v: Vec3) -> Vec3 {
        self.origin + self.vector(v)
    }
}

/// Affine or projective 4×4 transform kept with its inverse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub m: [[f64; 4]; 4],
    pub inv: [[f64; 4]; 4],
}

const IDENTITY4: [[f64; 4]; 4] =
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];

fn mat_mul(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    let mut r = [[0.0; 4]; 4];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

/// Inverse by Gauss-Jordan elimination with partial pivoting; `None` if singular.
fn mat_inverse(m: &[[f64; 4]; 4]) -> Option<[[f64; 4]; 4]> {
    let mut a = *m;
    let mut inv = IDENTITY4;
    for col in 0..4 {
        let pivot = (col..4).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        inv.swap(col, pivot);
        let p = a[col][col];
        for j in 0..4 {
            a[col][j] /= p;
            inv[col][j] /= p;
        }
        for i in 0..4 {
            if i != col {
                let f = a[i][col];
                if f != 0.0 {
                    for j in 0..4 {
                        a[i][j] -= f * a[col][j];
                        inv[i][j] -= f * inv[col][j];
                    }
                }
            }
        }
    }
    Some(inv)
}

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

impl Transform {
    pub const IDENTITY: Transform = Transform { m: IDENTITY4, inv: IDENTITY4 };

    /// From a row-major matrix; `None` when it cannot be inverted.
    pub fn from_matrix(m: [[f64; 4]; 4]) -> Option<Transform> {
        let inv = mat_inverse(&m)?;
        Some(Transform { m, inv })
    }
    pub fn translate(d: [f64; 3]) -> Transform {
        let mut m = IDENTITY4;
        let mut inv = IDENTITY4;
        for i in 0..3 {
            m[i][3] = d[i];
            inv[i][3] = -d[i];
        }
        Transform { m, inv }
    }
    pub fn scale(s: [f64; 3]) -> Option<Transform> {
        let mut m = IDENTITY4;
        for i in 0..3 {
            m[i][i] = s[i];
        }
        Transform::from_matrix(m)
    }
    /// Rotation by `angle_deg` degrees about `axis` (right-handed).
    pub fn rotate(axis: [f64; 3], angle_deg: f64) -> Option<Transform> {
        let len = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
        if !(len > 0.0) {
            return None;
        }
        let (x, y, z) = (axis[0] / len, axis[1] / len, axis[2] / len);
        let (s, c) = angle_deg.to_radians().sin_cos();
        let t = 1.0 - c;
        let m = [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y, 0.0],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x, 0.0],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        Transform::from_matrix(m)
    }
    /// Mitsuba's look-at: local +z looks at `target`, +x is "left", +y is up.
    pub fn look_at(origin: [f64; 3], target: [f64; 3], up: [f64; 3]) -> Option<Transform> {
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        };
        let norm = |a: [f64; 3]| {
            let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            if l > 0.0 && l.is_finite() {
                Some([a[0] / l, a[1] / l, a[2] / l])
            } else {
                None
            }
        };
        let dir = norm(sub(target, origin))?;
        let left = norm(cross(norm(up)?, dir))?;
        let new_up = cross(dir, left);
        let m = [
            [left[0], new_up[0], dir[0], origin[0]],
            [left[1], new_up[1], dir[1], origin[1]],
            [left[2], new_up[2], dir[2], origin[2]],
            [0.0, 0.0, 0.0, 1.0],
        ];
        Transform::from_matrix(m)
    }
    /// `self` applied after `first`.
    pub fn compose(&self, first: &Transform) -> Transform {
        Transform { m: mat_mul(&self.m, &first.m), inv: mat_mul(&first.inv, &self.inv) }
    }
    pub fn inverse(&self) -> Transform {
        Transform { m: self.inv, inv: self.m }
    }
    pub fn point(&self, p: Vec3) -> Vec3 {
        let m = &self.m;
        let (x, y, z) = (p.x as f64, p.y as f64, p.z as f64);
        let w = m[3][0] * x + m[3][1] * y + m[3][2] * z + m[3][3];
        vec3(
            ((m[0][0] * x + m[0][1] * y + m[0][2] * z + m[0][3]) / w) as f32,
            ((m[1][0] * x + m[1][1] * y + m[1][2] * z + m[1][3]) / w) as f32,
            ((m[2][0] * x + m[2][1] * y + m[2][2] * z + m[2][3]) / w) as f32,
        )
    }
    pub fn vector(&self, v: Vec3) -> Vec3 {
        let m = &self.m;
        let (x, y, z) = (v.x as f64, v.y as f64, v.z as f64);
        vec3(
            (m[0][0] * x + m[0][1] * y + m[0][2] * z) as f32,
            (m[1][0] * x + m[1][1] * y + m[1][2] * z) as f32,
            (m[2][0] * x + m[2][1] * y + m[2][2] * z) as f32,
        )
    }
    /// Normals transform by the inverse transpose.
    pub fn normal(&self, n: Vec3) -> Vec3 {
        let i = &self.inv;
        let (x, y, z) = (n.x as f64, n.y as f64, n.z as f64);
        vec3(
            (i[0][0] * x + i[1][0] * y + i[2][0] * z) as f32,
            (i[0][1] * x + i[1][1] * y + i[2][1] * z) as f32,
            (i[0][2] * x + i[1][2] * y + i[2][2] * z) as f32,
        )
    }
    /// Whether the transform flips handedness (negative determinant of the linear part).
    pub fn flips_handedness(&self) -> bool {
        let m = &self.m;
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        det < 0.0
    }
}

#[inline]
pub fn lerp(t: f32, a: f32, b: f32) -> f32 {
    a + t * (b - a)
}

#[inline]
pub fn sqr(x: f32) -> f32 {
    x * x
}

#[inline]
pub fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        for n in [vec3(0.0, 0.0, 1.0), vec3(0.0, 0.0, -1.0), vec3(0.3, -0.4, 0.866).normalize()] {
            let f = Frame::from_normal(n);
            assert!((f.s.dot(f.t)).abs() < 1e-5 && (f.s.dot(f.n)).abs() < 1e-5);
            assert!((f.s.cross(f.t) - f.n).length() < 1e-5);
            let v = vec3(0.1, 0.7, -0.2);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn transform_inverse_and_rotation() {
        let t = Transform::rotate([0.0, 1.0, 0.0], 90.0).unwrap().compose(&Transform::scale([2.0, 3.0, 4.0]).unwrap());
        let p = vec3(1.0, 2.0, 3.0);
        let q = t.point(p);
        assert!((q - vec3(12.0, 6.0, -2.0)).length() < 1e-4, "{q:?}");
        assert!((t.inverse().point(q) - p).length() < 1e-4);
        assert!(Transform::scale([1.0, 0.0, 1.0]).is_none());
    }

    #[test]
    fn look_at_maps_z_to_view_direction() {
        let t = Transform::look_at([0.0, 0.0, 3.9], [0.0; 3], [0.0, 1.0, 0.0]).unwrap();
        let d = t.vector(vec3(0.0, 0.0, 1.0));
        assert!((d - vec3(0.0, 0.0, -1.0)).length() < 1e-6);
        // +x is the viewer's left: looking down -z with +y up, that is world -x.
        assert!((t.vector(vec3(1.0, 0.0, 0.0)) - vec3(-1.0, 0.0, 0.0)).length() < 1e-6);
    }
}
