//! Watertight ray/triangle intersection (Woop, Benthin, Wald 2013): no cracks between
//! neighbouring triangles, which the thin walls of interiors need.

use super::Ray;
use crate::math::Vec3;

/// Per-ray constants of the watertight test: axis permutation and shear.
#[derive(Clone, Copy, Debug)]
pub struct RayPrecomp {
    pub kx: usize,
    pub ky: usize,
    pub kz: usize,
    pub sx: f32,
    pub sy: f32,
    pub sz: f32,
    pub inv_d: Vec3,
}

impl RayPrecomp {
    pub fn new(ray: &Ray) -> RayPrecomp {
        let kz = ray.d.abs().max_axis();
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if ray.d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let dz = ray.d[kz];
        let inv = |v: f32| {
            if v != 0.0 {
                1.0 / v
            } else {
                f32::INFINITY.copysign(v)
            }
        };
        RayPrecomp {
            kx,
            ky,
            kz,
            sx: ray.d[kx] / dz,
            sy: ray.d[ky] / dz,
            sz: 1.0 / dz,
            inv_d: crate::math::vec3(inv(ray.d.x), inv(ray.d.y), inv(ray.d.z)),
        }
    }
}

/// Returns `(t, b1, b2)` for a hit with `0 < t < tmax`.
#[inline(always)]
pub fn intersect_triangle(ray: &Ray, pre: &RayPrecomp, v: &[Vec3; 3], tmax: f32) -> Option<(f32, f32, f32)> {
    let a = v[0] - ray.o;
    let b = v[1] - ray.o;
    let c = v[2] - ray.o;
    let ax = a[pre.kx] - pre.sx * a[pre.kz];
    let ay = a[pre.ky] - pre.sy * a[pre.kz];
    let bx = b[pre.kx] - pre.sx * b[pre.kz];
    let by = b[pre.ky] - pre.sy * b[pre.kz];
    let cx = c[pre.kx] - pre.sx * c[pre.kz];
    let cy = c[pre.ky] - pre.sy * c[pre.kz];
    let mut u = cx * by - cy * bx;
    let mut w = bx * ay - by * ax;
    let mut vv = ax * cy - ay * cx;
    if u == 0.0 || vv == 0.0 || w == 0.0 {
        // Fall back to double precision on edges so that shared edges are hit exactly once.
        let (cxd, cyd, bxd, byd, axd, ayd) = (cx as f64, cy as f64, bx as f64, by as f64, ax as f64, ay as f64);
        u = (cxd * byd - cyd * bxd) as f32;
        vv = (axd * cyd - ayd * cxd) as f32;
        w = (bxd * ayd - byd * axd) as f32;
    }
    if (u < 0.0 || vv < 0.0 || w < 0.0) && (u > 0.0 || vv > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + vv + w;
    if det == 0.0 {
        return None;
    }
    let az = pre.sz * a[pre.kz];
    let bz = pre.sz * b[pre.kz];
    let cz = pre.sz * c[pre.kz];
    let t_scaled = u * az + vv * bz + w * cz;
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if !(t > 0.0 && t < tmax) {
        return None;
    }
    // u weighs vertex 0, vv vertex 1, w vertex 2.
    Some((t, vv * inv_det, w * inv_det))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::vec3;

    #[test]
    fn hits_inside_misses_outside_and_reports_barycentrics() {
        let tri = [vec3(0.0, 0.0, 0.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0)];
        let ray = Ray::new(vec3(0.25, 0.5, 1.0), vec3(0.0, 0.0, -1.0));
        let pre = RayPrecomp::new(&ray);
        let (t, b1, b2) = intersect_triangle(&ray, &pre, &tri, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6 && (b1 - 0.25).abs() < 1e-6 && (b2 - 0.5).abs() < 1e-6);
        let miss = Ray::new(vec3(0.8, 0.8, 1.0), vec3(0.0, 0.0, -1.0));
        assert!(intersect_triangle(&miss, &RayPrecomp::new(&miss), &tri, f32::INFINITY).is_none());
        assert!(intersect_triangle(&ray, &pre, &tri, 0.5).is_none());
    }

    #[test]
    fn shared_edge_is_watertight() {
        // Two triangles sharing the diagonal of a quad: a ray exactly on it hits one of them.
        let t1 = [vec3(0.0, 0.0, 0.0), vec3(1.0, 0.0, 0.0), vec3(1.0, 1.0, 0.0)];
        let t2 = [vec3(0.0, 0.0, 0.0), vec3(1.0, 1.0, 0.0), vec3(0.0, 1.0, 0.0)];
        for i in 1..50 {
            let s = i as f32 / 50.0;
            let ray = Ray::new(vec3(s, s, 1.0), vec3(0.0, 0.0, -1.0));
            let pre = RayPrecomp::new(&ray);
            let hits = [&t1, &t2].iter().filter(|t| intersect_triangle(&ray, &pre, t, f32::INFINITY).is_some()).count();
            assert!(hits >= 1, "crack at {s}");
        }
    }
}
