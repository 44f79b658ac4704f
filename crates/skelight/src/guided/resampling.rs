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

use rayon::prelude::*;

use super::SkeletonGuide;
use crate::integrator::mis::{running_sums, Heuristic};
use crate::integrator::subpath::LightPaths;
use crate::integrator::vertex::{Vertex, VertexKind};
use crate::math::Vec3;
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

/// How a table combines V, U and C.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Combination {
    /// The max heuristic folded into the distributions (§11.3, the thesis's choice).
    Max,
    /// The balance heuristic: the mixture (p_V + p_U + p_C)/K.
    Balance,
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

/// One resampled candidate.
#[derive(Clone, Copy, Debug)]
pub struct Draw {
    /// Index of the candidate (into [`Resampling::paths`]).
    pub candidate: usize,
    /// The probability it was drawn with.
    pub probability: f32,
    pub origin: Origin,
}

/// A node's table for one light depth, over the depth's eligible candidates in their
/// order. Drawn by a 32-bit random integer r: candidate i for `ends[i − 1] ≤ r < ends[i]`,
/// so its probability is exactly (ends[i] − ends[i − 1]) / 2³² — what the estimator divides
/// by is what the draw did, with no rounding of a float CDF in between.
#[derive(Default)]
struct Table {
    /// Exclusive upper thresholds, strictly increasing, the last 2³².
    ends: Vec<u64>,
    origins: Vec<Origin>,
}

impl Table {
    fn new(probabilities: &[f64], origins: Vec<Origin>) -> Table {
        let total: f64 = probabilities.iter().sum();
        let mut ends = Vec::with_capacity(probabilities.len());
        let (mut acc, mut prev) = (0.0f64, 0u64);
        for (i, p) in probabilities.iter().enumerate() {
            acc += p / total;
            let remaining = (probabilities.len() - 1 - i) as u64;
            // Every candidate keeps at least one threshold step (its probability is at
            // least 1/(3m), far above 2⁻³²), and room is left for those after it.
            let end = ((acc * TWO_32) as u64).clamp(prev + 1, (1u64 << 32) - remaining);
            ends.push(end);
            prev = end;
        }
        if let Some(last) = ends.last_mut() {
            *last = 1 << 32;
        }
        Table { ends, origins }
    }
}

const TWO_32: f64 = 4_294_967_296.0;

/// One iteration's candidates and tables.
#[derive(Default)]
pub struct Resampling {
    /// The light sub-path (index into the iteration's [`LightPaths`]) of each candidate.
    pub paths: Vec<u32>,
    /// The candidates' vertices, copied together (joins read them at random: kept close,
    /// they stay in cache), candidate c's at `vertices[starts[c]..starts[c + 1]]`, as are
    /// its MIS running sums ([`running_sums`]) in `sums`.
    vertices: Vec<Vertex>,
    starts: Vec<u32>,
    sums: Vec<f32>,
    /// Per light depth s ≥ 2 (at s − 2), the candidates whose vertex y_s can end a
    /// connection.
    eligible: Vec<Vec<u32>>,
    /// Node → its slot in `tables` (`u32::MAX`: not accepted this iteration).
    slot_of: Vec<u32>,
    /// Slot-major, one per light depth.
    tables: Vec<Table>,
    pub stats: BuildStats,
}

