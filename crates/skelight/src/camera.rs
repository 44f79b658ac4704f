//! Perspective and thin-lens cameras with Mitsuba's conventions (local +z forward, +x left,
//! film x to the right and y down), plus the importance function W_e that light tracing
//! and bidirectional methods connect to.

use crate::geometry::Ray;
use crate::math::{vec2, vec3, Affine, Transform, Vec2, Vec3};
use crate::sampling::concentric_disk;

/// Which field of view the `fov` value measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FovAxis {
    X,
    Y,
    Diagonal,
    Smaller,
    Larger,
}

/// Thin-lens parameters; a zero aperture is a pinhole.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    pub aperture_radius: f32,
    pub focus_distance: f32,
}

impl Lens {
    pub const PINHOLE: Lens = Lens { aperture_radius: 0.0, focus_distance: 0.0 };
}

#[derive(Clone, Debug)]
pub struct Camera {
    pub to_world: Transform,
    pub width: usize,
    pub height: usize,
    /// tan of the half field of view along film x and y, and their reciprocals.
    pub tan_half: Vec2,
    inv_tan_half: Vec2,
    pub aperture_radius: f32,
    pub focus_distance: f32,
    pub near_clip: f32,
    pub position: Vec3,
    pub forward: Vec3,
    /// `to_world` and its inverse in single precision: the per-sample transforms.
    local_to_world: Affine,
    world_to_local: Affine,
    fov_deg: f32,
    fov_axis: FovAxis,
}

/// A camera connection from a scene point (light tracing, t = 1 strategies).
#[derive(Clone, Copy, Debug)]
pub struct CameraSample {
    /// Continuous film position in pixels.
    pub raster: Vec2,
    /// Point on the lens and the unit direction from the scene point to it.
    pub lens_point: Vec3,
    pub wi: Vec3,
    pub dist: f32,
    /// Where the connection crosses the near plane: the segment from there to the scene
    /// point must be unoccluded (see [`Camera::near_point`]).
    pub near_point: Vec3,
    /// Importance W_e along the connection.
    pub importance: f32,
    /// Solid-angle density at the scene point of having sampled this lens point.
    pub pdf: f32,
}

impl Camera {
    /// Near-clip distance of scenes that give none: Mitsuba's default (scene units).
    pub const DEFAULT_NEAR_CLIP: f32 = 0.01;

    pub fn new(
        to_world: Transform,
        width: usize,
        height: usize,
        fov_deg: f32,
        axis: FovAxis,
        lens: Lens,
        near_clip: f32,
    ) -> Camera {
        let Lens { aperture_radius, focus_distance } = lens;
        // A negative or NaN near clip (a glTF znear, say) would start primary rays behind the
        // lens, which connections to it cannot see: no clip instead.
        let near_clip = if near_clip.is_finite() && near_clip > 0.0 { near_clip } else { 0.0 };
        let aspect = width as f32 / height as f32;
        let t = (fov_deg.to_radians() * 0.5).tan();
        let axis = match axis {
            FovAxis::Smaller => {
                if width <= height {
                    FovAxis::X
                } else {
                    FovAxis::Y
                }
            }
            FovAxis::Larger => {
                if width >= height {
                    FovAxis::X
                } else {
                    FovAxis::Y
                }
            }
            a => a,
        };
        let tan_half = match axis {
            FovAxis::X => vec2(t, t / aspect),
            FovAxis::Y => vec2(t * aspect, t),
            _ => {
                let d = (aspect * aspect + 1.0).sqrt();
                vec2(t * aspect / d, t / d)
            }
        };
        let position = to_world.point(Vec3::ZERO);
        let forward = to_world.vector(vec3(0.0, 0.0, 1.0)).normalize();
        Camera {
            to_world,
            width,
            height,
            tan_half,
            inv_tan_half: vec2(1.0 / tan_half.x, 1.0 / tan_half.y),
            aperture_radius,
            focus_distance,
            near_clip,
            position,
            forward,
            local_to_world: Affine::of(&to_world.m),
            world_to_local: Affine::of(&to_world.inv),
            fov_deg,
            fov_axis: axis,
        }
    }

