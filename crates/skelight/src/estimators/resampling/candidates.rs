//! What every light-vertex resampling estimator shares (thesis §11.1, seed 000 §4): each
//! iteration, N of the iteration's light sub-paths drawn at random as **candidates**, their
//! vertices and MIS running sums copied together, and per light depth s the candidates
//! whose vertex y_s can end a connection; discrete **tables** over those candidates, drawn
//! with exact integer thresholds; and the **combination** of the three distributions V, U
//! and C (eq. 188–190) into one table by the max heuristic (§11.3). `skelbpt` caches tables
//! at skeleton nodes ([`super::node_tables`]), `icbpt` at importance records
//! ([`super::importance_cache`]).

use super::node_tables::Origin;
use crate::paths::mis::{running_sums, Heuristic};
use crate::paths::subpath::LightPaths;
use crate::paths::vertex::{Vertex, VertexKind};
use crate::sampling::Rng;
use crate::scene::Scene;

/// How a table combines V, U and C.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Combination {
    /// The max heuristic folded into the distributions (§11.3, the thesis's choice).
    Max,
    /// The balance heuristic: the mixture (p_V + p_U + p_C)/K.
    Balance,
}

impl Combination {
    /// From a parameter's value ("balance"; anything else the registry let through: "max").
    pub fn parse(name: &str) -> Combination {
        if name == "balance" {
            Combination::Balance
        } else {
            Combination::Max
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Combination::Max => "max",
            Combination::Balance => "balance",
        }
    }
}

/// One resampled candidate.
#[derive(Clone, Copy, Debug)]
pub struct Draw {
    /// Index of the candidate (into [`Candidates::paths`]).
    pub candidate: usize,
    /// The probability it was drawn with.
    pub probability: f32,
    pub origin: Origin,
}

/// A table for one light depth, over the depth's eligible candidates in their order.
/// Drawn by a 32-bit random integer r: candidate i for `ends[i − 1] ≤ r < ends[i]`, so its
/// probability is exactly (ends[i] − ends[i − 1]) / 2³² — what the estimator divides by is
/// what the draw did, with no rounding of a float CDF in between.
#[derive(Default)]
pub struct Table {
    /// Exclusive upper thresholds, strictly increasing, the last 2³².
    ends: Vec<u64>,
    origins: Vec<Origin>,
}

pub(crate) const TWO_32: f64 = 4_294_967_296.0;

impl Table {
    /// The table of `probabilities` (any positive scale; normalised here).
    pub fn new(probabilities: &[f64], origins: Vec<Origin>) -> Table {
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

    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// The position drawn by the uniform 32-bit integer `r`, and its probability.
    #[inline]
    pub fn draw(&self, r: u32) -> (usize, f64) {
        let i = self.ends.partition_point(|&e| e <= r as u64);
        (i, self.probability(i))
    }

    /// The exact probability of position `i`.
    #[inline]
    pub fn probability(&self, i: usize) -> f64 {
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        (self.ends[i] - start) as f64 / TWO_32
    }

    /// The distribution position `i` is credited to.
    #[inline]
    pub fn origin(&self, i: usize) -> Origin {
        self.origins[i]
    }

    pub fn bytes(&self) -> usize {
        self.origins.len() * (1 + 8) + std::mem::size_of::<Table>()
    }
}

/// Uniform draw among `m` positions with the 32-bit integer `r`: r·m / 2³² puts ⌊2³²/m⌋ or
/// ⌈2³²/m⌉ values of r on each ([`uniform_position_probability`] says which).
#[inline]
pub fn uniform_position(r: u32, m: usize) -> usize {
    ((r as u64 * m as u64) >> 32) as usize
}

/// The exact probability that [`uniform_position`] returns `i` among `m` (within m/2³² of
/// 1/m, relatively): the r from ⌈i·2³²/m⌉ on return at least i.
#[inline]
pub fn uniform_position_probability(i: usize, m: usize) -> f64 {
    let start = |i: u64| (i << 32).div_ceil(m as u64);
    (start(i as u64 + 1) - start(i as u64)) as f64 / TWO_32
}

/// The smallest 32-bit integer for which [`uniform_position`] returns `i` among `m`.
pub fn uniform_position_start(i: usize, m: usize) -> u32 {
    ((i as u64) << 32).div_ceil(m as u64) as u32
}

/// One iteration's candidates.
#[derive(Default)]
pub struct Candidates {
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
}

/// Separates the candidates' random numbers from every other stream.
const CANDIDATE_STREAM: u64 = 0x7265_7361_6d70_6c65;

impl Candidates {
    /// Draws `n` of `light_paths` uniformly at random (seeded by `seed` and `iteration`
    /// only, so the choice is the same whatever the thread count), up to light depth
    /// `deepest`, replacing what was held.
    pub fn draw(
        &mut self,
        scene: &Scene,
        light_paths: &LightPaths,
        n: usize,
        heuristic: Heuristic,
        deepest: usize,
        (seed, iteration): (u64, u64),
    ) {
        let mut rng = Rng::new(seed ^ CANDIDATE_STREAM, 0, iteration);
        self.paths = random_subset(light_paths.len(), n, &mut rng);
        self.vertices.clear();
        self.sums.clear();
        self.starts.clear();
        self.starts.push(0);
        let mut buffer = Vec::new();
        let mut depths = 0;
        for &p in &self.paths {
            let path = light_paths.path(p as usize);
            running_sums(scene, path, heuristic, &mut buffer);
            self.vertices.extend_from_slice(path);
            self.sums.extend_from_slice(&buffer);
            self.starts.push(self.vertices.len() as u32);
            depths = depths.max(path.len().min(deepest).saturating_sub(1));
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
    }

    /// N, the number of candidates (the estimator's normalisation, eq. 186).
    pub fn candidates(&self) -> usize {
        self.paths.len()
    }

    /// Light depths with eligible candidates: s from 2 to this + 1.
    pub fn depths(&self) -> usize {
        self.eligible.len()
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

    /// The uniform draw among the candidates eligible at depth `s` (the fallback where no
    /// table applies); `None` where there is none.
    #[inline]
    pub fn draw_uniform(&self, s: usize, r: u32) -> Option<Draw> {
        let eligible = self.eligible(s);
        if eligible.is_empty() {
            return None;
        }
        let i = uniform_position(r, eligible.len());
        let probability = uniform_position_probability(i, eligible.len()) as f32;
        Some(Draw { candidate: eligible[i] as usize, probability, origin: Origin::Fallback })
    }

    /// Bytes held: the copied vertices and sums, the indices and eligible lists.
    pub fn bytes(&self) -> usize {
        self.vertices.len() * std::mem::size_of::<Vertex>()
            + self.sums.len() * 4
            + self.starts.len() * 4
            + self.paths.len() * 4
            + self.eligible.iter().map(|e| e.len() * 4).sum::<usize>()
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

/// Each candidate's probability and the distribution it is credited to, from its weight
/// (U's, unnormalised) and whether the table's point sees it (V is U restricted to those):
/// V, U and C (eq. 188–190) combined. Under the max heuristic a candidate keeps only the
/// distribution that gives it the highest probability; each distribution so cut is
/// renormalised (its kept mass Z_X), and X is drawn uniformly among the K distributions
/// left non-empty: the probability is p_X*(j)/(K·Z_X*). Every candidate keeps at least C's
/// share (its largest probability is at least 1/m), so every light vertex that can
/// contribute can be drawn. The balance combination is (p_V + p_U + p_C)/K.
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