/// Separates the candidates' random numbers from every other stream.
const CANDIDATE_STREAM: u64 = 0x7265_7361_6d70_6c65;

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
        let mut rng = Rng::new(input.seed ^ CANDIDATE_STREAM, 0, input.iteration);
        self.paths = random_subset(light_paths.len(), input.candidates, &mut rng);
        self.vertices.clear();
        self.sums.clear();
        self.starts.clear();
        self.starts.push(0);
        let mut buffer = Vec::new();
        let mut depths = 0;
        for &p in &self.paths {
            let path = light_paths.path(p as usize);
            running_sums(scene, path, input.heuristic, &mut buffer);
            self.vertices.extend_from_slice(path);
            self.sums.extend_from_slice(&buffer);
            self.starts.push(self.vertices.len() as u32);
            depths = depths.max(path.len().min(input.deepest).saturating_sub(1));
        }
        let mut eligible = std::mem::take(&mut self.eligible);
        eligible.iter_mut().for_each(Vec::clear);
        eligible.resize_with(depths, Vec::new);
        for c in 0..self.paths.len() {
            for (i, y) in self.path(c).iter().enumerate().take(depths + 1).skip(1) {
                if ends_connection(scene, y) {
                    eligible[i - 1].push(c as u32);
                }
            }
        }
        self.eligible = eligible;
        self.slot_of.clear();
        self.slot_of.resize(input.guide.graph.nodes.len(), u32::MAX);
        for (slot, &n) in input.accepted.iter().enumerate() {
            self.slot_of[n as usize] = slot as u32;
        }
        let this = &*self;
        let built: Vec<(Table, u64, u64)> = (0..input.accepted.len() * depths)
            .into_par_iter()
            .map(|k| {
                let (node, d) = (input.accepted[k / depths], k % depths);
                let at = input.guide.position(node);
                let vertex = |c: u32| &this.path(c as usize)[d + 1];
                build_table(scene, at, &this.eligible[d], vertex, input.combination)
            })
            .collect();
        self.stats = BuildStats { iterations: 1, accepted_nodes: input.accepted.len() as u64, ..BuildStats::default() };
        self.tables.clear();
        for (table, rays, visible) in built {
            self.stats.tables += !table.ends.is_empty() as u64;
            self.stats.shadow_rays += rays;
            self.stats.visible += visible;
            self.tables.push(table);
        }
        self.stats.seconds = clock.elapsed().as_secs_f64();
    }

    /// N, the number of candidates (the estimator's normalisation, eq. 186).
    pub fn candidates(&self) -> usize {
        self.paths.len()
    }

    /// Light depths with eligible candidates: s from 2 to this + 1.
    pub fn depths(&self) -> usize {
        self.eligible.len()
    }

    /// Draws a candidate for an eye vertex mapped to `node` at light depth `s` ≥ 2 with the
    /// uniform 32-bit integer `r`; `None` where no candidate has a vertex there.
    #[inline]
    pub fn draw(&self, node: Option<u32>, s: usize, r: u32) -> Option<Draw> {
        let d = s.checked_sub(2)?;
        let eligible = self.eligible.get(d)?;
        if eligible.is_empty() {
            return None;
        }
        let slot = node.map_or(u32::MAX, |n| self.slot_of[n as usize]);
        if slot != u32::MAX {
            let table = &self.tables[slot as usize * self.eligible.len() + d];
            if !table.ends.is_empty() {
                let i = table.ends.partition_point(|&e| e <= r as u64);
                let start = if i == 0 { 0 } else { table.ends[i - 1] };
                let probability = ((table.ends[i] - start) as f64 / TWO_32) as f32;
                return Some(Draw { candidate: eligible[i] as usize, probability, origin: table.origins[i] });
            }
        }
        // Uniform: r·m / 2³² puts ⌊2³²/m⌋ or ⌈2³²/m⌉ values of r on each candidate, within
        // m/2³² (relatively) of 1/m.
        let m = eligible.len() as u64;
        let i = ((r as u64 * m) >> 32) as usize;
        Some(Draw { candidate: eligible[i] as usize, probability: 1.0 / m as f32, origin: Origin::Fallback })
    }

    /// The candidates whose vertex y_s can end a connection (those a draw at depth s can
    /// return).
    pub fn eligible(&self, s: usize) -> &[u32] {
        s.checked_sub(2).and_then(|d| self.eligible.get(d)).map_or(&[], |e| &e[..])
    }

    /// Candidate `c`'s light sub-path.
    #[inline]
    pub fn path(&self, c: usize) -> &[Vertex] {
        &self.vertices[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// Candidate `c`'s MIS running sums.
    #[inline]
    pub fn sums(&self, c: usize) -> &[f32] {
        &self.sums[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// Bytes held by the candidates (their copied vertices and sums) and the tables.
    pub fn bytes(&self) -> usize {
        let tables: usize = self.tables.iter().map(|t| t.origins.len() * (1 + 8) + std::mem::size_of::<Table>()).sum();
        let candidates =
            self.vertices.len() * std::mem::size_of::<Vertex>() + self.sums.len() * 4 + self.starts.len() * 4;
        tables + candidates + self.paths.len() * 4 + self.eligible.iter().map(|e| e.len() * 4).sum::<usize>()
    }
}

/// Whether a light vertex can be the light end of a join with a camera vertex (as
/// `strategies::connect_vertices` requires: a surface with a non-specular part, carrying
/// light).
fn ends_connection(scene: &Scene, y: &Vertex) -> bool {
    y.kind == VertexKind::Surface && y.can_connect(scene) && !y.beta.is_black()
}

/// `k` distinct indices below `n`, uniformly among all such subsets (Floyd's algorithm),
/// in increasing order; all of them when `k ≥ n`.
pub fn random_subset(n: usize, k: usize, rng: &mut Rng) -> Vec<u32> {
    if k >= n {
        return (0..n as u32).collect();
    }
    let mut chosen = std::collections::HashSet::with_capacity(k);
    for j in n - k..n {
        let t = ((rng.next_u32() as u64 * (j as u64 + 1)) >> 32) as u32;
        if !chosen.insert(t) {
            chosen.insert(j as u32);
        }
    }
    let mut v: Vec<u32> = chosen.into_iter().collect();
    v.sort_unstable();
    v
}

/// The table of node position `at` over the light vertices of `eligible` (eq. 187–190,
/// combined as the module says), with the shadow rays it traced and how many found the
/// node.
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
        seen.push(!scene.occluded(&y.si.spawn_ray_to(at)));
    }
    let visible = seen.iter().filter(|v| **v).count() as u64;
    let (probabilities, origins) = combine(&weights, &seen, combination);
    let table = Table::new(&probabilities, origins);
    (table, m as u64, visible)
}

/// Each candidate's probability and the distribution it is credited to, from its weight
/// w_n (eq. 187) and whether the node sees it: V, U and C (eq. 188–190) combined as the
/// module says.
pub fn combine(weights: &[f64], seen: &[bool], combination: Combination) -> (Vec<f64>, Vec<Origin>) {
    let m = weights.len();
    let sum_u: f64 = weights.iter().sum();
    let sum_v: f64 = weights.iter().zip(seen).filter(|(_, s)| **s).map(|(w, _)| w).sum();
    let p = |x: Origin, j: usize| -> f64 {
        match x {
            Origin::Visible if sum_v > 0.0 && seen[j] => weights[j] / sum_v,
            Origin::Weighted if sum_u > 0.0 => weights[j] / sum_u,
            Origin::Uniform => 1.0 / m as f64,
            _ => 0.0,
        }
    };
    // The distribution that gives j the highest probability (V, then U, then C on ties).
    let best = |j: usize| {
        let mut best = Origin::Uniform;
        for x in [Origin::Weighted, Origin::Visible] {
            if p(x, j) >= p(best, j) {
                best = x;
            }
        }
        best
    };
    let origins: Vec<Origin> = (0..m).map(best).collect();
    let probabilities = match combination {
        Combination::Max => {
            let mut kept = [0.0f64; 3];
            for (j, &x) in origins.iter().enumerate() {
                kept[x as usize] += p(x, j);
            }
            let k = kept.iter().filter(|z| **z > 0.0).count() as f64;
            (0..m).map(|j| p(origins[j], j) / (k * kept[origins[j] as usize])).collect()
        }
        Combination::Balance => {
            let k = 1.0 + (sum_u > 0.0) as u8 as f64 + (sum_v > 0.0) as u8 as f64;
            (0..m).map(|j| (p(Origin::Visible, j) + p(Origin::Weighted, j) + p(Origin::Uniform, j)) / k).collect()
        }
    };
    (probabilities, origins)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_subsets_are_distinct_sorted_and_uniform() {
        let mut rng = Rng::new(1, 2, 3);
        let mut hits = [0u32; 10];
        for _ in 0..20_000 {
            let s = random_subset(10, 3, &mut rng);
            assert_eq!(s.len(), 3);
            assert!(s.windows(2).all(|w| w[0] < w[1]));
            for i in s {
                hits[i as usize] += 1;
            }
        }
        // Each index is in a subset with probability 3/10: 6000 ± 65 (binomial sd).
        for h in hits {
            assert!((h as f64 - 6000.0).abs() < 5.0 * 65.0, "{hits:?}");
        }
        assert_eq!(random_subset(4, 9, &mut rng), vec![0, 1, 2, 3]);
    }

    /// The folded table is the thesis's two-stage draw (X uniform among the non-empty
    /// distributions, then a candidate from X cut by the max heuristic and renormalised),
    /// done exactly; every candidate keeps at least a third of C's share.
    #[test]
    fn the_folded_max_table_is_the_two_stage_draw() {
        let weights = [4.0, 1.0, 0.25, 0.0, 2.0, 0.01];
        let seen = [true, false, true, false, false, true];
        let (p, origins) = combine(&weights, &seen, Combination::Max);
        let m = weights.len() as f64;
        let (su, sv) = (7.26, 4.26);
        let pv = |j: usize| if seen[j] { weights[j] / sv } else { 0.0 };
        let pu = |j: usize| weights[j] / su;
        let mut two_stage = [0.0f64; 6];
        let dists: [&dyn Fn(usize) -> f64; 3] = [&pv, &pu, &|_| 1.0 / m];
        // Which distribution is largest for each candidate, from the definitions.
        let argmax = |j: usize| (0..3).rev().max_by(|&a, &b| dists[a](j).total_cmp(&dists[b](j))).unwrap();
        let kept: Vec<f64> = (0..3).map(|x| (0..6).filter(|&j| argmax(j) == x).map(|j| dists[x](j)).sum()).collect();
        let k = kept.iter().filter(|z| **z > 0.0).count() as f64;
        for j in 0..6 {
            let x = argmax(j);
            two_stage[j] = dists[x](j) / kept[x] / k;
            assert_eq!(origins[j] as usize, x, "candidate {j}");
        }
        for j in 0..6 {
            assert!((p[j] - two_stage[j]).abs() < 1e-12, "{p:?} vs {two_stage:?}");
            assert!(p[j] >= 1.0 / (3.0 * m) - 1e-12, "candidate {j} starved: {}", p[j]);
        }
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        // The balance mixture, and a node that sees nothing (V empty: K = 2).
        let (b, _) = combine(&weights, &seen, Combination::Balance);
        assert!((b[0] - (pv(0) + pu(0) + 1.0 / m) / 3.0).abs() < 1e-12);
        let (blind, o) = combine(&weights, &[false; 6], Combination::Max);
        assert!(o.iter().all(|x| *x != Origin::Visible));
        assert!((blind.iter().sum::<f64>() - 1.0).abs() < 1e-12 && blind.iter().all(|&q| q > 0.0));
    }
}
