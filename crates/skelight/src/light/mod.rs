//! Light sources: emissive meshes, point, spot, directional, constant, and environments
//! (images and Mitsuba 3's sun and sky). Sampling returns solid-angle densities at the
//! receiving point.

mod sunsky;
pub use sunsky::{DateTime, SunPosition, SunSky, SunSkyParams, SUN_APERTURE_DEG};

use crate::color::Rgb;
use crate::imageio::Image;
use crate::math::{vec2, vec3, Frame, Transform, Vec2, Vec3, INV_PI, PI};
use crate::sampling::{uniform_sphere, uniform_triangle, Distribution1D, Distribution2D, UNIFORM_SPHERE_PDF};

/// A sampled connection from a receiving point to a light.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the receiver towards the light.
    pub wi: Vec3,
    /// Distance to the sampled point (infinite for distant lights).
    pub dist: f32,
    /// Emitted radiance (or intensity/dist² for delta lights) arriving along `-wi`.
    pub radiance: Rgb,
    /// Solid-angle density at the receiver (1 for delta lights).
    pub pdf: f32,
    pub delta: bool,
    /// Point on the light and its normal (for shadow rays spawned from the light side).
    pub p: Vec3,
    pub n: Vec3,
}

/// A light at infinity around the scene, seen through directions only.
pub trait Environment: std::fmt::Debug + Send + Sync {
    /// Radiance arriving from world direction `d` (unit, pointing away from the scene).
    fn eval(&self, d: Vec3) -> Rgb;
    /// Samples an incoming direction; returns (direction, radiance, solid-angle pdf).
    fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)>;
    /// Solid-angle density of `sample` producing world direction `d`.
    fn pdf(&self, d: Vec3) -> f32;
    /// Radiance integrated over all directions, ∫ L dω, averaged over the channels (for
    /// choosing lights by power).
    fn radiance_integral(&self) -> f32;
    /// The lat-long map this environment is, if it is one (the GPU renders these alone).
    fn as_lat_long(&self) -> Option<&EnvMap> {
        None
    }
}

/// Lat-long environment map with Mitsuba 3's conventions and luminance importance sampling.
#[derive(Debug)]
pub struct EnvMap {
    image: Image,
    scale: f32,
    to_world: Transform,
    distribution: Distribution2D,
    mean: Rgb,
}

impl EnvMap {
    pub fn new(image: Image, scale: f32, to_world: Transform) -> EnvMap {
        let (w, h) = (image.width, image.height.max(2));
        // Cells between texel rows j and j+1 (vertex-centred in v), wrapping in u.
        let rows = h - 1;
        let mut weights = vec![0.0f32; w * rows];
        for j in 0..rows {
            let theta = PI * (j as f32 + 0.5) / rows as f32;
            for i in 0..w {
                let corners = [
                    (i, j),
                    ((i + 1) % w, j),
                    (i, (j + 1).min(image.height - 1)),
                    ((i + 1) % w, (j + 1).min(image.height - 1)),
                ];
                let m = corners.iter().map(|&(x, y)| image.get(x, y).max_component().max(0.0)).fold(0.0, f32::max);
                weights[j * w + i] = m * theta.sin();
            }
        }
        let distribution = Distribution2D::new(&weights, w, rows);
        let mean = image.mean() * scale;
        EnvMap { image, scale, to_world, distribution, mean }
    }

    /// The map's texels (linear RGB, unscaled), its scale and its orientation.
    pub fn image(&self) -> &Image {
        &self.image
    }
    pub fn scale(&self) -> f32 {
        self.scale
    }
    pub fn to_world(&self) -> &Transform {
        &self.to_world
    }
    /// Its sampling distribution over the cells between texel rows (rows × width).
    pub fn distribution(&self) -> &Distribution2D {
        &self.distribution
    }

    fn texel(&self, x: usize, y: usize) -> Rgb {
        self.image.get(x % self.image.width, y.min(self.image.height - 1))
    }

    /// Lat-long coordinates of world direction `d` and sinθ. θ and sinθ come from the
    /// horizontal component, which stays accurate next to the poles (1 − y² does not).
    fn uv_of(&self, d: Vec3) -> (Vec2, f32) {
        let l = self.to_world.inverse().vector(d).normalize();
        let horizontal = (l.x * l.x + l.z * l.z).sqrt();
        let uv = vec2(l.x.atan2(-l.z) * crate::math::INV_2PI, horizontal.atan2(l.y) * INV_PI);
        (uv, horizontal)
    }

