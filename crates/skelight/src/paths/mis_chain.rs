//! The one-float MIS of instant bidirectional path tracing (seed 002, §3.2): a walk's
//! power-heuristic weights over the four strategies that start or end on a sub-path origin,
//! from one running product folded in as vertices leave the walk's window (so a walk keeps
//! only its last three vertices). `ibpt` uses it; `tests/mis.rs` checks it against
//! [`super::mis::weight`] on whole paths.
//!
//! In the notation of `mis` (x_0 on a light, x_k on the lens), a walk from side A visits
//! a_0, a_1, … with its own densities F_m and the other side's O_m. Relative to A's explicit
//! strategy at a_k (a_k sampled by the other side), the others' density ratios are
//! F_k/O_k (A hits a_k by chance), Π_{m=1}^{k−1} O_m/F_m (the other side's explicit
//! strategy) and that times O_0/F_0 (the other side hits a_0 by chance).

use super::mis::{self, remap_delta, Heuristic, Junction, PathWeight, SubPath};
use super::vertex::{Vertex, VertexKind};
use crate::scene::Scene;

/// The strategies `ibpt` has: those that start or end on the camera's or a light's
/// sub-path origin, i.e. s ≤ 1 or t ≤ 1.
pub fn ibpt_strategies(s: usize, t: usize) -> bool {
    s <= 1 || t <= 1
}

pub const HEURISTIC: Heuristic = Heuristic::Power;

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
    pub fn tail(&self) -> f32 {
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
