//! icbpt's light-vertex resampling distributions, cached at **importance records**:
//! Georgiev et al. 2012's importance caching adapted to bidirectional path tracing, as the
//! thesis compares against (§11.5, seed 000 §5). Each iteration, d·pixels sparse eye
//! sub-paths are traced through a jittered grid over the image, and each of their vertices
//! that can be joined becomes a record. Per record and light depth s, three distributions
//! over the iteration's N candidates (shared with `skelbpt`, [`super::candidates`]):
//! - **V**, Georgiev's *full* distribution: the join's unweighted contribution from the
//!   light vertex to the record (both BSDFs, both cosines, 1/d², the light throughput),
//!   with visibility;
//! - **U**, the same without visibility (Georgiev's *unoccluded*);
//! - **C**, Georgiev's *conservative*: uniform over the candidates that can contribute;
//!
//! combined in each record's table by the max heuristic folded in, as skelbpt's nodes
//! ([`super::candidates::combine`]). An eye vertex looks up its 6 nearest records in a
//! kd-tree, keeps the (up to) 3 that face its side best, picks one of them uniformly and
//! draws a candidate from its table. The records are combined by the max heuristic
//! (`records=max`: the draw counts only if the picked record gives the candidate the
//! highest probability among the kept ones, and the estimator divides by that probability
//! over their number) or the balance heuristic (`records=balance`: divided by the mixture).
//! Both are unbiased: every kept record gives every eligible candidate a positive
//! probability (C's share), so the weights form a partition of unity.
//!
//! Where no record is kept (none faces the eye vertex's side, or none exists), the eye
//! vertex draws uniformly among the candidates: the released code made no connection there,
//! which loses those paths' light (a bias).
//!
//! Not taken from Georgiev: the *bounded* distribution (an upper bound of the geometry term
//! over a record's region of influence) and the α-confidence of the α-max heuristic (α = 1,
//! the max heuristic); the bounded one matters for records far from the eye vertex, which
//! the kept records' C share already covers unbiasedly.

use rayon::prelude::*;

use super::candidates::{uniform_position, uniform_position_probability, Candidates, Combination, Draw, Table};
use super::kdtree::KdTree;
use super::node_tables::BuildStats;
use crate::math::{vec2, Vec3};
use crate::paths::mis::Heuristic;
use crate::paths::strategies::edge;
use crate::paths::subpath::{camera_subpath, LightPaths};
use crate::paths::vertex::{Vertex, VertexKind};
use crate::paths::visibility::visible;
use crate::sampling::Rng;
use crate::scene::Scene;

/// Records looked up per eye vertex, and kept among them (Georgiev et al.: 3 of 6).
pub const LOOKED_UP: usize = 6;
pub const KEPT: usize = 3;

/// Separates the records' random numbers from every other stream.
const RECORD_STREAM: u64 = 0x7265_636f_7264;

/// An eye vertex whose view of the candidates is cached.
struct Record {
    /// The vertex before it on its eye sub-path (the direction it was reached from).
    prev: Vertex,
    at: Vertex,
    /// Its normal, turned to the side it was seen from.
    side: Vec3,
}

/// One iteration's candidates, records and tables.
#[derive(Default)]
pub struct ImportanceCache {
    candidates: Candidates,
    records: Vec<Record>,
    tree: Option<KdTree>,
    /// Record-major, one per light depth.
    tables: Vec<Table>,
    /// Eye sub-paths traced for the records.
    pub record_paths: usize,
    pub stats: BuildStats,
}

impl std::ops::Deref for ImportanceCache {
    type Target = Candidates;
    fn deref(&self) -> &Candidates {
        &self.candidates
    }
}

/// What a build reads besides the iteration's light sub-paths.
pub struct CacheInput {
    /// Eye sub-paths traced to place records.
    pub record_paths: usize,
    /// N: candidates drawn among the iteration's light sub-paths.
    pub candidates: usize,
    pub combination: Combination,
    pub heuristic: Heuristic,
    /// The deepest light vertex a join may use (tables stop there).
    pub deepest: usize,
    pub max_depth: i32,
    pub seed: u64,
    pub iteration: u64,
}

