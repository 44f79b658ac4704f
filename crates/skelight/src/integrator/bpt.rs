//! `bpt`: bidirectional path tracing (thesis §4.1.3). Each iteration first traces one light
//! sub-path per pixel into a shared buffer (eq. 185); each camera sub-path is then joined to
//! its pixel's light sub-path by every (s, t) strategy, weighted by exact MIS (balance
//! heuristic by default, power on request).

use super::mis::{running_sums, AllStrategies, Heuristic, PathWeight};
use super::strategies;
use super::subpath::camera_subpath;
use super::vertex::Vertex;
use super::{Integrator, Iteration, SampleContext, Scratch};
use crate::color::Rgb;
use crate::film::FilmTile;
use crate::math::vec2;
use crate::sampling::Rng;
use crate::scene::Scene;

#[derive(Clone, Debug, Default)]
pub struct Bpt {
    /// Overrides the scene's `max_depth` when set.
    pub max_depth: Option<i32>,
    pub heuristic: Heuristic,
    /// Records only this (s, t) strategy's weighted contribution (for `--debug-strategies`).
    pub only: Option<(usize, usize)>,
}

/// A tile's buffers for one pixel sample: its camera sub-path and the MIS running sums
/// of both sub-paths.
#[derive(Default)]
struct PixelScratch {
    camera: Vec<Vertex>,
    camera_sums: Vec<f32>,
    light_sums: Vec<f32>,
}

impl Bpt {
    fn max_depth(&self, scene: &Scene) -> i32 {
        self.max_depth.unwrap_or(scene.settings.max_depth)
    }

    fn records(&self, s: usize, t: usize) -> bool {
        self.only.is_none_or(|o| o == (s, t))
    }

    /// Every strategy the path length allows, for the pixel's camera sub-path, weighted by
    /// `w`.
    #[allow(clippy::too_many_arguments)]
    pub fn sample_strategies(
        &self,
        scene: &Scene,
        light: &[Vertex],
        lens_hits: &[super::vertex::LensHit],
        camera: &[Vertex],
        rng: &mut Rng,
        tile: &mut FilmTile,
        w: &impl PathWeight,
    ) -> Rgb {
        let max_depth = self.max_depth(scene);
        let fits = |s: usize, t: usize| max_depth < 0 || s + t <= max_depth as usize + 1;
        let mut l = Rgb::BLACK;
        for t in 1..=camera.len() {
            if t >= 2 && fits(0, t) && self.records(0, t) {
                l += strategies::camera_hits_light(scene, camera, t, w);
            }
            if t >= 2 && fits(1, t) {
                // Drawn even when not recorded, so the random numbers of one strategy do
                // not depend on which others are recorded.
                let c = strategies::connect_to_light(scene, camera, t, rng, w);
                if self.records(1, t) {
                    l += c;
                }
            }
            if t == 1 {
                for s in 1..=light.len() {
                    if !fits(s, 1) {
                        break;
                    }
                    if let Some((raster, c)) = strategies::connect_to_camera(scene, light, s, rng, w) {
                        if self.records(s, 1) {
                            tile.splat(raster, c);
                        }
                    }
                }
            } else {
                for s in 2..=light.len() {
                    if !fits(s, t) {
                        break;
                    }
                    if self.records(s, t) {
                        l += strategies::connect_vertices(scene, light, s, camera, t, w);
                    }
                }
            }
        }
        for hit in lens_hits {
            let s = hit.light_vertices as usize + 1;
            if fits(s, 0) && self.records(s, 0) {
                tile.splat(hit.raster, strategies::light_hits_lens(scene, light, hit, w));
            }
        }
        l
    }
}

impl Integrator for Bpt {
    fn name(&self) -> &'static str {
        "bpt"
    }
    fn splats_per_sample(&self) -> u64 {
        1
    }
    fn prepares_iterations(&self) -> bool {
        true
    }
    fn prepare_iteration(&self, scene: &Scene, seed: u64, index: u64, into: &mut Iteration) {
        let pixels = scene.settings.width * scene.settings.height;
        into.light_paths.trace(scene, pixels, seed, index, self.max_depth(scene));
    }
    fn new_scratch(&self) -> Scratch {
        Scratch::new(PixelScratch::default())
    }
    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let (it, scratch, tile) = (cx.iteration, &mut *cx.scratch, &mut *cx.tile);
        let pixel = y * scene.settings.width + x;
        let (light, hits) = if pixel < it.light_paths.len() {
            (it.light_paths.path(pixel), it.light_paths.lens_hits(pixel))
        } else {
            (&[][..], &[][..])
        };
        let pos = vec2(x as f32, y as f32) + rng.next_2d();
        let PixelScratch { camera, camera_sums, light_sums } = scratch.get::<PixelScratch>();
        camera_subpath(scene, pos, rng, self.max_depth(scene), camera);
        running_sums(scene, camera, self.heuristic, camera_sums);
        running_sums(scene, light, self.heuristic, light_sums);
        let w = AllStrategies { heuristic: self.heuristic, light_sums, camera_sums };
        let l = self.sample_strategies(scene, light, hits, camera, rng, tile, &w);
        tile.add(pos, l);
    }
}
