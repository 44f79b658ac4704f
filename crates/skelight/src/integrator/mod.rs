//! The contract every estimator meets ([`Integrator`]) and the progressive, multi-threaded
//! render loop that drives them (one shared tile loop, as pbrt-v4's). The estimators
//! themselves are leaves in [`crate::estimators`], offered through its registry.
//!
//! Every sample draws its random numbers from a generator seeded by (seed, pixel, sample
//! index), and tiles are merged in a fixed order, so a render is a pure function of the
//! scene, the estimator, the seed and the sample count: thread count does not matter.

pub mod diagnostics;
pub mod params;

use std::any::Any;
use std::time::{Duration, Instant};

use crate::film::{Film, FilmTile};
use crate::paths::subpath;
use crate::sampling::Rng;
use crate::scene::Scene;

/// An estimator of the pixel integral.
///
/// A render calls [`Integrator::prepare`] once, then, pass after pass,
/// [`Integrator::prepare_iteration`] for each sample index of the pass and
/// [`Integrator::sample`] for every pixel and sample index, each tile of the film with its
/// own [`Scratch`], and at the end of the pass [`Integrator::finish_pass`] with those
/// scratches in tile order (so a render stays a pure function of its inputs).
pub trait Integrator: Sync + Send {
    fn name(&self) -> &'static str;
    /// Work done once per render before any sample, from the scene alone (an analysis of
    /// its empty space, importance from its lights). Counted in the render's time.
    fn prepare(&mut self, _scene: &Scene) -> Result<Preparation, PrepareError> {
        Ok(Preparation::default())
    }
    /// A tile's working memory (path buffers, statistics to learn from), made once per
    /// tile and pass and handed to every [`Integrator::sample`] of that tile.
    fn new_scratch(&self) -> Scratch {
        Scratch::none()
    }
    /// Takes one camera sample in pixel (`x`, `y`) and records it in `cx.tile` (and any
    /// light-path splats anywhere on the film).
    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext);
    /// Whether the estimator shares work between the pixels of an iteration.
    fn prepares_iterations(&self) -> bool {
        false
    }
    /// Work shared by all pixels for sample index `index` (bpt's light sub-paths), made
    /// before any of them is sampled, into `into` (whose buffers a previous iteration may
    /// have left allocated, to be reused). Must depend only on the scene, `seed` and `index`.
    fn prepare_iteration(&self, _scene: &Scene, _seed: u64, _index: u64, _into: &mut Iteration) {}
    /// Learns from a finished pass (what its tiles' scratches gathered, in tile order).
    /// Whatever it changes applies from the next pass on: within a pass the estimator is
    /// fixed, so each pass is unbiased on its own.
    fn finish_pass(&mut self, _scene: &Scene, _scratches: &mut [Scratch]) {}
    /// Whether [`Integrator::finish_pass`] changes how later passes sample (learning from
    /// earlier ones). A shard of such an estimator never sees the passes before it, so its
    /// merge would not equal the single render: shards refuse it.
    fn learns_across_passes(&self) -> bool {
        false
    }
    /// Light paths traced per camera sample (normalises splats; 0 if none).
    fn splats_per_sample(&self) -> u64 {
        0
    }
    /// Why this estimator cannot render all of `scene`, if it cannot (light transport it
    /// has no strategy for). Such renders are incomplete, not wrong.
    fn limitation(&self, _scene: &Scene) -> Option<String> {
        None
    }
    /// Its parameters as `name=value` pairs, for reports and checkpoint keys.
    fn describe(&self) -> String {
        self.name().to_string()
    }
    /// Facts about the render so far worth a line in its report (the cost of per-iteration
    /// work, what was learnt); empty for most estimators.
    fn report(&self) -> Vec<String> {
        Vec::new()
    }
    /// The parts its image splits into for `render --debug` ([`diagnostics::DebugParts`]),
    /// if it offers any; an error where it cannot for this scene (why).
    fn debug_parts(&self, _scene: &Scene) -> Result<Option<diagnostics::DebugParts>, String> {
        Ok(None)
    }
    /// Pictures of its internals for `render --debug`, after [`Integrator::prepare`] and the
    /// render (skelpt's guidance, skelbpt's nodes); empty for most.
    fn debug_files(&self, _scene: &Scene) -> Vec<diagnostics::DebugFile> {
        Vec::new()
    }
}