/// The records an eye vertex uses: indices, nearest first.
#[derive(Default)]
pub struct Nearby {
    found: Vec<(f32, u32)>,
    kept: Vec<u32>,
}

impl Nearby {
    pub fn records(&self) -> &[u32] {
        &self.kept
    }
}

impl ImportanceCache {
    /// Draws the candidates, places the records and builds their tables (in parallel),
    /// replacing what was held.
    pub fn build(&mut self, scene: &Scene, light_paths: &LightPaths, input: &CacheInput) {
        let clock = std::time::Instant::now();
        let (seed, iteration) = (input.seed, input.iteration);
        self.candidates.draw(scene, light_paths, input.candidates, input.heuristic, input.deepest, (seed, iteration));
        self.records = place_records(scene, input.record_paths, input.max_depth, seed, iteration);
        self.record_paths = input.record_paths;
        let positions: Vec<Vec3> = self.records.iter().map(|r| r.at.p()).collect();
        self.tree = Some(KdTree::new(&positions));
        let (pool, records) = (&self.candidates, &self.records);
        let depths = pool.depths();
        let built: Vec<(Table, u64, u64)> = (0..records.len() * depths)
            .into_par_iter()
            .map(|k| build_table(scene, &records[k / depths], pool, k % depths + 2, input.combination))
            .collect();
        (self.tables, self.stats) = super::join::table_stats(built, records.len(), clock);
    }

    /// Number of records this iteration.
    pub fn records(&self) -> usize {
        self.records.len()
    }

    /// Record `r`'s position.
    pub fn record_position(&self, r: u32) -> Vec3 {
        self.records[r as usize].at.p()
    }

    /// The records eye vertex `z` uses: of the [`LOOKED_UP`] nearest, those on its side,
    /// the [`KEPT`] best by distance × (2 − cos) of their normals (nearest wins ties).
    pub fn nearby(&self, z: &Vertex, into: &mut Nearby) {
        into.kept.clear();
        let Some(tree) = &self.tree else { return };
        tree.nearest(z.p(), LOOKED_UP, &mut into.found);
        let side = facing(z.n(), z.si.wi);
        let mut scored: [(f32, u32); LOOKED_UP] = [(0.0, 0); LOOKED_UP];
        let mut m = 0;
        for &(d2, r) in &into.found {
            let cos = side.dot(self.records[r as usize].side);
            if cos > 0.0 {
                scored[m] = (d2.sqrt() * (2.0 - cos), r);
                m += 1;
            }
        }
        let scored = &mut scored[..m];
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        into.kept.extend(scored.iter().take(KEPT).map(|e| e.1));
    }

    /// Draws a candidate at light depth `s` ≥ 2 for an eye vertex whose kept records are
    /// `records`, with two uniform 32-bit integers: [`ImportanceCache::pick`], then
    /// [`ImportanceCache::divisor`]. `None` where no candidate has a vertex there, or where
    /// the max heuristic gives this draw no weight. No records: uniform (the fallback).
    #[inline]
    pub fn draw(&self, records: &[u32], s: usize, random: (u32, u32), combination: Combination) -> Option<Draw> {
        if records.is_empty() {
            return self.candidates.draw_uniform(s, random.1);
        }
        let (picked, i, _) = self.pick(records, s, random)?;
        let probability = self.divisor(records, s, (picked, i), combination)?;
        let origin = self.table(records[picked], s).origin(i);
        Some(Draw { candidate: self.eligible(s)[i] as usize, probability: probability as f32, origin })
    }

    /// The first stage of a draw: one of `records` uniformly with `r1` (its index in
    /// `records`), then a position among the candidates eligible at depth `s` from its
    /// table with `r2`, and that position's probability in the table.
    #[inline]
    pub fn pick(&self, records: &[u32], s: usize, (r1, r2): (u32, u32)) -> Option<(usize, usize, f64)> {
        if records.is_empty() || self.eligible(s).is_empty() {
            return None;
        }
        let picked = uniform_position(r1, records.len());
        let (i, p) = self.table(records[picked], s).draw(r2);
        Some((picked, i, p))
    }

