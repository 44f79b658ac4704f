//! The bidirectional pixel sampler (thesis §4.1.3): a pixel sample's camera sub-path joined
//! to a light sub-path by every (s, t) strategy, weighted by exact MIS ([`super::mis`]).
//! `bpt` joins each pixel's camera sub-path to that pixel's own light sub-path; the
//! resampling estimators (`skelbpt`, `icbpt`) replace the joins of stored vertices s, t ≥ 2
//! with resampled ones and keep the rest.

use super::mis::{running_sums, AllStrategies, Heuristic};
use super::strategies;
use super::subpath::{camera_subpath, LightPaths};
use super::vertex::Vertex;
use crate::color::Rgb;
use crate::film::FilmTile;
use crate::math::vec2;
use crate::sampling::Rng;
use crate::scene::Scene;

/// Which of its strategies an estimator records; the others are still sampled, with the
/// same random numbers, so that images of each add up to the full render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Recorded {
    #[default]
    All,
    /// This (s, t) strategy alone.
    Strategy(usize, usize),
    /// None of them (an estimator that adds strategies of its own records those alone).
    Nothing,
}

/// A tile's buffers for one pixel sample: its camera sub-path and the MIS running sums
/// of both sub-paths.
#[derive(Default)]
pub struct PixelScratch {
    camera: Vec<Vertex>,
    camera_sums: Vec<f32>,
    light_sums: Vec<f32>,
}

/// A pixel sample's two sub-paths with their MIS running sums, as joins read them.
pub struct PixelPaths<'a> {
    /// The pixel's own light sub-path.
    pub light: &'a [Vertex],
    pub light_sums: &'a [f32],
    pub camera: &'a [Vertex],
    pub camera_sums: &'a [f32],
}

/// The bidirectional pixel sampler `bpt` and the resampling estimators share: the camera
/// sub-path of one pixel sample joined by every (s, t) strategy the path length allows.
#[derive(Clone, Debug, Default)]
pub struct PixelSampler {
    /// Overrides the scene's `max_depth` when set.
    pub max_depth: Option<i32>,
    pub heuristic: Heuristic,
    /// Which strategies' weighted contributions it records (one alone for `bpt`'s
    /// per-strategy images).
    pub only: Recorded,
}

impl PixelSampler {
    pub fn max_depth(&self, scene: &Scene) -> i32 {
        self.max_depth.unwrap_or(scene.settings.max_depth)
    }

    pub fn records(&self, s: usize, t: usize) -> bool {
        match self.only {
            Recorded::All => true,
            Recorded::Strategy(a, b) => (a, b) == (s, t),
            Recorded::Nothing => false,
        }
    }

    /// Traces an iteration's light sub-paths, one per pixel (eq. 185), into `into`.
    pub fn trace_light_paths(&self, scene: &Scene, seed: u64, index: u64, into: &mut LightPaths) {
        let pixels = scene.settings.width * scene.settings.height;
        into.trace(scene, pixels, seed, index, self.max_depth(scene));
    }

    /// One camera sample of pixel (`x`, `y`), joined by every strategy the path length
    /// allows, weighted by exact MIS: those that need no stored light vertex past the light
    /// itself here, with the pixel's light sub-path of `light_paths`, and the joins of camera vertex
    /// t ≥ 2 with stored light vertices s ≥ 2 by `joins(paths, t, rng)` (the pixel's own
    /// light sub-path in `bpt`, resampled ones in `skelbpt`).
    #[allow(clippy::too_many_arguments)]
    pub fn sample_pixel(
        &self,
        scene: &Scene,
        (x, y): (usize, usize),
        rng: &mut Rng,
        light_paths: &LightPaths,
        buffers: &mut PixelScratch,
        tile: &mut FilmTile,
        joins: &mut impl FnMut(&PixelPaths, usize, &mut Rng) -> Rgb,
    ) {
        let pixel = y * scene.settings.width + x;
        let (light, hits) = if pixel < light_paths.len() {
            (light_paths.path(pixel), light_paths.lens_hits(pixel))
        } else {
            (&[][..], &[][..])
        };
        let pos = vec2(x as f32, y as f32) + rng.next_2d();
        let PixelScratch { camera, camera_sums, light_sums } = buffers;
        camera_subpath(scene, pos, rng, self.max_depth(scene), camera);
        running_sums(scene, camera, self.heuristic, camera_sums);
        running_sums(scene, light, self.heuristic, light_sums);
        let paths = PixelPaths { light, light_sums, camera, camera_sums };
        let w = AllStrategies { heuristic: self.heuristic, light_sums, camera_sums };
        let mut l = Rgb::BLACK;
        for t in 1..=camera.len() {
            if t >= 2 && self.fits(scene, 0, t) && self.records(0, t) {
                l += strategies::camera_hits_light(scene, camera, t, &w);
            }
            if t >= 2 && self.fits(scene, 1, t) {
                // Drawn even when not recorded, so the random numbers of one strategy do
                // not depend on which others are recorded.
                let c = strategies::connect_to_light(scene, camera, t, rng, &w);
                if self.records(1, t) {
                    l += c;
                }
            }
            if t == 1 {
                for s in 1..=light.len() {
                    if !self.fits(scene, s, 1) {
                        break;
                    }
                    if let Some((raster, c)) = strategies::connect_to_camera(scene, light, s, rng, &w) {
                        if self.records(s, 1) {
                            tile.splat(raster, c);
                        }
                    }
                }
            } else {
                l += joins(&paths, t, rng);
            }
        }
        for hit in hits {
            let s = hit.light_vertices as usize + 1;
            if self.fits(scene, s, 0) && self.records(s, 0) {
                tile.splat(hit.raster, strategies::light_hits_lens(scene, light, hit, &w));
            }
        }
        tile.add(pos, l);
    }

    /// Whether paths made by strategy (s, t) are within the depth limit.
    #[inline]
    pub fn fits(&self, scene: &Scene, s: usize, t: usize) -> bool {
        let max_depth = self.max_depth(scene);
        max_depth < 0 || s + t <= max_depth as usize + 1
    }

    /// `bpt`'s joins of camera vertex t with every vertex s ≥ 2 of the pixel's own light
    /// sub-path.
    pub fn own_path_joins(&self, scene: &Scene, paths: &PixelPaths, t: usize) -> Rgb {
        let (light, camera) = (paths.light, paths.camera);
        let w =
            AllStrategies { heuristic: self.heuristic, light_sums: paths.light_sums, camera_sums: paths.camera_sums };
        let mut l = Rgb::BLACK;
        for s in 2..=light.len() {
            if !self.fits(scene, s, t) {
                break;
            }
            if self.records(s, t) {
                l += strategies::connect_vertices(scene, light, s, camera, t, &w);
            }
        }
        l
    }
}
