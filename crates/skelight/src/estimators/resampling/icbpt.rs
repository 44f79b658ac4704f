//! `icbpt`: bidirectional path tracing whose vertex connections are resampled with
//! distributions cached at importance records — Georgiev et al. 2012's importance caching
//! adapted to BPT, the method the thesis compares `skelbpt` against (§11.5, seed 000 §5).
//! Each iteration traces one light sub-path per pixel, as `bpt`, draws N of them as
//! candidates (as `skelbpt`), and traces d·pixels sparse eye sub-paths whose vertices
//! become records, each with a table per light depth over the candidates
//! ([`super::importance_cache`]: the full distribution with visibility, the
//! unoccluded one and the conservative one, combined by the max heuristic). Each eye vertex
//! z_t (t ≥ 2) finds its nearest records in a kd-tree and, for every s ≥ 2, joins one
//! candidate's y_s drawn from them, its contribution divided by N times the draw's
//! probability (eq. 186): unbiased, with `bpt`'s exact MIS weights over every strategy.
//! Eye vertices near no record draw uniformly among the candidates (the released code made
//! no connection there: a bias).
//!
//! The other strategies are `bpt`'s with the pixel's own light sub-path, as in `skelbpt`.
//! Per-distribution images: `only=V` (Georgiev's full), `U` (unoccluded), `C`
//! (conservative), `fallback`, `unresampled`.

use super::candidates::Combination;
use super::importance_cache::{CacheInput, ImportanceCache, Nearby};
use super::join::{self, Only};
use crate::color::Rgb;
use crate::integrator::diagnostics::DebugParts;
use crate::integrator::params::{ParamKind, ParamSpec, Params};
use crate::integrator::{Integrator, Iteration, Preparation, PrepareError, SampleContext, Scratch};
use crate::paths::bidir::{PixelPaths, PixelSampler, PixelScratch, Recorded};
use crate::paths::mis::Heuristic;
use crate::sampling::Rng;
use crate::scene::Scene;

/// icbpt's parameters, as the registry offers them.
pub const PARAMS: &[ParamSpec] = &[
    join::CANDIDATES,
    ParamSpec {
        name: "density",
        kind: ParamKind::Float { min: 0.0, max: 1.0 },
        default: "0.001",
        doc: "d: eye sub-paths traced per iteration to place importance records, per pixel (at least one); \
              the paper's 0.001 gave 524 paths and about 3000 records at 1024x512",
    },
    ParamSpec {
        name: "combination",
        kind: ParamKind::Choice(&["max", "balance"]),
        default: "max",
        doc: "how each record's three distributions combine: the max heuristic folded in, or balance",
    },
    ParamSpec {
        name: "records",
        kind: ParamKind::Choice(&["max", "balance"]),
        default: "max",
        doc: "how the (up to 3) records an eye vertex uses combine: the max heuristic (the paper's), or balance",
    },
    crate::integrator::params::MIS_HEURISTIC,
    join::ONLY,
];

/// The most the records' tables may take per iteration (a pass holds up to 64 iterations,
/// fewer as the image grows: `render`'s pass is about 65 536 samples).
pub const TABLE_BUDGET: usize = 512 << 20;

pub struct IcBpt {
    bpt: PixelSampler,
    pub candidates: usize,
    pub density: f64,
    pub combination: Combination,
    pub records: Combination,
    only: Only,
    /// The parameters it was made from (its per-distribution variants differ in `only`).
    params: Params,
    /// Whether the scene has lights to resample (set by `prepare`).
    resamples: bool,
    /// What the iterations' builds cost, summed, and the most memory one held.
    stats: join::BuildLog,
}

/// A tile's buffers.
#[derive(Default)]
struct TileScratch {
    buffers: PixelScratch,
    nearby: Nearby,
}

impl IcBpt {
    pub fn from_params(p: &Params) -> IcBpt {
        let only = Only::from_params(p);
        let heuristic = Heuristic::parse(p.choice("heuristic")).unwrap_or_default();
        let recorded = if only.records_unresampled() { Recorded::All } else { Recorded::Nothing };
        IcBpt {
            bpt: PixelSampler { max_depth: None, heuristic, only: recorded },
            candidates: p.int("candidates") as usize,
            density: p.float("density"),
            combination: Combination::parse(p.choice("combination")),
            records: Combination::parse(p.choice("records")),
            only,
            params: p.clone(),
            resamples: false,
            stats: join::BuildLog::default(),
        }
    }

