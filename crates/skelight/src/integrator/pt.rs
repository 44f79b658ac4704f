//! `pt`: unidirectional path tracing with next-event estimation, multiple importance
//! sampling against BSDF sampling (power heuristic) and Russian roulette. Path lengths
//! follow Mitsuba: `max_depth` counts segments, so 2 means direct lighting only.

use super::{Integrator, Iteration};
use crate::color::Rgb;
use crate::film::FilmTile;
use crate::geometry::Ray;
use crate::material::{BsdfCtx, BsdfModel, TransportMode};
use crate::math::{vec2, Vec3};
use crate::sampling::{power_heuristic, power_heuristic_over_pdf, Rng};
use crate::scene::Scene;

#[derive(Clone, Debug, Default)]
pub struct PathTracer {
    /// Overrides the scene's `max_depth` when set.
    pub max_depth: Option<i32>,
}

impl PathTracer {
    /// Radiance arriving along `ray`.
    pub fn li(&self, scene: &Scene, mut ray: Ray, rng: &mut Rng) -> Rgb {
        let max_depth = self.max_depth.unwrap_or(scene.settings.max_depth);
        let rr_depth = scene.settings.rr_depth as i32;
        let mut l = Rgb::BLACK;
        let mut beta = Rgb::WHITE;
        // State of the previous scattering event, for MIS on emitter hits.
        let mut prev_delta = true;
        let mut prev_pdf = 0.0f32;
        let mut prev_p = ray.o;
        let mut depth = 0i32;
        loop {
            let Some(si) = scene.intersect(&ray) else {
                for &li in &scene.infinite_lights {
                    let light = &scene.lights[li as usize];
                    let le = light.eval_infinite(ray.d);
                    if le.is_black() {
                        continue;
                    }
                    let w = if prev_delta {
                        1.0
                    } else {
                        power_heuristic(prev_pdf, scene.light_distribution.pmf(li as usize) * light.pdf_infinite(ray.d))
                    };
                    l += beta * le * w;
                }
                break;
            };
            depth += 1;
            let le = scene.emitted(&si);
            if !le.is_black() {
                let w = if prev_delta {
                    1.0
                } else {
                    let li = scene.mesh_light[si.mesh as usize].expect("emissive mesh has a light");
                    let light = &scene.lights[li as usize];
                    let pdf_light = scene.light_distribution.pmf(li as usize) * light.pdf_li_area(prev_p, si.p, si.ng);
                    power_heuristic(prev_pdf, pdf_light)
                };
                l += beta * le * w;
            }
            if max_depth >= 0 && depth >= max_depth {
                break;
            }
            let bsdf = &scene.materials[si.material as usize].bsdf;
            let ctx = BsdfCtx { uv: si.uv, mode: TransportMode::Radiance };
            let wi = si.frame.to_local(si.wi);

            // Next-event estimation.
            if bsdf.has_smooth() && !scene.lights.is_empty() {
                let (li, pmf, _) = scene.light_distribution.sample_discrete(rng.next_f32());
                let u = rng.next_2d();
                if let Some(ls) = scene.lights[li].sample_li(si.p, u) {
                    if !ls.radiance.is_black() && ls.pdf > 0.0 {
                        let wo = si.frame.to_local(ls.wi);
                        let f = bsdf.eval(&ctx, wi, wo);
                        if !f.is_black() {
                            let shadow = if ls.dist.is_finite() { si.spawn_ray_to(ls.p) } else { si.spawn_ray(ls.wi) };
                            if !scene.occluded(&shadow) {
                                let pdf = pmf * ls.pdf;
                                let scale = if ls.delta {
                                    1.0 / pdf
                                } else {
                                    power_heuristic_over_pdf(pdf, bsdf.pdf(&ctx, wi, wo))
                                };
                                l += beta * f * ls.radiance * scale;
                            }
                        }
                    }
                }
            }

            // Continue by sampling the BSDF.
            let u = rng.next_f32();
            let u2 = rng.next_2d();
            let Some(bs) = bsdf.sample(&ctx, wi, u, u2) else {
                break;
            };
            beta *= bs.weight;
            if beta.is_black() || !beta.is_finite() {
                break;
            }
            let d: Vec3 = si.frame.to_world(bs.wo);
            prev_delta = bs.delta;
            prev_pdf = bs.pdf;
            prev_p = si.p;
            ray = si.spawn_ray(d);
            if depth >= rr_depth {
                let q = beta.max_component().min(0.95);
                if rng.next_f32() >= q {
                    break;
                }
                beta = beta / q;
            }
        }
        l
    }
}

impl Integrator for PathTracer {
    fn name(&self) -> &'static str {
        "pt"
    }
    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, tile: &mut FilmTile, _: &Iteration) {
        let pos = vec2(x as f32, y as f32) + rng.next_2d();
        let ray = scene.camera.generate_ray(pos, rng.next_2d());
        let l = self.li(scene, ray, rng);
        tile.add(pos, l);
    }
}