    fn eval_uv(&self, uv: Vec2) -> Rgb {
        let (w, h) = (self.image.width, self.image.height);
        let mut u = uv.x - 0.5 / w as f32;
        u -= u.floor();
        let x = u * w as f32;
        let y = uv.y.clamp(0.0, 1.0) * (h - 1).max(1) as f32;
        let (x0, y0) = ((x as usize).min(w - 1), (y as usize).min(h.saturating_sub(2)));
        let (fx, fy) = (x - x0 as f32, (y - y0 as f32).clamp(0.0, 1.0));
        let v = self.texel(x0, y0) * ((1.0 - fx) * (1.0 - fy))
            + self.texel(x0 + 1, y0) * (fx * (1.0 - fy))
            + self.texel(x0, y0 + 1) * ((1.0 - fx) * fy)
            + self.texel(x0 + 1, y0 + 1) * (fx * fy);
        v * self.scale
    }

    fn dir_from_uv(&self, uv: Vec2) -> (Vec3, f32) {
        let (phi, theta) = (uv.x * 2.0 * PI, uv.y * PI);
        let (sp, cp) = phi.sin_cos();
        let (st, ct) = theta.sin_cos();
        (self.to_world.vector(vec3(sp * st, ct, -cp * st)).normalize(), st)
    }
}

impl Environment for EnvMap {
    fn eval(&self, d: Vec3) -> Rgb {
        self.eval_uv(self.uv_of(d).0)
    }

    fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        let (p, pdf_uv) = self.distribution.sample(u);
        let w = self.image.width as f32;
        let uv = vec2((p.x + 0.5 / w).fract(), p.y);
        let (d, sin_theta) = self.dir_from_uv(uv);
        if sin_theta <= 0.0 || pdf_uv <= 0.0 {
            return None;
        }
        let pdf = pdf_uv / (2.0 * PI * PI * sin_theta);
        Some((d, self.eval_uv(uv), pdf))
    }

    fn pdf(&self, d: Vec3) -> f32 {
        let (uv, sin_theta) = self.uv_of(d);
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let w = self.image.width as f32;
        let mut px = uv.x - 0.5 / w;
        px -= px.floor();
        self.distribution.pdf(vec2(px, uv.y)) / (2.0 * PI * PI * sin_theta)
    }

    fn radiance_integral(&self) -> f32 {
        4.0 * PI * self.mean.mean()
    }

    fn as_lat_long(&self) -> Option<&EnvMap> {
        Some(self)
    }
}

/// Triangles of one emissive mesh, chosen in proportion to their area.
#[derive(Clone, Debug)]
pub struct AreaEmitter {
    pub mesh: u32,
    pub radiance: Rgb,
    pub triangles: Vec<[Vec3; 3]>,
    /// Per-vertex shading normals of each triangle, if the mesh has them (emission side).
    pub normals: Option<Vec<[Vec3; 3]>>,
    pub area: f32,
    pub distribution: Distribution1D,
    /// Unit geometric normal of each triangle (winding order), worked out once rather than
    /// per light sample.
    geometric_normals: Vec<Vec3>,
}

/// A sampled ray leaving a light (for light tracing and bidirectional methods).
#[derive(Clone, Copy, Debug)]
pub struct EmissionSample {
    /// Origin on the light (a point far outside the scene for distant lights).
    pub p: Vec3,
    /// Geometric normal at the origin (zero for point-like lights).
    pub n: Vec3,
    pub d: Vec3,
    /// Initial throughput: emitted radiance (or intensity) × |cos| / (pdf_pos · pdf_dir).
    pub beta: Rgb,
    /// Density of the origin per unit area (1 for delta positions).
    pub pdf_pos: f32,
    /// Density of the direction per solid angle (1 for delta directions).
    pub pdf_dir: f32,
    /// The origin is a point (point, spot) or infinitely far (directional, environment).
    pub delta_pos: bool,
    pub infinite: bool,
}

/// A point drawn uniformly on an area emitter.
struct AreaPoint {
    p: Vec3,
    /// Geometric normal.
    ng: Vec3,
    /// Shading normal, not normalised: it only decides the emitting side.
    ns: Vec3,
}