    /// Eye sub-paths traced per iteration for the records: d·pixels (at least one), capped
    /// so that the tables stay under [`TABLE_BUDGET`] bytes per iteration; and whether the
    /// cap applied. A table takes N × 9 bytes, a record one per light depth (at most
    /// max depth − 1), an eye sub-path at most max depth records (16 counted when unlimited).
    pub fn record_paths(&self, scene: &Scene) -> (usize, bool) {
        let wanted = ((self.density * (scene.settings.width * scene.settings.height) as f64).ceil() as usize).max(1);
        let depth = match self.bpt.max_depth(scene) {
            d if d < 0 => 16,
            d => d.max(2) as usize,
        };
        let per_path = depth * (depth - 1) * self.candidates * 9;
        let cap = (TABLE_BUDGET / per_path).max(1);
        (wanted.min(cap), wanted > cap)
    }

    /// The joins of camera vertex t with one candidate per light depth s ≥ 2, drawn from
    /// its nearest records' tables.
    fn resampled_joins(
        &self,
        scene: &Scene,
        cache: &ImportanceCache,
        paths: &PixelPaths,
        t: usize,
        rng: &mut Rng,
        nearby: &mut Nearby,
    ) -> Rgb {
        let Some(z) = join::joinable(scene, paths, t) else { return Rgb::BLACK };
        cache.nearby(z, nearby);
        let draw =
            |s: usize, rng: &mut Rng| cache.draw(nearby.records(), s, (rng.next_u32(), rng.next_u32()), self.records);
        join::joins_at(&self.bpt, scene, cache, paths, t, rng, self.only, draw)
    }
}

impl Integrator for IcBpt {
    fn name(&self) -> &'static str {
        "icbpt"
    }

    fn describe(&self) -> String {
        format!(
            "icbpt candidates={} density={} combination={} records={} heuristic={} only={}",
            self.candidates,
            self.density,
            self.combination.name(),
            self.records.name(),
            format!("{:?}", self.bpt.heuristic).to_lowercase(),
            self.only.name(),
        )
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Preparation, PrepareError> {
        self.stats.reset();
        let mut prep = Preparation::default();
        self.resamples = !scene.lights.is_empty();
        if self.resamples {
            let (paths, capped) = self.record_paths(scene);
            prep.notes.push(format!(
                "importance records: {paths} eye sub-paths per iteration (d = {}{}), {} candidates",
                self.density,
                if capped { ", capped to keep the tables under 512 MB per iteration" } else { "" },
                self.candidates
            ));
        } else {
            prep.notes.push("the scene has no lights: plain bpt".into());
        }
        Ok(prep)
    }

    fn splats_per_sample(&self) -> u64 {
        1
    }

    fn prepares_iterations(&self) -> bool {
        true
    }

    fn prepare_iteration(&self, scene: &Scene, seed: u64, index: u64, into: &mut Iteration) {
        self.bpt.trace_light_paths(scene, seed, index, &mut into.light_paths);
        if !self.resamples {
            return;
        }
        let (light_paths, cache) = into.with_extra::<ImportanceCache>();
        let max_depth = self.bpt.max_depth(scene);
        let input = CacheInput {
            record_paths: self.record_paths(scene).0,
            candidates: self.candidates,
            combination: self.combination,
            heuristic: self.bpt.heuristic,
            deepest: join::deepest_join(max_depth),
            max_depth,
            seed,
            iteration: index,
        };
        cache.build(scene, light_paths, &input);
        self.stats.add(&cache.stats, cache.bytes());
    }

    fn new_scratch(&self) -> Scratch {
        Scratch::new(TileScratch::default())
    }

    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let it = cx.iteration;
        let TileScratch { buffers, nearby } = cx.scratch.get::<TileScratch>();
        let joins = it.extra::<ImportanceCache>().filter(|_| self.resamples).map(|cache| {
            move |paths: &PixelPaths, t: usize, rng: &mut Rng| self.resampled_joins(scene, cache, paths, t, rng, nearby)
        });
        join::sample_pixel(&self.bpt, scene, (x, y), rng, it, buffers, cx.tile, joins);
    }

    fn debug_parts(&self, _scene: &Scene) -> Result<Option<DebugParts>, String> {
        join::distribution_parts(&self.params, |p| Box::new(IcBpt::from_params(p)))
    }

    fn report(&self) -> Vec<String> {
        self.stats.report("importance records")
    }
}
