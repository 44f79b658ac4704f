//! `ibpt`: instant bidirectional path tracing (seed 002, §3). Each sample traces one camera
//! path and one light path, independently. The camera path makes implicit view paths (it
//! hits an emitter) and explicit ones (next-event estimation); the light path makes explicit
//! light paths (connected to the lens) and implicit ones (it passes through a thin-lens
//! aperture). No connection joins two stored sub-paths, so a walk keeps only its last three
//! vertices; the power-heuristic weights of the four strategies come from one running
//! product per walk (§3.2), folded in as vertices leave the window.
//! The weights' bookkeeping is [`crate::paths::mis_chain`]'s.

use crate::color::Rgb;
use crate::film::FilmTile;
use crate::integrator::{Integrator, SampleContext};
use crate::math::vec2;
use crate::paths::mis_chain::{ChainWeight, MisChain, Side};
use crate::paths::strategies;
use crate::paths::subpath::{camera_subpath_start, max_vertices, random_walk, start_light_subpath, VertexSink};
use crate::paths::vertex::{LensHit, Vertex};
use crate::sampling::Rng;
use crate::scene::Scene;

/// A walk's last three vertices and its MIS state, with what the estimator does at each
/// vertex (connections, emitter and lens hits) recorded as it goes.
struct WindowedWalk<'a> {
    side: Side,
    window: [Vertex; 3],
    len: usize,
    count: usize,
    chain: MisChain,
    max_depth: i32,
    tile: &'a mut FilmTile,
    /// Radiance gathered by a camera walk.
    radiance: Rgb,
}

impl WindowedWalk<'_> {
    fn weighting(&self) -> ChainWeight {
        ChainWeight { side: self.side, chain: self.chain, window_start: self.count - self.len }
    }
    /// Whether a path of `segments` segments is within the depth limit.
    fn fits(&self, segments: usize) -> bool {
        self.max_depth < 0 || segments <= self.max_depth as usize
    }
}

impl VertexSink for WindowedWalk<'_> {
    fn push(&mut self, v: Vertex) {
        if self.len == 3 {
            self.window.rotate_left(1);
            self.len = 2;
        }
        self.window[self.len] = v;
        self.len += 1;
        self.count += 1;
        // a_{j−2}'s other-side density is known once a_{j−1} has been left.
        if self.count >= 3 && self.chain.folded == self.count - 3 {
            let (v2, v1) = (self.window[self.len - 3], self.window[self.len - 2]);
            self.chain.fold(self.count - 3, v2.pdf_rev, v2.pdf_fwd, !v1.delta);
        }
    }
    fn count(&self) -> usize {
        self.count
    }
    fn back(&self, i: usize) -> &Vertex {
        &self.window[self.len - 1 - i]
    }
    fn back_mut(&mut self, i: usize) -> &mut Vertex {
        &mut self.window[self.len - 1 - i]
    }
    fn visit(&mut self, scene: &Scene, rng: &mut Rng) {
        let j = self.count - 1;
        let w = self.weighting();
        let window = &self.window[..self.len];
        match self.side {
            Side::Camera => {
                self.radiance += strategies::camera_hits_light(scene, window, self.len, &w);
                if self.fits(j + 1) {
                    self.radiance += strategies::connect_to_light(scene, window, self.len, rng, &w);
                }
            }
            Side::Light => {
                if self.fits(j + 1) {
                    if let Some((raster, c)) = strategies::connect_to_camera(scene, window, self.len, rng, &w) {
                        self.tile.splat(raster, c);
                    }
                }
            }
        }
    }
    fn wants_lens_hits(&self) -> bool {
        self.side == Side::Light
    }
    fn lens_hit(&mut self, scene: &Scene, hit: LensHit) {
        if !self.fits(self.count) {
            return;
        }
        let w = self.weighting();
        let in_window = LensHit { light_vertices: self.len as u32, ..hit };
        let c = strategies::light_hits_lens(scene, &self.window[..self.len], &in_window, &w);
        self.tile.splat(hit.raster, c);
    }
}

#[derive(Clone, Debug, Default)]
pub struct InstantBpt;

impl InstantBpt {
    fn walk<'a>(&self, scene: &Scene, side: Side, first: Vertex, tile: &'a mut FilmTile) -> WindowedWalk<'a> {
        let origin_hittable = first.hittable(scene);
        let mut walk = WindowedWalk {
            side,
            window: [first; 3],
            len: 0,
            count: 0,
            chain: MisChain::new(origin_hittable),
            max_depth: scene.settings.max_depth,
            tile,
            radiance: Rgb::BLACK,
        };
        walk.push(first);
        walk
    }
}

impl Integrator for InstantBpt {
    fn name(&self) -> &'static str {
        "ibpt"
    }
    fn splats_per_sample(&self) -> u64 {
        1
    }
    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let tile = &mut *cx.tile;
        let max_depth = scene.settings.max_depth;
        // Path-tracing pass: implicit and explicit view paths.
        let pos = vec2(x as f32, y as f32) + rng.next_2d();
        let radiance = if let Some((lens, ray, pdf_dir)) = camera_subpath_start(scene, pos, rng, max_depth) {
            let mut walk = self.walk(scene, Side::Camera, lens, tile);
            random_walk(
                scene,
                ray,
                Rgb::WHITE,
                pdf_dir,
                rng,
                max_vertices(max_depth),
                crate::material::TransportMode::Radiance,
                &mut walk,
            );
            walk.radiance
        } else {
            Rgb::BLACK
        };
        tile.add(pos, radiance);
        // Light-tracing pass: explicit and implicit light paths.
        if let Some(start) = start_light_subpath(scene, rng, max_depth) {
            let first = start.vertex;
            let mut walk = self.walk(scene, Side::Light, first, tile);
            // The light point itself seen by the camera (area lights only, as in `mis`).
            if walk.fits(1) {
                let w = walk.weighting();
                if let Some((raster, c)) = strategies::connect_to_camera(scene, &[first], 1, rng, &w) {
                    walk.tile.splat(raster, c);
                }
            }
            start.walk(scene, rng, max_depth, &mut walk);
        }
    }
}