    /// The same camera for another image size (same field of view along its axis).
    pub fn with_resolution(&self, width: usize, height: usize) -> Camera {
        Camera::new(
            self.to_world,
            width,
            height,
            self.fov_deg,
            self.fov_axis,
            Lens { aperture_radius: self.aperture_radius, focus_distance: self.focus_distance },
            self.near_clip,
        )
    }

    fn film_area(&self) -> f32 {
        4.0 * self.tan_half.x * self.tan_half.y
    }

    fn lens_area(&self) -> f32 {
        if self.aperture_radius > 0.0 {
            std::f32::consts::PI * self.aperture_radius * self.aperture_radius
        } else {
            1.0
        }
    }

    /// Local direction through film position `raster` (pixels) from the lens centre.
    fn local_direction(&self, raster: Vec2) -> Vec3 {
        let sx = raster.x / self.width as f32;
        let sy = raster.y / self.height as f32;
        vec3((1.0 - 2.0 * sx) * self.tan_half.x, (1.0 - 2.0 * sy) * self.tan_half.y, 1.0)
    }

    /// Primary ray through film position `raster` (pixels), lens sample `u_lens`, starting
    /// on the near plane (see [`Camera::sample_ray`]).
    /// One ray through each pixel's centre (lens centre), row by row: pictures and ray
    /// benchmarks of what the camera sees.
    pub fn pixel_centre_rays(&self) -> Vec<Ray> {
        use rayon::prelude::*;
        let w = self.width;
        (0..w * self.height)
            .into_par_iter()
            .map(|i| self.generate_ray(vec2((i % w) as f32 + 0.5, (i / w) as f32 + 0.5), vec2(0.5, 0.5)))
            .collect()
    }

    pub fn generate_ray(&self, raster: Vec2, u_lens: Vec2) -> Ray {
        self.sample_ray(raster, u_lens).1
    }

    /// The lens point a primary ray through `raster` leaves from, and the ray itself, whose
    /// origin is moved along it to the near plane (camera-space depth `near_clip`, as
    /// Mitsuba's cameras clip): surfaces nearer than that plane are invisible. The lens
    /// point is the camera vertex of the path; the near plane only hides part of its
    /// first segment (see [`Camera::near_point`]).
    pub fn sample_ray(&self, raster: Vec2, u_lens: Vec2) -> (Vec3, Ray) {
        let d = self.local_direction(raster);
        // Directions stay unnormalised until the last step: the near-clip offset does not
        // depend on their length, and one normalisation in world space is enough.
        let (o, d) = if self.aperture_radius > 0.0 {
            let l = concentric_disk(u_lens) * self.aperture_radius;
            let lens = vec3(l.x, l.y, 0.0);
            (lens, d * self.focus_distance - lens)
        } else {
            (Vec3::ZERO, d)
        };
        let lens = self.local_to_world.point(o);
        let o = o + d * (self.near_clip / d.z);
        (lens, Ray::new(self.local_to_world.point(o), self.local_to_world.vector(d).normalize()))
    }

    /// Where the segment from lens point `lens_world` to scene point `p` crosses the near
    /// plane: the part between it and `p` is what must be unoccluded for the camera to see
    /// `p` (occluders nearer than the plane are clipped away). `None` if `p` itself lies
    /// nearer than the plane (the camera cannot see it). With no near clip, the lens point.
    pub fn near_point(&self, lens_world: Vec3, p: Vec3) -> Option<Vec3> {
        if self.near_clip <= 0.0 {
            return Some(lens_world);
        }
        let (l, q) = (self.world_to_local.point(lens_world), self.world_to_local.point(p));
        if !(q.z >= self.near_clip) {
            return None;
        }
        // The lens lies in the plane z = 0 of camera space.
        let f = (self.near_clip - l.z) / (q.z - l.z);
        Some(lens_world + (p - lens_world) * f)
    }

