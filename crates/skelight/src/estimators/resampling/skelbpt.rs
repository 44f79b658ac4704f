//! `skelbpt`: bidirectional path tracing whose vertex connections are resampled with
//! distributions cached at the nodes of the empty space's skeleton (thesis ch. 11, seed
//! 000). Each iteration traces one light sub-path per pixel, as `bpt`, and draws N of them
//! as candidates; every node that enough eye vertices mapped to so far (§11.4) gets, per
//! light depth s, a table combining the distributions V, U and C of eq. 187–190
//! ([`super::node_tables`]). Each eye vertex z_t (t ≥ 2) finds its node through the
//! mapping grid (eq. 151–155) and, for every s ≥ 2, joins one candidate's y_s drawn from its
//! node's table, its contribution divided by N times the draw's probability (eq. 186,
//! 191): an unbiased estimate of the average over the N candidates of that (s, t)
//! strategy's MIS-weighted contribution. The path weights are `bpt`'s (exact, over every
//! strategy), so every strategy stays unbiased and together they add up to the image.
//!
//! The other strategies are `bpt`'s with the pixel's own light sub-path: emitter hits
//! (s = 0), next-event estimation (s = 1, a fresh light sample per eye vertex), light
//! vertices joined to the lens (t = 1) and light sub-paths through the aperture (t = 0).
//!
//! Choices where the authors' released code differs, and why:
//! - the first iteration resamples too: node acceptance starts from pilot eye sub-paths
//!   traced in the preparation (the released code rejected every node then);
//! - U has no hemisphere test, as eq. 189 has none (a light vertex behind the node's side
//!   of a wall is V's business, and C keeps every candidate reachable);
//! - s = 1 is next-event estimation, not resampled stored emission samples: the light's
//!   own sampling already picks the emission point, and an eye vertex no light point is
//!   visible from gains nothing from choosing among them;
//! - surface points find their node by eq. 151–155 (`skelight-shape`'s mapping), not by a
//!   search of neighbouring empty voxels along the normal.
//!
//! Where it departs from the thesis's letter: X is drawn with probability 1/K among the K
//! distributions left non-empty (V is empty at a node that sees no light vertex), not 1/3;
//! C is uniform over the candidates with a connectible vertex at depth s (those without one
//! contribute nothing whichever way they are drawn); acceptance is updated between passes
//! of the render loop (up to 64 iterations), not every iteration, so that each pass is a
//! fixed estimator. A render resumed from a checkpoint starts its acceptance again from the
//! pilot counts (the image stays unbiased; it is not bit-identical to an uninterrupted one).
//! With `combination=balance` a draw is credited to the distribution that gives it the
//! highest probability, as under max, for the per-distribution images.

use super::join::{self, Only};
use super::node_tables::{accept, BuildInput, Combination, NodeSelection, Resampling};
use crate::color::Rgb;
use crate::guided::pictures::node_use_picture;
use crate::guided::{GuideSettings, SkeletonGuide};
use crate::integrator::diagnostics::{DebugFile, DebugParts};
use crate::integrator::params::{ParamKind, ParamSpec, Params};
use crate::integrator::{Integrator, Iteration, Preparation, PrepareError, SampleContext, Scratch};
use crate::paths::bidir::{PixelPaths, PixelSampler, PixelScratch, Recorded};
use crate::paths::mis::Heuristic;
use crate::sampling::Rng;
use crate::scene::Scene;

/// skelbpt's parameters, as the registry offers them.
pub const PARAMS: &[ParamSpec] = &[
    join::CANDIDATES,
    ParamSpec {
        name: "acceptance",
        kind: ParamKind::Float { min: 0.0, max: 1000.0 },
        default: "1",
        doc: "alpha: a node gets tables when at least alpha times the mean count of eye vertices per node \
              have mapped to it so far (section 11.4); 0 takes every node reached",
    },
    ParamSpec {
        name: "combination",
        kind: ParamKind::Choice(&["max", "balance"]),
        default: "max",
        doc: "how each node's V, U and C distributions combine: the max heuristic folded in (the thesis), or balance",
    },
    crate::integrator::params::SKELETON_RESOLUTION,
    crate::integrator::params::SKELETON_BOUNDS,
    crate::integrator::params::MIS_HEURISTIC,
    join::ONLY,
];

pub struct SkeletonBpt {
    bpt: PixelSampler,
    pub candidates: usize,
    pub acceptance: f64,
    pub combination: Combination,
    /// The analysis' resolution and box.
    pub guide: GuideSettings,
    /// What it records (for per-distribution images).
    only: Only,
    /// The parameters it was made from (its per-distribution variants differ in `only`).
    params: Params,
    prepared: Option<NodeSelection>,
    /// What the iterations' builds cost, summed.
    stats: join::BuildLog,
}

/// A tile's buffers, and the eye vertices its samples mapped to each node.
struct TileScratch {
    buffers: PixelScratch,
    mapped: Vec<u32>,
}