/// What one camera sample writes to and may use besides the scene and its random numbers.
pub struct SampleContext<'a> {
    /// The tile of the film the pixel lies in (splats may land anywhere on the film).
    pub tile: &'a mut FilmTile,
    /// What [`Integrator::prepare_iteration`] made for this sample index.
    pub iteration: &'a Iteration,
    /// The tile's working memory.
    pub scratch: &'a mut Scratch,
}

/// A tile's working memory, of whatever type its estimator chose.
pub struct Scratch(Box<dyn Any + Send>);

impl Scratch {
    pub fn new<T: Any + Send>(value: T) -> Scratch {
        Scratch(Box::new(value))
    }
    /// For estimators that need none.
    pub fn none() -> Scratch {
        Scratch(Box::new(()))
    }
    /// The estimator's own type (made by its [`Integrator::new_scratch`]).
    pub fn get<T: Any>(&mut self) -> &mut T {
        self.0.downcast_mut().expect("a scratch made by the same estimator's new_scratch")
    }
}

/// What [`Integrator::prepare`] did, for reports.
#[derive(Clone, Debug, Default)]
pub struct Preparation {
    /// Its stages and their wall times in seconds.
    pub stages: Vec<(String, f64)>,
    /// Facts worth a line in the report (node counts, fallbacks taken).
    pub notes: Vec<String>,
    /// Total wall time (filled by [`render`]).
    pub elapsed: Duration,
}

#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct PrepareError(pub String);

/// What all pixels of one iteration (one sample each) share.
#[derive(Default)]
pub struct Iteration {
    /// One light sub-path per pixel (empty for estimators that need none).
    pub light_paths: subpath::LightPaths,
    /// Whatever else the estimator shares between the iteration's pixels (skelbpt's
    /// resampling distributions), of its own type.
    extra: Option<Box<dyn Any + Send + Sync>>,
}

impl Iteration {
    /// The light sub-paths and the estimator's own shared state, made with `T::default()`
    /// the first time (kept from iteration to iteration, so its buffers are reused).
    pub fn with_extra<T: Any + Send + Sync + Default>(&mut self) -> (&subpath::LightPaths, &mut T) {
        if !self.extra.as_ref().is_some_and(|e| e.is::<T>()) {
            self.extra = Some(Box::new(T::default()));
        }
        (&self.light_paths, self.extra.as_mut().and_then(|e| e.downcast_mut()).expect("just made"))
    }
    /// The state [`Iteration::with_extra`] made, if it made one of this type.
    pub fn extra<T: Any>(&self) -> Option<&T> {
        self.extra.as_ref().and_then(|e| e.downcast_ref())
    }
}

/// When to stop and how to run.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Samples per pixel to reach (used when `time` is `None`, or as a cap with it).
    pub spp: Option<u32>,
    /// Wall-clock budget.
    pub time: Option<Duration>,
    pub seed: u64,
    /// Worker threads; 0 = all cores.
    pub threads: usize,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions { spp: Some(16), time: None, seed: 0, threads: 0 }
    }
}

/// Reported after each pass.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    pub spp_done: u32,
    pub spp_target: Option<u32>,
    pub elapsed: Duration,
    pub time_budget: Option<Duration>,
    pub samples_per_second: f64,
}

pub struct RenderResult {
    pub film: Film,
    pub spp: u32,
    /// Wall time, preparation included.
    pub elapsed: Duration,
    pub preparation: Preparation,
}

const TILE: usize = 32;

/// Tile side for a `w`×`h` film: [`TILE`], or less on small films so that there are at least
/// 64 tiles to balance between threads. Depends on the film only (not on the thread count),
/// so splats merge in the same order and renders stay identical whatever the thread count.
fn tile_size(w: usize, h: usize) -> usize {
    let mut tile = TILE;
    while tile > 8 && w.div_ceil(tile) * h.div_ceil(tile) < 64 {
        tile /= 2;
    }
    tile
}

/// Samples per pixel of each pass of [`render`] on a `w`×`h` film: about 2^18 samples, or
/// 2^16 for estimators that keep a pass's iterations in memory. Estimators that learn do so
/// between passes.
pub fn samples_per_pass(integrator: &dyn Integrator, w: usize, h: usize) -> u32 {
    let pass_samples = if integrator.prepares_iterations() { 65_536 } else { 262_144 };
    (pass_samples / (w * h).max(1)).clamp(1, 64) as u32
}

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid render options: {0}")]
    Options(String),
    #[error("cannot start worker threads: {0}")]
    Threads(String),
    #[error("preparing {estimator}: {error}")]
    Prepare { estimator: &'static str, error: PrepareError },
}