    /// Film position (pixels) that a world direction leaving lens point `lens_world` maps to
    /// (for a pinhole, which every ray passes through, the direction alone).
    pub fn raster_of(&self, lens_world: Vec3, dir_world: Vec3) -> Option<Vec2> {
        let d = self.world_to_local.vector(dir_world);
        if d.z <= 0.0 {
            return None;
        }
        // Where the ray crosses the plane of focus, seen from the lens centre, per unit depth.
        let (x, y) = if self.aperture_radius > 0.0 {
            let o = self.world_to_local.point(lens_world);
            let p = o + d * ((self.focus_distance - o.z) / d.z);
            let inv_z = 1.0 / p.z;
            (p.x * inv_z, p.y * inv_z)
        } else {
            // Every ray of a pinhole passes through it: the direction alone decides (one
            // division, as this runs for every connection to the camera).
            let inv_z = 1.0 / d.z;
            (d.x * inv_z, d.y * inv_z)
        };
        let sx = (1.0 - x * self.inv_tan_half.x) * 0.5;
        let sy = (1.0 - y * self.inv_tan_half.y) * 0.5;
        if !(0.0..1.0).contains(&sx) || !(0.0..1.0).contains(&sy) {
            return None;
        }
        Some(vec2(sx * self.width as f32, sy * self.height as f32))
    }

    /// Where a ray arriving from the scene crosses the thin-lens aperture, if it does and
    /// the camera sees the ray's origin: (distance along the ray, lens point, film
    /// position). `ray.tmax` is the distance to the first surface along the ray; a surface
    /// nearer to the lens than the near plane does not block it (it is clipped away), one
    /// beyond does. Pinholes have no area to hit.
    pub fn intersect_lens(&self, ray: &Ray) -> Option<(f32, Vec3, Vec2)> {
        if self.aperture_radius <= 0.0 {
            return None;
        }
        let (o, d) = (self.world_to_local.point(ray.o), self.world_to_local.vector(ray.d));
        // Arriving from the front means travelling towards −z in camera space, from a point
        // the camera can see.
        if d.z >= 0.0 || !(o.z >= self.near_clip) {
            return None;
        }
        let t = -o.z / d.z;
        // The ray enters the clipped region at depth `near_clip`.
        let t_near = (self.near_clip - o.z) / d.z;
        if !(t > 0.0 && t_near <= ray.tmax) {
            return None;
        }
        let p = o + d * t;
        if p.x * p.x + p.y * p.y > self.aperture_radius * self.aperture_radius {
            return None;
        }
        let lens_point = self.local_to_world.point(vec3(p.x, p.y, 0.0));
        let raster = self.raster_of(lens_point, -ray.d)?;
        Some((t, lens_point, raster))
    }

    /// Importance W_e for a ray leaving the lens in world direction `dir`.
    pub fn importance(&self, dir: Vec3) -> f32 {
        let cos = dir.dot(self.forward);
        if cos <= 0.0 {
            return 0.0;
        }
        1.0 / (self.film_area() * self.lens_area() * cos.powi(4))
    }

    /// Densities of `generate_ray`: (per unit lens area, per solid angle).
    pub fn pdf_we(&self, dir: Vec3) -> (f32, f32) {
        let cos = dir.dot(self.forward);
        if cos <= 0.0 {
            return (0.0, 0.0);
        }
        (1.0 / self.lens_area(), 1.0 / (self.film_area() * cos.powi(3)))
    }

