//! `lt`: light tracing. Paths start on the lights (chosen by power) and every vertex is
//! connected to the camera (the t = 1 strategy), splatting onto the film; with a thin lens,
//! paths that pass through the aperture count too (t = 0), the two combined by MIS. It sees
//! what reaches the camera through non-specular surfaces only: emitters and surfaces seen in
//! a mirror or through glass by a pinhole need `pt` or `bpt`. The environment seen directly
//! (a path of one segment from a light at infinity, which no light path can connect to the
//! lens) is added from one primary ray per sample when the scene has such lights, as
//! Mitsuba's particle tracer does: its only strategy, so its weight is one.

use crate::color::Rgb;
use crate::film::FilmTile;
use crate::integrator::{Integrator, SampleContext, Scratch};
use crate::math::vec2;
use crate::paths::mis::Heuristic;
use crate::paths::strategies::{self, camera_end_strategies, Weighting};
use crate::paths::subpath::light_subpath;
use crate::paths::vertex::{LensHit, Vertex};
use crate::sampling::Rng;
use crate::scene::Scene;

#[derive(Clone, Debug, Default)]
pub struct LightTracer {
    /// Overrides the scene's `max_depth` when set.
    pub max_depth: Option<i32>,
}

/// A tile's buffers for one light sub-path and the lens hits along it.
type LightPathScratch = (Vec<Vertex>, Vec<LensHit>);

impl Integrator for LightTracer {
    fn limitation(&self, scene: &Scene) -> Option<String> {
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
    fn new_scratch(&self) -> Scratch {
        Scratch::new(LightPathScratch::default())
    }
    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let tile = &mut *cx.tile;
        let scratch = &mut *cx.scratch;
        let max_depth = self.max_depth.unwrap_or(scene.settings.max_depth);
        if !scene.infinite_lights.is_empty() {
            add_environment_seen_directly(scene, x, y, rng, max_depth, tile);
        }
        let w = Weighting { heuristic: Heuristic::Balance, strategies: &camera_end_strategies };
        let (path, hits) = scratch.get::<LightPathScratch>();
        {
            light_subpath(scene, rng, max_depth, path, hits);
            let fits = |s: usize| max_depth < 0 || s <= max_depth as usize;
            for s in 1..=path.len() {
                if !fits(s) {
                    break;
                }
                if let Some((raster, c)) = strategies::connect_to_camera(scene, path, s, rng, &w) {
                    tile.splat(raster, c);
                }
            }
            for hit in hits.iter() {
                if fits(hit.light_vertices as usize) {
                    tile.splat(hit.raster, strategies::light_hits_lens(scene, path, hit, &w));
                }
            }
        }
    }
}

/// The environment seen directly through pixel (`x`, `y`): one primary ray; its radiance if
/// it leaves the scene, zero otherwise (every sample counts towards the pixel's average).
fn add_environment_seen_directly(
    scene: &Scene,
    x: usize,
    y: usize,
    rng: &mut Rng,
    max_depth: i32,
    tile: &mut FilmTile,
) {
    let pos = vec2(x as f32 + rng.next_f32(), y as f32 + rng.next_f32());
    let ray = scene.camera.generate_ray(pos, rng.next_2d());
    let escaped = max_depth != 0 && scene.intersect(&ray).is_none();
    tile.add(pos, if escaped { scene.environment(ray.d) } else { Rgb::BLACK });
}
