//! skelbpt's light-vertex resampling distributions, cached at skeleton nodes (thesis
//! §11.2–11.4, seed 000 §4). Each iteration, N of its light sub-paths are drawn at random
//! as candidates. For every node accepted this iteration (§11.4) and every light depth s,
//! the distributions V (eq. 188), U (eq. 189) and C (eq. 190) over the candidates' vertex
//! y_s are combined into one table; an eye vertex mapped to the node draws one candidate
//! per depth from it, and the estimator divides the connection's contribution by N times
//! the candidate's probability (eq. 186, 191).
//!
//! **Combining the three (§11.3).** Under the max heuristic a candidate keeps only the
//! distribution that gives it the highest probability; each distribution so cut is
//! renormalised (its kept mass Z_X), and X is drawn uniformly among the K distributions
//! left non-empty. A candidate's probability is then p_X*(j) / (K·Z_X*): the estimator
//! divides by it, so no weight is evaluated per eye vertex. Every candidate keeps at least
//! C's share (its largest probability is at least 1/N_s), so every light vertex that can
//! contribute can be drawn, and the estimator is unbiased whatever the node's visibility.
//! The balance combination, (p_V + p_U + p_C)/K, is offered for comparison.
//!
//! Eye vertices mapped to no node, or to a node not accepted this iteration, draw
//! uniformly among the candidates with a vertex at depth s (the thesis's fallback).

use std::ops::Deref;

use rayon::prelude::*;

use super::candidates::{Candidates, Table};
pub use super::candidates::{Combination, Draw};
use std::sync::Arc;

use crate::guided::analysis::prepare_guide;
use crate::guided::{GuideSettings, SkeletonGuide};
use crate::integrator::{Preparation, PrepareError};
use crate::math::{vec2, Vec3};
use crate::paths::mis::Heuristic;
use crate::paths::subpath::{camera_subpath, LightPaths};
use crate::paths::vertex::{Vertex, VertexKind};
use crate::paths::visibility::{light_visible, ShadowEnd};
use crate::sampling::Rng;
use crate::scene::Scene;

/// Which distribution a resampled candidate is credited to (thesis Fig. 106).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Origin {
    /// Eq. 188: w_n restricted to light vertices the node sees.
    Visible = 0,
    /// Eq. 189: w_n(y) = L(y)/‖P_n − y‖² (eq. 187).
    Weighted = 1,
    /// Eq. 190: uniform over the candidates.
    Uniform = 2,
    /// The fallback where the eye vertex's node has no table this iteration.
    Fallback = 3,
}

impl Origin {
    pub const ALL: [Origin; 4] = [Origin::Visible, Origin::Weighted, Origin::Uniform, Origin::Fallback];
    /// Short name, as parameters and file names use it.
    pub fn name(self) -> &'static str {
        match self {
            Origin::Visible => "V",
            Origin::Weighted => "U",
            Origin::Uniform => "C",
            Origin::Fallback => "fallback",
        }
    }
}

/// What a build cost and covered (accumulated over iterations for the report).
#[derive(Clone, Copy, Debug, Default)]
pub struct BuildStats {
    pub iterations: u64,
    pub accepted_nodes: u64,
    pub tables: u64,
    pub shadow_rays: u64,
    /// Of those, the light vertices the node saw.
    pub visible: u64,
    pub seconds: f64,
}

impl BuildStats {
    pub fn add(&mut self, o: &BuildStats) {
        self.iterations += o.iterations;
        self.accepted_nodes += o.accepted_nodes;
        self.tables += o.tables;
        self.shadow_rays += o.shadow_rays;
        self.visible += o.visible;
        self.seconds += o.seconds;
    }
}

/// One iteration's candidates and node tables.
#[derive(Default)]
pub struct Resampling {
    candidates: Candidates,
    /// Node → its slot in `tables` (`u32::MAX`: not accepted this iteration).
    slot_of: Vec<u32>,
    /// Slot-major, one per light depth.
    tables: Vec<Table>,
    pub stats: BuildStats,
}