    /// Samples a lens point as seen from scene point `p` (for connections to the camera).
    pub fn sample_wi(&self, p: Vec3, u: Vec2) -> Option<CameraSample> {
        let lens_local = if self.aperture_radius > 0.0 {
            let l = concentric_disk(u) * self.aperture_radius;
            vec3(l.x, l.y, 0.0)
        } else {
            Vec3::ZERO
        };
        let lens_point = self.local_to_world.point(lens_local);
        let d = lens_point - p;
        // The film position needs the direction only up to its length: found before the
        // square root and division that normalise it, not after (and points off the film
        // are dropped before them).
        let raster = self.raster_of(lens_point, -d)?;
        let near_point = self.near_point(lens_point, p)?;
        let dist2 = d.length_squared();
        if !(dist2 > 0.0) {
            return None;
        }
        let dist = dist2.sqrt();
        let wi = d / dist;
        let cos_lens = (-wi).dot(self.forward);
        if cos_lens <= 0.0 {
            return None;
        }
        let pdf = dist2 / (cos_lens * self.lens_area());
        Some(CameraSample { raster, lens_point, near_point, wi, dist, importance: self.importance(-wi), pdf })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(aperture: f32) -> Camera {
        let t = Transform::look_at([0.0, 0.0, 3.9], [0.0; 3], [0.0, 1.0, 0.0]).unwrap();
        Camera::new(t, 64, 32, 40.0, FovAxis::X, Lens { aperture_radius: aperture, focus_distance: 3.6 }, 0.0)
    }

    #[test]
    fn rays_map_back_to_their_film_position() {
        for aperture in [0.0, 0.1] {
            let cam = camera(aperture);
            for (x, y) in [(0.5, 0.5), (10.25, 20.75), (63.5, 31.5)] {
                let ray = cam.generate_ray(vec2(x, y), vec2(0.3, 0.8));
                let r = cam.raster_of(ray.o, ray.d).unwrap();
                assert!((r.x - x).abs() < 1e-3 && (r.y - y).abs() < 1e-3, "{r:?} vs {x},{y}");
            }
        }
        // Mitsuba's orientation: film left is the camera's left (world -x here), top is up.
        let cam = camera(0.0);
        let left = cam.generate_ray(vec2(0.0, 16.0), vec2(0.5, 0.5));
        let top = cam.generate_ray(vec2(32.0, 0.0), vec2(0.5, 0.5));
        assert!(left.d.x < 0.0 && top.d.y > 0.0);
    }

    /// Negative or NaN near clips (a glTF znear, say) mean no clip, never rays starting
    /// behind the lens.
    #[test]
    fn absurd_near_clips_mean_none() {
        let t = Transform::look_at([0.0, 0.0, 3.9], [0.0; 3], [0.0, 1.0, 0.0]).unwrap();
        for near in [-1.0, f32::NAN, f32::INFINITY] {
            let cam = Camera::new(t, 8, 8, 40.0, FovAxis::X, Lens::PINHOLE, near);
            assert_eq!(cam.near_clip, 0.0);
            assert!((cam.generate_ray(vec2(4.0, 4.0), vec2(0.5, 0.5)).o - cam.position).length() < 1e-6);
        }
    }

    /// A ray leaving the lens towards the scene, reversed, hits the lens where it left and
    /// maps to the film position it was generated for.
    #[test]
    fn reversed_camera_rays_hit_the_lens() {
        let cam = camera(0.1);
        let ray = cam.generate_ray(vec2(20.5, 7.25), vec2(0.9, 0.2));
        let far = ray.at(5.0);
        let back = Ray::new(far, -ray.d);
        let (t, p, raster) = cam.intersect_lens(&back).expect("hits the aperture");
        assert!((t - 5.0).abs() < 1e-3 && (p - ray.o).length() < 1e-3);
        assert!((raster.x - 20.5).abs() < 1e-2 && (raster.y - 7.25).abs() < 1e-2, "{raster:?}");
        assert!(cam.intersect_lens(&ray).is_none(), "leaving rays do not hit it");
        assert!(camera(0.0).intersect_lens(&back).is_none(), "pinholes have no area");
    }

    /// ∫ W_e cosθ dω over the film's directions is 1/lens_area (importance is normalised).
    #[test]
    fn importance_integrates_to_one_over_the_film() {
        let cam = camera(0.0);
        let n = 200;
        let mut sum = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let raster = vec2((i as f32 + 0.5) / n as f32 * 64.0, (j as f32 + 0.5) / n as f32 * 32.0);
                let d = cam.local_direction(raster);
                let dir = cam.to_world.vector(d).normalize();
                let cos = dir.dot(cam.forward);
                // dω = dA_film cos³θ on the z=1 plane.
                let d_area = cam.film_area() / (n * n) as f32;
                sum += (cam.importance(dir) * cos * d_area * cos.powi(3)) as f64;
            }
        }
        assert!((sum - 1.0).abs() < 1e-3, "{sum}");
    }
}
