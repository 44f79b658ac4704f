//! `bpt`: bidirectional path tracing (thesis §4.1.3). Each iteration first traces one light
//! sub-path per pixel into a shared buffer (eq. 185); each camera sub-path is then joined to
//! its pixel's light sub-path by every (s, t) strategy ([`crate::paths::bidir`]), weighted
//! by exact MIS (balance heuristic by default, power on request).

use crate::integrator::diagnostics::{DebugPart, DebugParts};
use crate::integrator::{Integrator, Iteration, SampleContext, Scratch};
use crate::paths::bidir::{PixelPaths, PixelSampler, PixelScratch, Recorded};
use crate::sampling::Rng;
use crate::scene::Scene;

#[derive(Clone, Debug, Default)]
pub struct Bpt {
    pub sampler: PixelSampler,
}

impl Integrator for Bpt {
    fn name(&self) -> &'static str {
        "bpt"
    }
    fn splats_per_sample(&self) -> u64 {
        1
    }
    fn prepares_iterations(&self) -> bool {
        true
    }
    fn prepare_iteration(&self, scene: &Scene, seed: u64, index: u64, into: &mut Iteration) {
        self.sampler.trace_light_paths(scene, seed, index, &mut into.light_paths);
    }
    fn describe(&self) -> String {
        let mut d = format!("bpt heuristic={}", format!("{:?}", self.sampler.heuristic).to_lowercase());
        if self.sampler.only != Recorded::All {
            d += &format!(" only={:?}", self.sampler.only);
        }
        if let Some(m) = self.sampler.max_depth {
            d += &format!(" max_depth={m}");
        }
        d
    }
    fn new_scratch(&self) -> Scratch {
        Scratch::new(PixelScratch::default())
    }
    /// Each (s, t) strategy's MIS-weighted contribution alone (paths of k segments have
    /// k + 1 vertices: strategies s + t = k + 1).
    fn debug_parts(&self, scene: &Scene) -> Result<Option<DebugParts>, String> {
        let max_depth = self.sampler.max_depth(scene);
        if !(1..=16).contains(&max_depth) {
            return Err(format!("bpt's strategy images need a max depth from 1 to 16 (--max-depth), not {max_depth}"));
        }
        let parts = (2..=max_depth as usize + 1)
            .flat_map(|vertices| (0..=vertices).map(move |s| (s, vertices - s)))
            .map(|(s, t)| DebugPart {
                stem: format!("s{s}_t{t}"),
                columns: format!("{s},{t},{}", s + t - 2),
                estimator: Box::new(Bpt {
                    sampler: PixelSampler { only: Recorded::Strategy(s, t), ..self.sampler.clone() },
                }),
            })
            .collect();
        Ok(Some(DebugParts { table: ("strategies.csv", "s,t,segments"), parts }))
    }
    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let sampler = &self.sampler;
        let mut joins = |paths: &PixelPaths, t: usize, _: &mut Rng| sampler.own_path_joins(scene, paths, t);
        let buffers = cx.scratch.get::<PixelScratch>();
        sampler.sample_pixel(scene, (x, y), rng, &cx.iteration.light_paths, buffers, cx.tile, &mut joins);
    }
}