impl AreaEmitter {
    /// The emitter made of `triangles` (with per-vertex shading normals if given), sampled
    /// by area; `None` if they have no area.
    pub fn new(mesh: u32, radiance: Rgb, triangles: Vec<[Vec3; 3]>, normals: Option<Vec<[Vec3; 3]>>) -> Option<Self> {
        let cross = |t: &[Vec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]);
        let areas: Vec<f32> = triangles.iter().map(|t| 0.5 * cross(t).length()).collect();
        let area: f32 = areas.iter().sum();
        if !(area > 0.0) {
            return None;
        }
        // Degenerate triangles are never sampled (zero area); their normal does not matter.
        let geometric_normals = triangles
            .iter()
            .map(|t| {
                let c = cross(t);
                if c.length_squared() > 0.0 {
                    c.normalize()
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        let distribution = Distribution1D::new(&areas);
        Some(AreaEmitter { mesh, radiance, triangles, normals, area, distribution, geometric_normals })
    }

    /// Density per solid angle, at the receiver, of a point drawn uniformly by area, with
    /// geometric normal `ng` at offset `d` from the receiver (|d|² = `dist2`, |d| = `dist`):
    /// dist² / (cos · area) with cos = |ng · d| / dist, from the unnormalised d so that its one
    /// division need not wait for the direction's. `None` for a point seen edge-on.
    #[inline]
    fn solid_angle_pdf(&self, ng: Vec3, d: Vec3, dist2: f32, dist: f32) -> Option<f32> {
        let projected = ng.dot(d).abs() * self.area;
        (projected > 0.0).then(|| dist2 * dist / projected)
    }

    fn sample_point(&self, u: Vec2) -> AreaPoint {
        let (tri, _, rem) = self.distribution.sample_discrete(u.x);
        let b = uniform_triangle(vec2(rem, u.y));
        let [v0, v1, v2] = self.triangles[tri];
        let p = v0 * (1.0 - b.x - b.y) + v1 * b.x + v2 * b.y;
        let ng = self.geometric_normals[tri];
        let ns = match &self.normals {
            Some(n) => n[tri][0] * (1.0 - b.x - b.y) + n[tri][1] * b.x + n[tri][2] * b.y,
            None => ng,
        };
        AreaPoint { p, ng, ns }
    }
}

#[derive(Debug)]
pub enum Light {
    Area(AreaEmitter),
    Point {
        position: Vec3,
        intensity: Rgb,
    },
    Spot {
        position: Vec3,
        frame: Frame,
        intensity: Rgb,
        cos_cutoff: f32,
        cutoff: f32,
        beam_width: f32,
    },
    /// Light travelling along `direction` (unit), `irradiance` on a perpendicular plane.
    Directional {
        direction: Vec3,
        irradiance: Rgb,
    },
    Constant {
        radiance: Rgb,
    },
    Env(Box<dyn Environment>),
}

impl Light {
    pub fn is_infinite(&self) -> bool {
        matches!(self, Light::Constant { .. } | Light::Env(_) | Light::Directional { .. })
    }
    pub fn is_delta(&self) -> bool {
        matches!(self, Light::Point { .. } | Light::Spot { .. } | Light::Directional { .. })
    }

    /// Approximate emitted power, for choosing lights in proportion to it.
    pub fn power(&self, scene_radius: f32) -> f32 {
        let area_disk = PI * scene_radius * scene_radius;
        match self {
            Light::Area(a) => PI * a.area * a.radiance.mean(),
            Light::Point { intensity, .. } => 4.0 * PI * intensity.mean(),
            Light::Spot { intensity, cos_cutoff, .. } => 2.0 * PI * (1.0 - cos_cutoff) * intensity.mean(),
            Light::Directional { irradiance, .. } => area_disk * irradiance.mean(),
            Light::Constant { radiance } => PI * area_disk * radiance.mean(),
            Light::Env(e) => 0.25 * area_disk * e.radiance_integral(),
        }
    }

    /// Spot falloff: full inside the beam, linear in angle to zero at the cutoff (Mitsuba 3).
    fn spot_falloff(local: Vec3, cos_cutoff: f32, cutoff: f32, beam_width: f32) -> f32 {
        let cos_t = local.z;
        if cos_t <= cos_cutoff {
            return 0.0;
        }
        if cos_t >= beam_width.cos() {
            return 1.0;
        }
        ((cutoff - cos_t.clamp(-1.0, 1.0).acos()) / (cutoff - beam_width)).clamp(0.0, 1.0)
    }

    /// Samples light arriving at `p`.
    pub fn sample_li(&self, p: Vec3, u: Vec2) -> Option<LightSample> {
        match self {
            Light::Area(a) => {
                let AreaPoint { p: q, ng, ns } = a.sample_point(u);
                let d = q - p;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                let dist = dist2.sqrt();
                let pdf = a.solid_angle_pdf(ng, d, dist2, dist)?;
                let wi = d / dist;
                let radiance = if ns.dot(d) < 0.0 { a.radiance } else { Rgb::BLACK };
                Some(LightSample { wi, dist, radiance, pdf, delta: false, p: q, n: ng })
            }
            Light::Point { position, intensity } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                Some(LightSample {
                    wi: d / dist,
                    dist,
                    radiance: *intensity / dist2,
                    pdf: 1.0,
                    delta: true,
                    p: *position,
                    n: -d / dist,
                })
            }
            Light::Spot { position, frame, intensity, cos_cutoff, cutoff, beam_width } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                let wi = d / dist;
                let f = Self::spot_falloff(frame.to_local(-wi), *cos_cutoff, *cutoff, *beam_width);
                if f <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    dist,
                    radiance: *intensity * (f / dist2),
                    pdf: 1.0,
                    delta: true,
                    p: *position,
                    n: -wi,
                })
            }
            Light::Directional { direction, irradiance } => Some(LightSample {
                wi: -*direction,
                dist: f32::INFINITY,
                radiance: *irradiance,
                pdf: 1.0,
                delta: true,
                p: p - *direction * 1e30,
                n: *direction,
            }),
            Light::Constant { radiance } => {
                let wi = uniform_sphere(u);
                Some(LightSample {
                    wi,
                    dist: f32::INFINITY,
                    radiance: *radiance,
                    pdf: UNIFORM_SPHERE_PDF,
                    delta: false,
                    p: p + wi * 1e30,
                    n: -wi,
                })
            }
            Light::Env(e) => {
                let (wi, radiance, pdf) = e.sample(u)?;
                Some(LightSample { wi, dist: f32::INFINITY, radiance, pdf, delta: false, p: p + wi * 1e30, n: -wi })
            }
        }
    }

    /// Samples a ray leaving the light. Distant lights start on a disk of the scene's
    /// bounding sphere (`center`, `radius`), perpendicular to their direction.
    pub fn sample_le(&self, u1: Vec2, u2: Vec2, center: Vec3, radius: f32) -> Option<EmissionSample> {
        let distant = |d: Vec3, radiance: Rgb, pdf_dir: f32| {
            // Light travels along d; start on a disk behind the scene.
            let f = Frame::from_normal(d);
            let disk = crate::sampling::concentric_disk(u1) * radius;
            let p = center - d * radius + f.s * disk.x + f.t * disk.y;
            let pdf_pos = 1.0 / (PI * radius * radius);
            (pdf_dir > 0.0).then(|| EmissionSample {
                p,
                n: d,
                d,
                beta: radiance / (pdf_pos * pdf_dir),
                pdf_pos,
                pdf_dir,
                delta_pos: false,
                infinite: true,
            })
        };
        match self {
            Light::Area(a) => {
                let AreaPoint { p, ng, ns } = a.sample_point(u1);
                let ng = if ns.dot(ng) < 0.0 { -ng } else { ng };
                let local = crate::sampling::cosine_hemisphere(u2);
                let d = Frame::from_normal(ng).to_world(local);
                let pdf_dir = crate::sampling::cosine_hemisphere_pdf(local.z);
                let le = if ns.dot(d) > 0.0 { a.radiance } else { Rgb::BLACK };
                if pdf_dir <= 0.0 || le.is_black() {
                    return None;
                }
                let pdf_pos = 1.0 / a.area;
                Some(EmissionSample {
                    p,
                    n: ng,
                    d,
                    beta: le * (local.z / (pdf_pos * pdf_dir)),
                    pdf_pos,
                    pdf_dir,
                    delta_pos: false,
                    infinite: false,
                })
            }
            Light::Point { position, intensity } => {
                let d = uniform_sphere(u2);
                Some(EmissionSample {
                    p: *position,
                    n: Vec3::ZERO,
                    d,
                    beta: *intensity / UNIFORM_SPHERE_PDF,
                    pdf_pos: 1.0,
                    pdf_dir: UNIFORM_SPHERE_PDF,
                    delta_pos: true,
                    infinite: false,
                })
            }
            Light::Spot { position, frame, intensity, cos_cutoff, cutoff, beam_width } => {
                let local = crate::sampling::uniform_cone(u2, *cos_cutoff);
                let pdf_dir = crate::sampling::uniform_cone_pdf(*cos_cutoff);
                let f = Self::spot_falloff(local, *cos_cutoff, *cutoff, *beam_width);
                if f <= 0.0 {
                    return None;
                }
                Some(EmissionSample {
                    p: *position,
                    n: Vec3::ZERO,
                    d: frame.to_world(local),
                    beta: *intensity * (f / pdf_dir),
                    pdf_pos: 1.0,
                    pdf_dir,
                    delta_pos: true,
                    infinite: false,
                })
            }
            Light::Directional { direction, irradiance } => distant(*direction, *irradiance, 1.0),
            Light::Constant { radiance } => {
                let to_light = uniform_sphere(u2);
                distant(-to_light, *radiance, UNIFORM_SPHERE_PDF)
            }
            Light::Env(e) => {
                let (to_light, radiance, pdf) = e.sample(u2)?;
                distant(-to_light, radiance, pdf)
            }
        }
    }

    /// What a point of this light sends towards direction `d` (unit): radiance for area
    /// lights (`n` the emitting side's normal), intensity × falloff for point and spot lights.
    pub fn emitted_towards(&self, n: Vec3, d: Vec3) -> Rgb {
        match self {
            Light::Area(a) if n.dot(d) > 0.0 => a.radiance,
            Light::Point { intensity, .. } => *intensity,
            Light::Spot { frame, intensity, cos_cutoff, cutoff, beam_width, .. } => {
                *intensity * Self::spot_falloff(frame.to_local(d), *cos_cutoff, *cutoff, *beam_width)
            }
            _ => Rgb::BLACK,
        }
    }

    /// Solid-angle density of `sample_li` from `p` producing the point `q` (normal `ng`) on
    /// an area light.
    pub fn pdf_li_area(&self, p: Vec3, q: Vec3, ng: Vec3) -> f32 {
        match self {
            Light::Area(a) => {
                let d = q - p;
                let dist2 = d.length_squared();
                a.solid_angle_pdf(ng, d, dist2, dist2.sqrt()).unwrap_or(0.0)
            }
            _ => 0.0,
        }
    }

    /// Solid-angle density with which `sample_le` sends light from a vertex with normal `n`
    /// (area lights) in direction `d`; zero for distant lights (see `pdf_le_origin`).
    pub fn pdf_le_direction(&self, n: Vec3, d: Vec3) -> f32 {
        match self {
            Light::Area(_) => crate::sampling::cosine_hemisphere_pdf(n.dot(d).max(0.0)),
            Light::Point { .. } => UNIFORM_SPHERE_PDF,
            Light::Spot { frame, cos_cutoff, .. } if frame.to_local(d).z > *cos_cutoff => {
                crate::sampling::uniform_cone_pdf(*cos_cutoff)
            }
            _ => 0.0,
        }
    }

    /// Density of the origin `sample_le` (and `sample_li`) picks: per unit area on area
    /// lights, 1 for point-like lights, and for distant lights the solid-angle density of the
    /// direction the light arrives from (`travel` is the direction light travels).
    pub fn pdf_le_origin(&self, travel: Vec3) -> f32 {
        match self {
            Light::Area(a) => 1.0 / a.area,
            Light::Point { .. } | Light::Spot { .. } | Light::Directional { .. } => 1.0,
            Light::Constant { .. } | Light::Env(_) => self.pdf_infinite(-travel),
        }
    }

    /// Whether a ray can hit this light (it has area or surrounds the scene).
    pub fn can_be_hit(&self) -> bool {
        matches!(self, Light::Area(_) | Light::Constant { .. } | Light::Env(_))
    }

    /// Radiance from an infinite light along a ray leaving the scene in direction `d`.
    pub fn eval_infinite(&self, d: Vec3) -> Rgb {
        match self {
            Light::Constant { radiance } => *radiance,
            Light::Env(e) => e.eval(d),
            _ => Rgb::BLACK,
        }
    }

    /// Solid-angle density of `sample_li` producing direction `d` for infinite lights.
    pub fn pdf_infinite(&self, d: Vec3) -> f32 {
        match self {
            Light::Constant { .. } => UNIFORM_SPHERE_PDF,
            Light::Env(e) => e.pdf(d),
            _ => 0.0,
        }
    }
}

