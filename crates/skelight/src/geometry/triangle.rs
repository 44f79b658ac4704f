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
    #[inline(always)]
    pub fn new(ray: &Ray) -> RayPrecomp {
        let kz = ray.d.abs().max_axis();
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if ray.d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let inv_d = reciprocal(ray.d);
        // The shear reuses 1/d_z (d_z is the largest component, never zero for a real
        // direction): three divisions a ray instead of six, which in rendering (not in
        // traversal alone) is worth 5 %. Watertightness only needs every triangle to see
        // the same shear.
        let sz = inv_d[kz];
        RayPrecomp { kx, ky, kz, sx: ray.d[kx] * sz, sy: ray.d[ky] * sz, sz, inv_d }
    }
}

/// 1 / d per component; IEEE division gives the ±∞ the slab test needs for ±0. One vector
/// division instead of three scalar ones that would wait on each other's divider.
#[inline(always)]
fn reciprocal(d: Vec3) -> Vec3 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE is part of the x86_64 baseline; `r` holds four floats.
        unsafe {
            let mut r = [0.0f32; 4];
            _mm_storeu_ps(r.as_mut_ptr(), _mm_div_ps(_mm_set1_ps(1.0), _mm_set_ps(1.0, d.z, d.y, d.x)));
            crate::math::vec3(r[0], r[1], r[2])
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    crate::math::vec3(1.0 / d.x, 1.0 / d.y, 1.0 / d.z)
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

/// Four triangles tested together: vertices as `v[vertex][axis][lane]`, so each step of
/// the watertight test is one SIMD instruction over the four. Unused lanes hold NaN
/// vertices, which every comparison of the test rejects.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Triangle4 {
    pub v: [[[f32; 4]; 3]; 3],
}

impl Triangle4 {
    /// Packs up to four triangles; missing ones become NaN lanes.
    pub fn pack(tris: &[[Vec3; 3]]) -> Triangle4 {
        debug_assert!(tris.len() <= 4);
        let mut v = [[[f32::NAN; 4]; 3]; 3];
        for (lane, t) in tris.iter().enumerate() {
            for (vertex, p) in t.iter().enumerate() {
                for axis in 0..3 {
                    v[vertex][axis][lane] = p[axis];
                }
            }
        }
        Triangle4 { v }
    }

    #[cfg(any(test, not(target_arch = "x86_64")))]
    pub fn triangle(&self, lane: usize) -> [Vec3; 3] {
        std::array::from_fn(|k| crate::math::vec3(self.v[k][0][lane], self.v[k][1][lane], self.v[k][2][lane]))
    }
}

/// Results of [`intersect4`]: per lane, distance and barycentrics; `valid` has bit `k` set
/// when lane `k` is hit with `0 < t < tmax`.
#[derive(Clone, Copy, Debug)]
pub struct Hits4 {
    pub valid: u32,
    pub t: [f32; 4],
    pub b1: [f32; 4],
    pub b2: [f32; 4],
}

impl Hits4 {
    /// The valid lane with the smallest distance.
    #[inline(always)]
    pub fn nearest(&self) -> Option<usize> {
        let mut best: Option<usize> = None;
        let mut bits = self.valid;
        while bits != 0 {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if best.is_none_or(|b| self.t[k] < self.t[b]) {
                best = Some(k);
            }
        }
        best
    }
}