/// Prepares `integrator` for `scene`, then renders progressively until the sample count or
/// the time budget (which the preparation counts against) is reached. `progress` runs after
/// every pass; returning `false` from it stops early.
pub fn render(
    scene: &Scene,
    integrator: &mut dyn Integrator,
    opts: &RenderOptions,
    film: Option<(Film, u32)>,
    mut progress: impl FnMut(&Progress, &Film) -> bool,
) -> Result<RenderResult, RenderError> {
    let (w, h) = (scene.settings.width, scene.settings.height);
    if opts.spp.is_none() && opts.time.is_none() {
        return Err(RenderError::Options("give a sample count or a time budget".into()));
    }
    if opts.spp == Some(0) {
        return Err(RenderError::Options("the sample count must be at least 1".into()));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads)
        .build()
        .map_err(|e| RenderError::Threads(e.to_string()))?;
    let start = Instant::now();
    let mut preparation = pool
        .install(|| integrator.prepare(scene))
        .map_err(|error| RenderError::Prepare { estimator: integrator.name(), error })?;
    preparation.elapsed = start.elapsed();
    let (mut film, mut done) = film.unwrap_or_else(|| (Film::new(w, h, scene.settings.filter), 0));
    let tile = tile_size(w, h);
    let tiles: Vec<(usize, usize, usize, usize)> = (0..h.div_ceil(tile))
        .flat_map(|ty| (0..w.div_ceil(tile)).map(move |tx| (tx * tile, ty * tile)))
        .map(|(x, y)| (x, y, tile.min(w - x), tile.min(h - y)))
        .collect();
    // Passes of about 2^18 samples, aligned to multiples of `pass` samples per pixel from
    // sample 0, so that a render resumed from a checkpoint (taken between passes) adds up
    // its sums in exactly the same order as an uninterrupted one.
    // Estimators that prepare iterations keep a pass's worth of them in memory at once.
    let pass = samples_per_pass(integrator, w, h);
    // Kept from pass to pass, so that their buffers are allocated (and paged in) once.
    let mut iterations: Vec<Iteration> = (0..pass).map(|_| Iteration::default()).collect();
    loop {
        let remaining = opts.spp.map(|s| s.saturating_sub(done)).unwrap_or(u32::MAX);
        if remaining == 0 {
            break;
        }
        if opts.time.is_some_and(|budget| start.elapsed() >= budget) {
            break;
        }
        let n = (pass - done % pass).min(remaining);
        let first = done;
        let shared: &dyn Integrator = integrator;
        let (results, mut scratches): (Vec<FilmTile>, Vec<Scratch>) = pool.install(|| {
            use rayon::prelude::*;
            let iterations = &mut iterations[..n as usize];
            iterations.par_iter_mut().zip(first..first + n).for_each(|(it, s)| {
                shared.prepare_iteration(scene, opts.seed, s as u64, it);
            });
            let iterations = &*iterations;
            tiles
                .par_iter()
                .map(|&(x0, y0, tw, th)| {
                    let mut tile = FilmTile::new(x0, y0, tw, th, film.filter);
                    let mut scratch = shared.new_scratch();
                    for y in y0..y0 + th {
                        for x in x0..x0 + tw {
                            let pixel = (y * w + x) as u64;
                            for s in first..first + n {
                                let mut rng = Rng::new(opts.seed, pixel, s as u64);
                                let iteration = &iterations[(s - first) as usize];
                                let mut cx = SampleContext { tile: &mut tile, iteration, scratch: &mut scratch };
                                shared.sample(scene, x, y, &mut rng, &mut cx);
                            }
                        }
                    }
                    (tile, scratch)
                })
                .unzip()
        });
        pool.install(|| film.merge_tiles(&results));
        integrator.finish_pass(scene, &mut scratches);
        film.splat_paths += integrator.splats_per_sample() * n as u64 * (w * h) as u64;
        done += n;
        let elapsed = start.elapsed();
        let p = Progress {
            spp_done: done,
            spp_target: opts.spp,
            elapsed,
            time_budget: opts.time,
            samples_per_second: (done as f64 * (w * h) as f64) / elapsed.as_secs_f64().max(1e-9),
        };
        if !progress(&p, &film) {
            break;
        }
    }
    Ok(RenderResult { film, spp: done, elapsed: start.elapsed(), preparation })
}