/// Checks an environment's importance sampling: `sample`'s estimate of ∫ L dω equals a
/// uniform-sphere estimate of `rest`'s plus `unseen` (the exact integral of a part too small
/// for uniform directions to find, left out of `rest`), within 5 standard errors; `pdf` and
/// `eval` agree with what `sample` returns.
#[cfg(test)]
pub(crate) fn check_environment_sampling(env: &dyn Environment, rest: &dyn Environment, unseen: f64, n: usize) {
    use crate::sampling::Rng;
    let mut rng = Rng::new(n as u64, 3, 3);
    let (mut a, mut a2, mut b, mut b2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for _ in 0..n {
        if let Some((d, l, pdf)) = env.sample(rng.next_2d()) {
            assert!((env.pdf(d) - pdf).abs() <= 2e-3 * pdf, "{} vs {pdf}", env.pdf(d));
            assert!((env.eval(d) - l).map(f32::abs).max_component() <= 1e-3 * l.max_component().max(1.0));
            let v = (l.mean() / pdf) as f64;
            a += v;
            a2 += v * v;
        }
        let d = uniform_sphere(rng.next_2d());
        let v = (rest.eval(d).mean() / UNIFORM_SPHERE_PDF) as f64;
        b += v;
        b2 += v * v;
    }
    let nf = n as f64;
    let (ma, mb) = (a / nf, b / nf);
    let se = ((a2 / nf - ma * ma) / nf + (b2 / nf - mb * mb) / nf).sqrt();
    assert!((ma - mb - unseen).abs() < 5.0 * se, "{ma} vs {mb} + {unseen} ± {se}");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::rgb;
    use crate::sampling::Rng;

    fn test_env() -> EnvMap {
        let mut img = Image::new(8, 5);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = rgb(0.1 + (i % 7) as f32, 0.5, 0.2 * (i % 3) as f32);
        }
        img.pixels[13] = rgb(50.0, 40.0, 30.0);
        EnvMap::new(img, 1.5, Transform::rotate([0.0, 1.0, 0.0], 30.0).unwrap())
    }

    #[test]
    fn envmap_sampling_is_unbiased_and_consistent() {
        let env = test_env();
        check_environment_sampling(&env, &env, 0.0, 200_000);
    }

    #[test]
    fn area_light_pdf_matches_sampling() {
        let tris = vec![
            [vec3(0.0, 1.0, 0.0), vec3(1.0, 1.0, 0.0), vec3(0.0, 1.0, 1.0)],
            [vec3(0.0, 1.0, 0.0), vec3(-2.0, 1.0, 0.0), vec3(0.0, 1.0, -1.0)],
        ];
        let light = Light::Area(AreaEmitter::new(0, Rgb::WHITE, tris, None).unwrap());
        let mut rng = Rng::new(1, 0, 0);
        for _ in 0..100 {
            let s = light.sample_li(Vec3::ZERO, rng.next_2d()).unwrap();
            let pdf = light.pdf_li_area(Vec3::ZERO, s.p, s.n);
            assert!((pdf - s.pdf).abs() < 1e-3 * pdf);
        }
    }

    #[test]
    fn spot_falloff_is_linear_in_angle() {
        let (cutoff, beam) = (30f32.to_radians(), 20f32.to_radians());
        let at = |deg: f32| {
            Light::spot_falloff(vec3(deg.to_radians().sin(), 0.0, deg.to_radians().cos()), cutoff.cos(), cutoff, beam)
        };
        assert_eq!(at(10.0), 1.0);
        assert!((at(25.0) - 0.5).abs() < 1e-4);
        assert_eq!(at(31.0), 0.0);
    }
}