/// The watertight test of [`intersect_triangle`] on four triangles at once, with the same
/// floating-point operations in the same order, so results are bit-identical to it.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub fn intersect4(ray: &Ray, pre: &RayPrecomp, tri: &Triangle4, tmax: f32) -> Hits4 {
    use std::arch::x86_64::*;
    // SAFETY: SSE is part of the x86_64 baseline; `Triangle4` is 16-byte aligned and each
    // row is 16 bytes, so the aligned loads are in bounds and aligned.
    unsafe {
        let o = [ray.o.x, ray.o.y, ray.o.z];
        let (sx, sy, sz) = (_mm_set1_ps(pre.sx), _mm_set1_ps(pre.sy), _mm_set1_ps(pre.sz));
        // Vertex k relative to the origin, sheared: (x, y) in the ray's frame and the raw z.
        let sheared = |k: usize| {
            let rel = |axis: usize| _mm_sub_ps(_mm_load_ps(tri.v[k][axis].as_ptr()), _mm_set1_ps(o[axis]));
            let z = rel(pre.kz);
            (_mm_sub_ps(rel(pre.kx), _mm_mul_ps(sx, z)), _mm_sub_ps(rel(pre.ky), _mm_mul_ps(sy, z)), z)
        };
        let (ax, ay, az) = sheared(0);
        let (bx, by, bz) = sheared(1);
        let (cx, cy, cz) = sheared(2);
        let mut u = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
        let mut w = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
        let mut v = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
        let zero = _mm_setzero_ps();
        let on_edge =
            _mm_movemask_ps(_mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)), _mm_cmpeq_ps(w, zero)));
        if on_edge != 0 {
            // Rare: redo the lanes on an edge in double precision, as the scalar test does.
            let lanes = |x: __m128| {
                let mut a = [0.0f32; 4];
                _mm_storeu_ps(a.as_mut_ptr(), x);
                a
            };
            let (lax, lay, lbx, lby, lcx, lcy) = (lanes(ax), lanes(ay), lanes(bx), lanes(by), lanes(cx), lanes(cy));
            let (mut lu, mut lv, mut lw) = (lanes(u), lanes(v), lanes(w));
            for k in 0..4 {
                if on_edge & (1 << k) != 0 {
                    let d = |x: &[f32; 4]| x[k] as f64;
                    lu[k] = (d(&lcx) * d(&lby) - d(&lcy) * d(&lbx)) as f32;
                    lv[k] = (d(&lax) * d(&lcy) - d(&lay) * d(&lcx)) as f32;
                    lw[k] = (d(&lbx) * d(&lay) - d(&lby) * d(&lax)) as f32;
                }
            }
            (u, v, w) = (_mm_loadu_ps(lu.as_ptr()), _mm_loadu_ps(lv.as_ptr()), _mm_loadu_ps(lw.as_ptr()));
        }
        let negative = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)), _mm_cmplt_ps(w, zero));
        let positive = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)), _mm_cmpgt_ps(w, zero));
        let det = _mm_add_ps(_mm_add_ps(u, v), w);
        let t_scaled = _mm_add_ps(
            _mm_add_ps(_mm_mul_ps(u, _mm_mul_ps(sz, az)), _mm_mul_ps(v, _mm_mul_ps(sz, bz))),
            _mm_mul_ps(w, _mm_mul_ps(sz, cz)),
        );
        let inv_det = _mm_div_ps(_mm_set1_ps(1.0), det);
        let t = _mm_mul_ps(t_scaled, inv_det);
        let inside = _mm_andnot_ps(_mm_and_ps(negative, positive), _mm_cmpneq_ps(det, zero));
        let in_range = _mm_and_ps(_mm_cmpgt_ps(t, zero), _mm_cmplt_ps(t, _mm_set1_ps(tmax)));
        let valid = _mm_movemask_ps(_mm_and_ps(inside, in_range)) as u32;
        let mut hits = Hits4 { valid, t: [0.0; 4], b1: [0.0; 4], b2: [0.0; 4] };
        if valid != 0 {
            _mm_storeu_ps(hits.t.as_mut_ptr(), t);
            _mm_storeu_ps(hits.b1.as_mut_ptr(), _mm_mul_ps(v, inv_det));
            _mm_storeu_ps(hits.b2.as_mut_ptr(), _mm_mul_ps(w, inv_det));
        }
        hits
    }
}

/// Portable form of the x86_64 version above: the scalar test lane by lane.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub fn intersect4(ray: &Ray, pre: &RayPrecomp, tri: &Triangle4, tmax: f32) -> Hits4 {
    let mut hits = Hits4 { valid: 0, t: [0.0; 4], b1: [0.0; 4], b2: [0.0; 4] };
    for k in 0..4 {
        if let Some((t, b1, b2)) = intersect_triangle(ray, pre, &tri.triangle(k), tmax) {
            hits.valid |= 1 << k;
            (hits.t[k], hits.b1[k], hits.b2[k]) = (t, b1, b2);
        }
    }
    hits
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

    /// The four-lane test must give exactly what the scalar one gives, lane by lane, and
    /// never hit an unused lane; rays through shared vertices exercise the edge fallback.
    #[test]
    fn four_lanes_match_the_scalar_test() {
        let mut rng = crate::sampling::Rng::new(3, 0, 0);
        let mut point = || vec3(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let mut hits = 0;
        for round in 0..2000 {
            let used = 1 + round % 4;
            let tris: Vec<[Vec3; 3]> = (0..used).map(|_| [point(), point(), point()]).collect();
            let packed = Triangle4::pack(&tris);
            let o = point() * 3.0 - Vec3::splat(1.0);
            let target = if round % 3 == 0 { tris[0][1] } else { point() };
            let ray = Ray::new(o, target - o);
            let pre = RayPrecomp::new(&ray);
            let four = intersect4(&ray, &pre, &packed, 2.0);
            for lane in 0..4 {
                let scalar = tris.get(lane).and_then(|t| intersect_triangle(&ray, &pre, t, 2.0));
                assert_eq!(four.valid & (1 << lane) != 0, scalar.is_some(), "round {round} lane {lane}");
                if let Some((t, b1, b2)) = scalar {
                    assert_eq!((four.t[lane], four.b1[lane], four.b2[lane]), (t, b1, b2));
                    assert_eq!(packed.triangle(lane), tris[lane]);
                    hits += 1;
                    // At the end of the ray's range, where the four-lane test's bound before
                    // its division must not reject what the scalar test accepts.
                    for tmax in [t, t.next_up(), t.next_up().next_up()] {
                        let four = intersect4(&ray, &pre, &packed, tmax);
                        let scalar = intersect_triangle(&ray, &pre, &tris[lane], tmax);
                        assert_eq!(four.valid & (1 << lane) != 0, scalar.is_some(), "round {round} tmax {tmax}");
                    }
                }
            }
        }
        assert!(hits > 500, "too few hits to judge: {hits}");
    }
}