    /// What the estimator divides by (before N) for position `i` drawn from
    /// `records[picked]`'s table, with π_j the exact probability of picking record j
    /// ([`uniform_position_probability`], 1/k to within k·2⁻³²): under the max heuristic,
    /// π·p of the picked record if it gives the highest π_j·p_j(i) among them (the first
    /// such), and `None` (no weight) otherwise; under balance, the mixture Σ_j π_j·p_j(i).
    #[inline]
    pub fn divisor(
        &self,
        records: &[u32],
        s: usize,
        (picked, i): (usize, usize),
        combination: Combination,
    ) -> Option<f64> {
        let k = records.len();
        let q = |j: usize| uniform_position_probability(j, k) * self.table(records[j], s).probability(i);
        match combination {
            Combination::Max => {
                let winner = (1..k).fold(0, |best, j| if q(j) > q(best) { j } else { best });
                (winner == picked).then(|| q(picked))
            }
            Combination::Balance => Some((0..k).map(q).sum::<f64>()),
        }
    }

    #[inline]
    fn table(&self, record: u32, s: usize) -> &Table {
        &self.tables[record as usize * self.depths() + s - 2]
    }

    /// Bytes held by the candidates, the records and their tables.
    pub fn bytes(&self) -> usize {
        self.tables.iter().map(Table::bytes).sum::<usize>()
            + self.candidates.bytes()
            + self.records.len() * (std::mem::size_of::<Record>() + 16)
    }
}

/// The normal `n` turned towards `wi`.
fn facing(n: Vec3, wi: Vec3) -> Vec3 {
    if n.dot(wi) < 0.0 {
        -n
    } else {
        n
    }
}

/// The vertices (t ≥ 2, joinable) of `count` eye sub-paths through the cells of a jittered
/// grid over the image, its cells as square as the image allows (the last row partly
/// filled).
fn place_records(scene: &Scene, count: usize, max_depth: i32, seed: u64, iteration: u64) -> Vec<Record> {
    let (w, h) = (scene.settings.width as f32, scene.settings.height as f32);
    let rows = ((count as f32 * h / w).sqrt().round() as usize).max(1);
    let cols = count.div_ceil(rows);
    (0..count)
        .into_par_iter()
        .map(|cell| {
            let mut rng = Rng::new(seed ^ RECORD_STREAM, cell as u64, iteration);
            let (cx, cy) = ((cell % cols) as f32, (cell / cols) as f32);
            let raster = vec2((cx + rng.next_f32()) * w / cols as f32, (cy + rng.next_f32()) * h / rows as f32);
            let mut path = Vec::new();
            camera_subpath(scene, raster, &mut rng, max_depth, &mut path);
            let mut records = Vec::new();
            for t in 2..=path.len() {
                let at = &path[t - 1];
                if at.kind == VertexKind::Surface && at.can_connect(scene) {
                    records.push(Record { prev: path[t - 2], at: *at, side: facing(at.n(), at.si.wi) });
                }
            }
            records
        })
        .flatten()
        .collect()
}

/// Record `record`'s table at light depth `s` over the eligible candidates, with the
/// shadow rays traced and how many reached the record.
fn build_table(
    scene: &Scene,
    record: &Record,
    pool: &Candidates,
    s: usize,
    combination: Combination,
) -> (Table, u64, u64) {
    let eligible = pool.eligible(s);
    if eligible.is_empty() {
        return (Table::default(), 0, 0);
    }
    let mut weights = Vec::with_capacity(eligible.len());
    let mut seen = Vec::with_capacity(eligible.len());
    let mut rays = 0;
    for &c in eligible {
        let path = pool.path(c as usize);
        let y = &path[s - 1];
        let contribution = edge(scene, y, &path[s - 2], &record.at, &record.prev)
            .map_or(0.0, |e| (y.beta * e.light_end.f * e.camera_end.f / e.d2).luminance().max(0.0) as f64);
        // Only a join that carries light needs its visibility (V is U restricted to it).
        let sees = contribution > 0.0 && {
            rays += 1;
            visible(scene, &record.at, y)
        };
        weights.push(if contribution.is_finite() { contribution } else { 0.0 });
        seen.push(sees);
    }
    let visible_count = seen.iter().filter(|v| **v).count() as u64;
    let (probabilities, origins) = super::candidates::combine(&weights, &seen, combination);
    (Table::new(&probabilities, origins), rays, visible_count)
}