/// The tables draw among the candidates: a `Resampling` reads as its candidate pool.
impl Deref for Resampling {
    type Target = Candidates;
    fn deref(&self) -> &Candidates {
        &self.candidates
    }
}

/// What a build reads besides the iteration's light sub-paths.
pub struct BuildInput<'a> {
    pub guide: &'a SkeletonGuide,
    /// Nodes to build tables for this iteration.
    pub accepted: &'a [u32],
    /// N: candidates drawn among the iteration's light sub-paths.
    pub candidates: usize,
    pub combination: Combination,
    pub heuristic: Heuristic,
    /// The deepest light vertex a join may use (s ≤ this; max depth − 1 for joins with
    /// t ≥ 2): no table is built beyond it.
    pub deepest: usize,
    pub seed: u64,
    pub iteration: u64,
}

impl Resampling {
    /// Draws this iteration's candidates and builds the accepted nodes' tables (in
    /// parallel), replacing what was held.
    pub fn build(&mut self, scene: &Scene, light_paths: &LightPaths, input: &BuildInput) {
        let clock = std::time::Instant::now();
        let (n, heuristic, deepest) = (input.candidates, input.heuristic, input.deepest);
        self.candidates.draw(scene, light_paths, n, heuristic, deepest, (input.seed, input.iteration));
        self.slot_of.clear();
        self.slot_of.resize(input.guide.graph.nodes.len(), u32::MAX);
        for (slot, &n) in input.accepted.iter().enumerate() {
            self.slot_of[n as usize] = slot as u32;
        }
        let pool = &self.candidates;
        let depths = pool.depths();
        let built: Vec<(Table, u64, u64)> = (0..input.accepted.len() * depths)
            .into_par_iter()
            .map(|k| {
                let (node, s) = (input.accepted[k / depths], k % depths + 2);
                let at = input.guide.position(node);
                let vertex = |c: u32| &pool.path(c as usize)[s - 1];
                build_table(scene, at, pool.eligible(s), vertex, input.combination)
            })
            .collect();
        (self.tables, self.stats) = super::join::table_stats(built, input.accepted.len(), clock);
    }

    /// Draws a candidate for an eye vertex mapped to `node` at light depth `s` ≥ 2 with the
    /// uniform 32-bit integer `r`; `None` where no candidate has a vertex there.
    #[inline]
    pub fn draw(&self, node: Option<u32>, s: usize, r: u32) -> Option<Draw> {
        let d = s.checked_sub(2)?;
        let eligible = self.eligible(s);
        let slot = node.map_or(u32::MAX, |n| self.slot_of[n as usize]);
        if slot != u32::MAX && !eligible.is_empty() {
            let table = &self.tables[slot as usize * self.depths() + d];
            if !table.is_empty() {
                let (i, probability) = table.draw(r);
                return Some(Draw {
                    candidate: eligible[i] as usize,
                    probability: probability as f32,
                    origin: table.origin(i),
                });
            }
        }
        self.candidates.draw_uniform(s, r)
    }

    /// Bytes held by the candidates (their copied vertices and sums) and the tables.
    pub fn bytes(&self) -> usize {
        self.tables.iter().map(Table::bytes).sum::<usize>() + self.candidates.bytes() + self.slot_of.len() * 4
    }
}

/// The table of node position `at` over the light vertices of `eligible` (eq. 187–190,
/// combined as [`super::candidates::combine`] says), with the shadow rays it traced and how
/// many found the node.
fn build_table<'a>(
    scene: &Scene,
    at: Vec3,
    eligible: &[u32],
    vertex: impl Fn(u32) -> &'a Vertex,
    combination: Combination,
) -> (Table, u64, u64) {
    let m = eligible.len();
    if m == 0 {
        return (Table::default(), 0, 0);
    }
    // Eq. 187: w_n(y) = L(y)/‖P_n − y‖², L the light sub-path's throughput at y.
    let mut weights = Vec::with_capacity(m);
    let mut seen = Vec::with_capacity(m);
    for &c in eligible {
        let y = vertex(c);
        let d2 = (at - y.p()).length_squared().max(1e-12) as f64;
        weights.push((y.beta.luminance().max(0.0) as f64) / d2);
        seen.push(light_visible(scene, &y.si, ShadowEnd::Point(at)));
    }
    let visible = seen.iter().filter(|v| **v).count() as u64;
    let (probabilities, origins) = super::candidates::combine(&weights, &seen, combination);
    (Table::new(&probabilities, origins), m as u64, visible)
}

