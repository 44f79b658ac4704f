//! Analytic spheres. Mitsuba's `sphere` shape is an exact sphere; a tessellation with
//! interpolated normals has shading normals that differ from its facets' normals, and light
//! transport through it then needs Veach's shading-normal correction, which grows without
//! bound at grazing incidence on a facet: light paths through a glass ball pick up
//! fireflies that paths from the camera do not (see docs/benchmarks.md, caustic study).
//! An exact sphere has one normal, so no correction.

use crate::math::{vec2, vec3, Transform, Vec2, Vec3, PI};

use super::Ray;

/// A sphere in world space, with the object axes its texture coordinates follow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
    /// The object's x, y and z axes in world space (unit length, orthogonal).
    pub axes: [Vec3; 3],
    /// Normals point inwards (`flip_normals`).
    pub inward: bool,
}

impl Sphere {
    /// The unit sphere at the origin under `to_world`, if that transform keeps it a sphere
    /// (rotation, uniform scale, translation, mirroring); `None` for an ellipsoid.
    pub fn from_transform(to_world: &Transform, inward: bool) -> Option<Sphere> {
        let columns = [vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0)].map(|a| to_world.vector(a));
        let radius = columns[0].length();
        let similar = columns.iter().all(|c| (c.length() - radius).abs() <= 1e-5 * radius)
            && columns[0].dot(columns[1]).abs() <= 1e-5 * radius * radius
            && columns[1].dot(columns[2]).abs() <= 1e-5 * radius * radius
            && columns[0].dot(columns[2]).abs() <= 1e-5 * radius * radius;
        let projective = to_world.m[3] != [0.0, 0.0, 0.0, 1.0];
        if !(radius > 0.0) || !radius.is_finite() || !similar || projective {
            return None;
        }
        let center = to_world.point(Vec3::ZERO);
        Some(Sphere { center, radius, axes: columns.map(|c| c / radius), inward })
    }

    /// Distance along `ray` to the nearest intersection in `(0, tmax)`. Computed in double
    /// precision with the cancellation-free form of the quadratic's roots, so that rays
    /// leaving the surface (offset by `offset_origin`) do not find it again.
    pub fn intersect(&self, ray: &Ray, tmax: f32) -> Option<f32> {
        let f = |v: Vec3| [v.x as f64, v.y as f64, v.z as f64];
        let (o, d, c) = (f(ray.o), f(ray.d), f(self.center));
        let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let a = dot(d, d);
        let b = dot(oc, d);
        let r = self.radius as f64;
        let cc = dot(oc, oc) - r * r;
        // Discriminant as r² − |oc − (oc·d/|d|²) d|², which keeps its precision far away.
        let along = b / a;
        let perp = [oc[0] - along * d[0], oc[1] - along * d[1], oc[2] - along * d[2]];
        let disc = a * (r * r - dot(perp, perp));
        if !(disc >= 0.0) || a == 0.0 {
            return None;
        }
        let q = -(b + disc.sqrt().copysign(b));
        let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, cc / q) };
        let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        let tmax = tmax as f64;
        [near, far].into_iter().find(|&t| t > 0.0 && t < tmax).map(|t| t as f32)
    }

    /// The point of the surface nearest to `p`, its outward normal, texture coordinates
    /// (u = φ/2π, v = θ/π in object axes, as Mitsuba) and the derivatives of the point
    /// along u and v.
    pub fn surface_at(&self, p: Vec3) -> (Vec3, Vec3, Vec2, Vec3, Vec3) {
        let d = p - self.center;
        let outward = if d.length_squared() > 0.0 { d.normalize() } else { self.axes[2] };
        let point = self.center + outward * self.radius;
        let local = vec3(outward.dot(self.axes[0]), outward.dot(self.axes[1]), outward.dot(self.axes[2]));
        let theta = local.z.clamp(-1.0, 1.0).acos();
        let mut phi = local.y.atan2(local.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let uv = vec2(phi / (2.0 * PI), theta / PI);
        let [x, y, z] = self.axes;
        let (st, ct, sp, cp) = (theta.sin(), theta.cos(), phi.sin(), phi.cos());
        let dpdu = (y * (st * cp) - x * (st * sp)) * (2.0 * PI * self.radius);
        let dpdv = (x * (ct * cp) + y * (ct * sp) - z * st) * (PI * self.radius);
        (point, outward, uv, dpdu, dpdv)
    }

    /// The normal the surface faces with (outward unless flipped).
    pub fn facing(&self, outward: Vec3) -> Vec3 {
        if self.inward {
            -outward
        } else {
            outward
        }
    }

    pub fn bounds(&self) -> crate::math::Aabb {
        let r = Vec3::splat(self.radius);
        crate::math::Aabb { min: self.center - r, max: self.center + r }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{offset_origin, ray_epsilon};
    use crate::sampling::Rng;

    fn ball() -> Sphere {
        let t = Transform::translate([0.5, -1.0, 2.0])
            .compose(&Transform::rotate([1.0, 2.0, 0.5], 30.0).unwrap())
            .compose(&Transform::scale([0.7, 0.7, 0.7]).unwrap());
        Sphere::from_transform(&t, false).expect("a similarity keeps a sphere")
    }

    #[test]
    fn only_similarities_give_spheres() {
        let b = ball();
        assert!((b.radius - 0.7).abs() < 1e-6 && (b.center - vec3(0.5, -1.0, 2.0)).length() < 1e-6);
        assert!(Sphere::from_transform(&Transform::scale([1.0, 2.0, 1.0]).unwrap(), false).is_none());
    }

    /// Hits lie on the sphere, are the nearest crossing, and rays leaving the surface at
    /// the offset origin do not find it again.
    #[test]
    fn hits_are_on_the_surface_and_leaving_rays_escape() {
        let b = ball();
        let mut rng = Rng::new(7, 0, 0);
        let mut hits = 0;
        for _ in 0..10_000 {
            let o = b.center + vec3(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * 6.0;
            let target = b.center + vec3(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * 1.6;
            let ray = Ray::new(o, target - o);
            let inside = (o - b.center).length() < b.radius;
            let Some(t) = b.intersect(&ray, f32::INFINITY) else {
                assert!(!inside, "a ray from inside must leave");
                continue;
            };
            hits += 1;
            let p = ray.at(t);
            assert!(
                ((p - b.center).length() - b.radius).abs() < 1e-5,
                "off the surface by {}",
                (p - b.center).length()
            );
            assert!(b.intersect(&ray, t * 0.999).is_none(), "a nearer crossing was skipped");
            let (q, n, _, _, _) = b.surface_at(p);
            // Leaving outwards (any direction with d·n ≥ 0.7): nothing.
            let out = Ray::new(offset_origin(q, n, n), n + ray.d.normalize() * 0.3);
            assert!(b.intersect(&out, f32::INFINITY).is_none(), "an outgoing ray hit its own sphere");
            // Going in through the centre from the origin offset by ε: the far side at 2r − ε,
            // up to float rounding of points of size ~5 (a few ulp, < 1e-5).
            let eps = ray_epsilon(q);
            let into = Ray::new(offset_origin(q, n, -n), -n);
            let far = b.intersect(&into, f32::INFINITY).expect("a ray into the ball leaves it");
            assert!((far - (2.0 * b.radius - eps)).abs() < 1e-5, "through the centre: {far}");
        }
        assert!(hits > 1000);
    }

    /// uv follows the object's axes; the derivatives are those of the parameterisation.
    #[test]
    fn uv_and_derivatives_match_finite_differences() {
        let b = ball();
        for (u, v) in [(0.1f32, 0.3f32), (0.6, 0.5), (0.9, 0.8)] {
            let at = |u: f32, v: f32| {
                let (phi, theta) = (2.0 * PI * u, PI * v);
                let [x, y, z] = b.axes;
                b.center + (x * (theta.sin() * phi.cos()) + y * (theta.sin() * phi.sin()) + z * theta.cos()) * b.radius
            };
            let (_, _, uv, dpdu, dpdv) = b.surface_at(at(u, v));
            assert!((uv.x - u).abs() < 1e-4 && (uv.y - v).abs() < 1e-4, "{uv:?} vs ({u}, {v})");
            // Central differences: truncation ~ (2πh)²/6 ≈ 7e-6 relative, rounding ~ 3 ulp of
            // |p| ≈ 2.5 over 2h ≈ 1e-3 absolute; 2e-3 covers both with room.
            let h = 1e-3;
            let du = (at(u + h, v) - at(u - h, v)) / (2.0 * h);
            let dv = (at(u, v + h) - at(u, v - h)) / (2.0 * h);
            assert!((du - dpdu).length() < 2e-3 * dpdu.length().max(1.0), "{du:?} vs {dpdu:?}");
            assert!((dv - dpdv).length() < 2e-3 * dpdv.length().max(1.0), "{dv:?} vs {dpdv:?}");
        }
    }
}
