//! `lt`: light tracing. Paths start on the lights (chosen by power) and every vertex is
//! connected to the camera (the t = 1 strategy), splatting onto the film. It sees what
//! reaches the camera through non-specular surfaces only: emitters and surfaces seen in a
//! mirror or through glass, and the environment seen directly, need `pt` or `bpt`.

use super::Integrator;
use crate::film::FilmTile;
use crate::geometry::{offset_origin, Ray};
use crate::material::{BsdfCtx, BsdfModel, TransportMode};
use crate::math::Vec3;
use crate::sampling::Rng;
use crate::scene::{Scene, SurfaceInteraction};

#[derive(Clone, Debug, Default)]
pub struct LightTracer;

/// Veach's correction for shading normals in importance transport (adjoint BSDF):
/// |wi·ns| |wo·ng| / (|wi·ng| |wo·ns|), with `wi` towards the light and `wo` onwards.
pub fn shading_normal_correction(si: &SurfaceInteraction, wi: Vec3, wo: Vec3) -> f32 {
    let num = wi.dot(si.frame.n).abs() * wo.dot(si.ng).abs();
    let den = wi.dot(si.ng).abs() * wo.dot(si.frame.n).abs();
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

impl Integrator for LightTracer {
    fn limitation(&self, scene: &Scene) -> Option<String> {
        if !scene.infinite_lights.is_empty() {
            return Some("light tracing cannot show an environment seen directly".into());
        }
        if scene.camera.aperture_radius <= 0.0 {
            if let Some(m) = scene.materials.iter().find(|m| m.bsdf.has_delta_lobe()) {
                return Some(format!(
                    "light tracing cannot show what a pinhole camera sees in the specular material '{}'",
                    m.name
                ));
            }
        }
        None
    }
    fn name(&self) -> &'static str {
        "lt"
    }
    fn splats_per_sample(&self) -> u64 {
        1
    }
    fn sample(&self, scene: &Scene, _x: usize, _y: usize, rng: &mut Rng, tile: &mut FilmTile) {
        if scene.lights.is_empty() {
            return;
        }
        let cam = &scene.camera;
        let pixels = (scene.settings.width * scene.settings.height) as f32;
        let max_depth = scene.settings.max_depth;
        let bounds = scene.bounds();
        let (center, radius) = (bounds.center(), bounds.bounding_radius().max(1e-3) * 1.01);
        let (li, pmf, _) = scene.light_distribution.sample_discrete(rng.next_f32());
        let light = &scene.lights[li];
        let (u1, u2) = (rng.next_2d(), rng.next_2d());
        let Some(e) = light.sample_le(u1, u2, center, radius) else { return };
        if max_depth == 0 {
            return;
        }
        // The light vertex seen by the camera (s = 1, t = 1). Point-like lights have no area
        // to be seen, as for every other estimator.
        if !e.infinite && !e.delta_pos {
            if let Some(cs) = cam.sample_wi(e.p, rng.next_2d()) {
                let to_cam = cs.wi;
                let cos = e.n.dot(to_cam).abs();
                let le = light.emitted_from(&e, to_cam);
                let o = offset_origin(e.p, e.n, to_cam);
                let shadow = Ray { o, d: cs.lens_point - o, tmax: 1.0 - 1e-4 };
                if !le.is_black() && cs.pdf > 0.0 && !scene.occluded(&shadow) {
                    let c = le * (cos * cs.importance * pixels / (pmf * e.pdf_pos * cs.pdf));
                    tile.splat(cs.raster, c);
                }
            }
        }
        let mut beta = e.beta / pmf;
        let origin = if e.delta_pos || e.infinite { e.p } else { offset_origin(e.p, e.n, e.d) };
        let mut ray = Ray::new(origin, e.d);
        let mut depth = 0i32; // segments traced from the light
        while let Some(si) = scene.intersect(&ray) {
            depth += 1;
            let bsdf = &scene.materials[si.material as usize].bsdf;
            let ctx = BsdfCtx { uv: si.uv, mode: TransportMode::Importance };
            let wi = si.frame.to_local(si.wi);
            // Connect this vertex to the camera: a path of depth + 1 segments.
            if bsdf.has_smooth() && (max_depth < 0 || depth < max_depth) {
                if let Some(cs) = cam.sample_wi(si.p, rng.next_2d()) {
                    let f =
                        bsdf.eval(&ctx, wi, si.frame.to_local(cs.wi)) * shading_normal_correction(&si, si.wi, cs.wi);
                    if !f.is_black() && cs.pdf > 0.0 && !scene.occluded(&si.spawn_ray_to(cs.lens_point)) {
                        tile.splat(cs.raster, beta * f * (cs.importance * pixels / cs.pdf));
                    }
                }
            }
            if max_depth >= 0 && depth + 1 >= max_depth {
                break;
            }
            let Some(bs) = bsdf.sample(&ctx, wi, rng.next_f32(), rng.next_2d()) else { break };
            let wo = si.frame.to_world(bs.wo);
            beta *= bs.weight * shading_normal_correction(&si, si.wi, wo);
            if beta.is_black() || !beta.is_finite() {
                break;
            }
            if depth >= scene.settings.rr_depth as i32 {
                let q = beta.max_component().min(0.95);
                if rng.next_f32() >= q {
                    break;
                }
                beta = beta / q;
            }
            ray = si.spawn_ray(wo);
        }
    }
}