impl SkeletonBpt {
    pub fn from_params(p: &Params) -> SkeletonBpt {
        let only = Only::from_params(p);
        let heuristic = Heuristic::parse(p.choice("heuristic")).unwrap_or_default();
        let recorded = if only.records_unresampled() { Recorded::All } else { Recorded::Nothing };
        SkeletonBpt {
            bpt: PixelSampler { max_depth: None, heuristic, only: recorded },
            candidates: p.int("candidates") as usize,
            acceptance: p.float("acceptance"),
            combination: Combination::parse(p.choice("combination")),
            guide: GuideSettings::from_params(p),
            only,
            params: p.clone(),
            prepared: None,
            stats: join::BuildLog::default(),
        }
    }

    /// The skeleton it resamples with and the nodes the next pass builds tables for (after
    /// [`Integrator::prepare`]).
    pub fn nodes(&self) -> Option<(&SkeletonGuide, &[u32], &[u64])> {
        self.prepared.as_ref().map(|p| (&*p.guide, &p.accepted[..], &p.mapped[..]))
    }

    /// The joins of camera vertex t with one candidate per light depth s ≥ 2, drawn from
    /// its node's tables.
    fn resampled_joins(
        &self,
        scene: &Scene,
        (guide, table): (&SkeletonGuide, &Resampling),
        paths: &PixelPaths,
        t: usize,
        rng: &mut Rng,
        mapped: &mut [u32],
    ) -> Rgb {
        let Some(z) = join::joinable(scene, paths, t) else { return Rgb::BLACK };
        let node = guide.node_at(z.p(), z.n(), z.si.wi);
        if let Some(n) = node {
            mapped[n as usize] += 1;
        }
        let draw = |s: usize, rng: &mut Rng| table.draw(node, s, rng.next_u32());
        join::joins_at(&self.bpt, scene, table, paths, t, rng, self.only, draw)
    }
}

impl Integrator for SkeletonBpt {
    fn name(&self) -> &'static str {
        "skelbpt"
    }

    fn describe(&self) -> String {
        let only = self.only.name();
        format!(
            "skelbpt candidates={} acceptance={} combination={} {} heuristic={} only={only}",
            self.candidates,
            self.acceptance,
            self.combination.name(),
            self.guide.describe(),
            format!("{:?}", self.bpt.heuristic).to_lowercase(),
        )
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Preparation, PrepareError> {
        self.prepared = None;
        self.stats.reset();
        let mut prep = Preparation::default();
        if scene.lights.is_empty() {
            prep.notes.push("the scene has no lights: plain bpt".into());
            return Ok(prep);
        }
        let settings = self.guide;
        self.prepared =
            Some(NodeSelection::prepare(scene, &settings, self.acceptance, self.bpt.max_depth(scene), &mut prep)?);
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
        let Some(p) = &self.prepared else { return };
        let (light_paths, table) = into.with_extra::<Resampling>();
        let input = BuildInput {
            guide: &p.guide,
            accepted: &p.accepted,
            candidates: self.candidates,
            combination: self.combination,
            heuristic: self.bpt.heuristic,
            deepest: join::deepest_join(self.bpt.max_depth(scene)),
            seed,
            iteration: index,
        };
        table.build(scene, light_paths, &input);
        self.stats.add(&table.stats, table.bytes());
    }

    fn new_scratch(&self) -> Scratch {
        let nodes = self.prepared.as_ref().map_or(0, |p| p.mapped.len());
        Scratch::new(TileScratch { buffers: PixelScratch::default(), mapped: vec![0; nodes] })
    }

    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let it = cx.iteration;
        let TileScratch { buffers, mapped } = cx.scratch.get::<TileScratch>();
        let joins = match (&self.prepared, it.extra::<Resampling>()) {
            (Some(p), Some(table)) => Some(|paths: &PixelPaths, t: usize, rng: &mut Rng| {
                self.resampled_joins(scene, (&p.guide, table), paths, t, rng, mapped)
            }),
            _ => None,
        };
        join::sample_pixel(&self.bpt, scene, (x, y), rng, it, buffers, cx.tile, joins);
    }

    fn learns_across_passes(&self) -> bool {
        true
    }

    fn finish_pass(&mut self, _scene: &Scene, scratches: &mut [Scratch]) {
        let Some(p) = self.prepared.as_mut() else { return };
        for s in scratches.iter_mut() {
            for (total, m) in p.mapped.iter_mut().zip(&s.get::<TileScratch>().mapped) {
                *total += *m as u64;
            }
        }
        p.accepted = accept(&p.mapped, self.acceptance);
    }

    fn debug_files(&self, scene: &Scene) -> Vec<DebugFile> {
        let Some((guide, accepted, mapped)) = self.nodes() else { return Vec::new() };
        let image = node_use_picture(scene, guide, accepted, mapped);
        vec![DebugFile::Png { name: "nodes_view.png".into(), image }]
    }

    fn debug_parts(&self, _scene: &Scene) -> Result<Option<DebugParts>, String> {
        join::distribution_parts(&self.params, |p| Box::new(SkeletonBpt::from_params(p)))
    }

    fn report(&self) -> Vec<String> {
        self.stats.report("nodes accepted")
    }
}
