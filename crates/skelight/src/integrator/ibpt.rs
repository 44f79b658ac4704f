//! `ibpt`: instant bidirectional path tracing (seed 002, §3). Each sample traces one camera
//! path and one light path, independently. The camera path makes implicit view paths (it
//! hits an emitter) and explicit ones (next-event estimation); the light path makes explicit
//! light paths (connected to the lens) and implicit ones (it passes through a thin-lens
//! aperture). No connection joins two stored sub-paths, so a walk keeps only its last three
//! vertices; the power-heuristic weights of the four strategies come from one running
//! product per walk (§3.2), folded in as vertices leave the window.
//!
//! In the notation of `mis` (x_0 on a light, x_k on the lens), a walk from side A visits
//! a_0, a_1, … with its own densities F_m and the other side's O_m. Relative to A's explicit
//! strategy at a_k (a_k sampled by the other side), the others' density ratios are
//! F_k/O_k (A hits a_k by chance), Π_{m=1}^{k−1} O_m/F_m (the other side's explicit
//! strategy) and that times O_0/F_0 (the other side hits a_0 by chance).

use super::mis::{self, remap_delta, Heuristic, Junction, PathWeight, SubPath};
use super::strategies;
use super::subpath::{camera_subpath_start, max_vertices, random_walk, start_light_subpath, VertexSink};
use super::vertex::{LensHit, Vertex, VertexKind};
use super::{Integrator, SampleContext};
use crate::color::Rgb;
use crate::film::FilmTile;
use crate::math::vec2;
use crate::sampling::Rng;
use crate::scene::Scene;

/// The strategies `ibpt` has: those that start or end on the camera's or a light's
/// sub-path origin, i.e. s ≤ 1 or t ≤ 1.
pub fn ibpt_strategies(s: usize, t: usize) -> bool {
    s <= 1 || t <= 1
}

const HEURISTIC: Heuristic = Heuristic::Power;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Camera,
    Light,
}

/// The running MIS state of one walk: Π_{m=1}^{…} h(O_m/F_m) over the vertices folded so far,
/// and the origin's term [the other side's explicit strategy applies] + [it can hit the
/// origin]·h(O_0/F_0).
#[derive(Clone, Copy, Debug)]
pub struct MisChain {
    /// Vertices folded so far (a_0 … a_{folded−1}).
    pub folded: usize,
    product: f32,
    origin: f32,
    /// Whether the other side's sub-paths can hit this walk's origin (an area light, a lens
    /// with an aperture).
    origin_hittable: bool,
}

impl MisChain {
    pub fn new(origin_hittable: bool) -> MisChain {
        MisChain { folded: 0, product: 1.0, origin: 0.0, origin_hittable }
    }

    /// Folds vertex a_m given its other-side density `other` and own density `own`.
    /// `first_splittable`: whether a_1 can end a connection on this path (used for m = 0).
    pub fn fold(&mut self, m: usize, other: f32, own: f32, first_splittable: bool) {
        debug_assert_eq!(m, self.folded);
        let r = HEURISTIC.apply(remap_delta(other) / remap_delta(own));
        if m == 0 {
            self.origin = first_splittable as u8 as f32 + if self.origin_hittable { r } else { 0.0 };
        } else {
            self.product *= r;
        }
        self.folded = m + 1;
    }

    /// Sum of the other side's two strategies' terms, relative to this walk's explicit one.
    fn tail(&self) -> f32 {
        self.product * self.origin
    }
}

/// Weights paths whose walk-side part is `window` (the walk's last vertices, the first of
/// them at index `window_start`) with the folded state `chain`.
pub struct ChainWeight {
    pub side: Side,
    pub chain: MisChain,
    pub window_start: usize,
}

/// Density with which a sub-path origin (a light point, a lens point) is chosen.
fn origin_density(scene: &Scene, v: &Vertex) -> f32 {
    match v.kind {
        VertexKind::Camera => scene.camera.pdf_we(scene.camera.forward).0,
        _ => v.pdf_light_origin(scene),
    }
}

impl PathWeight for ChainWeight {
    fn weight_joined(&self, scene: &Scene, light: SubPath, camera: SubPath, junction: &Junction) -> f32 {
        if self.window_start + light.len() + camera.len() == 2 {
            // A light seen directly: the special cases of `mis::weight` apply.
            return mis::weight(scene, light, camera, &Junction::NONE, HEURISTIC, &ibpt_strategies);
        }
        let (walk, other) = match self.side {
            Side::Camera => (camera, light),
            Side::Light => (light, camera),
        };
        let at = |m: usize| walk.get(m - self.window_start);
        let end = self.window_start + walk.len() - 1;
        let mut chain = self.chain;
        // Whether a_1 can end a connection on this path (needed only while a_0 is unfolded,
        // and then a_1 is in the window): it ends this one, or was left diffusely.
        let first_splittable = chain.folded > 0 || (end == 1 && other.len() == 1) || !at(1).delta;
        for m in chain.folded..end - 1 {
            chain.fold(m, at(m).pdf_rev, at(m).pdf_fwd, first_splittable);
        }
        if other.len() == 1 {
            // Explicit: a_j joined to the other side's origin b.
            let (b, aj, prev) = (other.get(0), at(end), at(end - 1));
            // a_j's densities towards b and back to its predecessor, if the connection has
            // them already.
            let known = match self.side {
                Side::Camera => junction.camera_end,
                Side::Light => junction.light_end,
            };
            let back = known.map_or_else(|| aj.pdf(scene, Some(b), prev), |d| d.prev);
            chain.fold(end - 1, back, prev.pdf_fwd, first_splittable);
            chain.fold(end, b.pdf(scene, None, aj), aj.pdf_fwd, first_splittable);
            let implicit = if b.hittable(scene) {
                let towards_b = known.map_or_else(|| aj.pdf(scene, Some(prev), b), |d| d.next);
                HEURISTIC.apply(remap_delta(towards_b) / remap_delta(origin_density(scene, b)))
            } else {
                0.0
            };
            1.0 / (1.0 + implicit + chain.tail())
        } else {
            // Implicit: the walk reached the other side's origin a_k.
            let (ak, prev) = (at(end), at(end - 1));
            chain.fold(end - 1, ak.pdf(scene, None, prev), prev.pdf_fwd, first_splittable);
            let r = HEURISTIC.apply(remap_delta(origin_density(scene, ak)) / remap_delta(ak.pdf_fwd));
            let explicit = if prev.delta { 0.0 } else { r };
            1.0 / (1.0 + explicit + r * chain.tail())
        }
    }
}

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