/// Seed of the pilot eye sub-paths (fixed: the preparation is part of the estimator).
const PILOT_SEED: u64 = 0x70_696c_6f74;

/// §11.4: the nodes at least `acceptance` times the mean count mapped to (and at least
/// one).
pub fn accept(mapped: &[u64], acceptance: f64) -> Vec<u32> {
    let mean = mapped.iter().sum::<u64>() as f64 / mapped.len().max(1) as f64;
    (0..mapped.len() as u32)
        .filter(|&n| {
            let m = mapped[n as usize];
            m > 0 && m as f64 >= acceptance * mean
        })
        .collect()
}

/// Eye vertices (t ≥ 2) of pilot camera sub-paths mapped to each node, and how many
/// sub-paths were traced: one per 16 pixels, at least 1024 and at most 16 384.
fn pilot_counts(scene: &Scene, guide: &SkeletonGuide, max_depth: i32) -> (Vec<u64>, usize) {
    use rayon::prelude::*;
    let (w, h) = (scene.settings.width, scene.settings.height);
    let count = (w * h / 16).clamp(1024, 16_384);
    let nodes = guide.graph.nodes.len();
    let chunks = count.div_ceil(256);
    let mapped = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut counts = vec![0u64; nodes];
            let mut path = Vec::new();
            for i in c * 256..((c + 1) * 256).min(count) {
                let mut rng = Rng::new(PILOT_SEED, i as u64, 0);
                let raster = vec2(rng.next_f32() * w as f32, rng.next_f32() * h as f32);
                camera_subpath(scene, raster, &mut rng, max_depth, &mut path);
                for z in path.iter().skip(1).filter(|z| z.kind == VertexKind::Surface && z.can_connect(scene)) {
                    if let Some(n) = guide.node_at(z.p(), z.n(), z.si.wi) {
                        counts[n as usize] += 1;
                    }
                }
            }
            counts
        })
        .reduce(
            || vec![0u64; nodes],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    (mapped, count)
}

/// The skeleton `skelbpt` resamples with and the nodes that get tables (§11.4), as its
/// preparation makes them: the analysis, pilot eye sub-paths' counts per node, and the
/// nodes accepted for the first pass.
pub struct NodeSelection {
    pub guide: Arc<SkeletonGuide>,
    /// Eye vertices mapped to each node so far (pilot, then finished passes).
    pub mapped: Vec<u64>,
    /// The nodes that get tables in the current pass.
    pub accepted: Vec<u32>,
}

impl NodeSelection {
    /// Analyses `scene` and runs the pilot, with stages and notes added to `prep`.
    pub fn prepare(
        scene: &Scene,
        settings: &GuideSettings,
        acceptance: f64,
        max_depth: i32,
        prep: &mut Preparation,
    ) -> Result<NodeSelection, PrepareError> {
        let guide = prepare_guide(scene, settings, prep)?;
        let lap = std::time::Instant::now();
        let (mapped, pilots) = pilot_counts(scene, &guide, max_depth);
        prep.stages.push(("pilot eye sub-paths (node acceptance, section 11.4)".into(), lap.elapsed().as_secs_f64()));
        let accepted = accept(&mapped, acceptance);
        prep.notes.push(format!(
            "skeleton: {} nodes; {pilots} pilot eye sub-paths reached {}; {} accepted for the first pass (alpha = {acceptance})",
            guide.graph.nodes.len(),
            mapped.iter().filter(|m| **m > 0).count(),
            accepted.len(),
        ));
        Ok(NodeSelection { guide, mapped, accepted })
    }
}
