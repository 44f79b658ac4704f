//! A render job (skelight::job) run on the GPU: all its samples, one shard of them, or as many
//! as its time budget allows, so that `render --device gpu` takes the CPU's `--spp`, `--time`
//! and `--shard` with their meaning, and its shards merge (`skelight merge`); and `compare`'s
//! `gpu:NAME` estimators, run for the comparison's time budget.

use std::time::{Duration, Instant};

use skelight::compare::External;
use skelight::estimators::registry;
use skelight::film::Film;
use skelight::integrator::params::Params;
use skelight::integrator::{Preparation, Progress, RenderOptions, RenderResult};
use skelight::job::{Device, Job, JobError, JobSpec, Rendered};
use skelight::scene::Scene;
use skelight::shard::Manifest;

use crate::launch::READBACK_BATCH;
use crate::{Estimator, GpuError, GpuRenderer};

/// Work between two progress reports under a time budget (and the most it runs past it).
const BATCH_TIME: Duration = Duration::from_millis(250);

/// Samples per pixel in the next batch from sample index `at`. With a sample count alone, up
/// to the next multiple of READBACK_BATCH, the device's f32 groups (render_into): the same
/// command gives the same film bit for bit, and so does a reference resumed at a batch's end.
/// Under a time budget, what the rate measured so far renders in `BATCH_TIME` (or in the time
/// left), at least one; the first batch is one sample, which measures the rate (the number of
/// samples depends on the machine's speed there anyway).
fn next_batch(at: u32, done: u32, elapsed: Duration, left: Option<Duration>) -> u32 {
    let Some(left) = left else {
        return READBACK_BATCH - at % READBACK_BATCH;
    };
    if done == 0 || elapsed.is_zero() {
        return 1;
    }
    let rate = done as f64 / elapsed.as_secs_f64();
    (rate * left.min(BATCH_TIME).as_secs_f64()).clamp(1.0, u32::MAX as f64) as u32
}

/// The GPU's estimator for a registry name and parameters: the registry parses them as it
/// does for the CPU (an unknown estimator or parameter, a bad value: the CPU's errors), then
/// [`kernels_for`]. The one check that `render`, `reference` and `compare` on the GPU make
/// before the scene loads.
pub fn estimator_for(integrator: &str, params: &[(String, String)]) -> Result<Estimator, JobError> {
    let e = registry::find(integrator)?;
    kernels_for(&Params::new(e.name, e.params, params)?)
}

/// The GPU's kernels for the registry estimator whose parsed parameters are `params` (a
/// job's, the scene's `<integrator>` properties included), refusing an estimator the GPU
/// does not have and a parameter set away from its default that its kernels do not honour.
pub fn kernels_for(params: &Params) -> Result<Estimator, JobError> {
    let name = params.estimator();
    let estimator = Estimator::from_name(name).ok_or_else(|| {
        let gpu = Estimator::ALL.map(|e| e.name()).join(", ");
        JobError::Invalid(format!("the GPU renders {gpu}, not {name}"))
    })?;
    let refused: Vec<_> = params.changed().into_iter().filter(|p| !estimator.honours().contains(p)).collect();
    if !refused.is_empty() {
        return Err(JobError::Invalid(format!(
            "{name} on the GPU does not take {} (its kernels use the defaults); render on the CPU for them",
            refused.join(", ")
        )));
    }
    Ok(estimator)
}

/// The one device switch: the renderer for `job` on `scene`, the CPU's estimator
/// (`Job::run`) for a CPU job, and for a GPU job the GPU's kernels for the same registry
/// estimator, opened here (with a line naming the adapter, the splat mode and the set-up
/// time, which is not counted in the render's). The CLI's `render` and `reference`, Python's
/// `render` (and through it Dask) and `compare`'s `gpu:NAME` all pick their renderer here.
pub fn renderer_for(job: &Job, scene: &Scene) -> Result<(Box<skelight::job::Render>, Option<String>), JobError> {
    if job.device == Device::Cpu {
        return Ok((skelight::job::cpu_renderer(), None));
    }
    let estimator = kernels_for(&job.params)?;
    let setup = std::time::Instant::now();
    let mut gpu = GpuRenderer::new(scene, estimator)?;
    let line = format!(
        "GPU {}: {} (splats by {:?}; set up in {:.2} s, before the render's time)",
        estimator.name(),
        gpu.adapter,
        gpu.splat_mode,
        setup.elapsed().as_secs_f64()
    );
    let render = move |job: &mut Job,
                       scene: &Scene,
                       resume,
                       on_pass: &mut dyn FnMut(&Progress, &Film) -> Result<(), JobError>| {
        run(&mut gpu, scene, job, resume, on_pass)
    };
    Ok((Box::new(render), Some(line)))
}

/// Renders `job` (a GPU job: `JobSpec::device`) on `gpu` (bound to `scene` and the job's
/// estimator): sample indices 0..spp, the shard's slice of them, or, under a time budget,
/// from 0 until the budget is spent (at most `spp` when given too), from `resume`'s film and
/// sample count when given (a checkpointed reference); the last batch may run up to a
/// quarter of a second past the budget, which counts from when the kernels are ready (their
/// setup, GpuRenderer::new, is before). `on_pass` sees the progress and the film after each
/// batch; its error stops the render and is returned.
pub fn run(
    gpu: &mut GpuRenderer,
    scene: &Scene,
    job: &Job,
    resume: Option<(Film, u32)>,
    mut on_pass: impl FnMut(&Progress, &Film) -> Result<(), JobError>,
) -> Result<Rendered, JobError> {
    if job.device != Device::Gpu {
        return Err(JobError::Invalid("a CPU job runs on the CPU (Job::run)".into()));
    }
    let (spp, time) = (job.opts.spp, job.opts.time);
    let samples = match (job.shard_samples(), spp) {
        (Some(shard), _) if resume.is_none() => shard,
        (Some(_), _) => return Err(JobError::Invalid("a shard cannot resume another render".into())),
        (None, Some(spp)) => 0..spp,
        (None, None) if time.is_some() => 0..u32::MAX,
        _ => return Err(JobError::Invalid("give a sample count (a shard needs one) or a time budget".into())),
    };
    let s = &scene.settings;
    let (mut film, first) = match resume {
        Some((film, spp)) => (film, spp),
        None => (Film::new(s.width, s.height, s.filter), samples.start),
    };
    let pixels = (s.width * s.height) as f64;
    let start = Instant::now();
    let mut done = 0u32;
    while first + done < samples.end {
        let elapsed = start.elapsed();
        let left = time.map(|t| t.saturating_sub(elapsed));
        if left.is_some_and(|l| l.is_zero()) {
            break;
        }
        let n = next_batch(first + done, done, elapsed, left).min(samples.end - first - done);
        gpu.render_into(&mut film, job.opts.seed, first + done, n, |_| {})?;
        done += n;
        let elapsed = start.elapsed();
        let progress = Progress {
            spp_done: first + done - samples.start,
            spp_target: spp.map(|_| samples.len() as u32),
            elapsed,
            time_budget: time,
            samples_per_second: done as f64 * pixels / elapsed.as_secs_f64().max(1e-9),
        };
        on_pass(&progress, &film)?;
    }
    let manifest = job.shard.map(|shard| Manifest { render: job.key(scene), shard, samples: samples.clone() });
    Ok(Rendered {
        film,
        samples: samples.start..first + done,
        elapsed: start.elapsed(),
        preparation: Preparation::default(),
        manifest,
    })
}

/// A GPU error as a job's: what the scene or the settings ask of the GPU that it cannot do
/// is invalid input; the rest is the device's.
impl From<GpuError> for JobError {
    fn from(e: GpuError) -> JobError {
        match e {
            GpuError::Unsupported(_) | GpuError::Invalid(_) => JobError::Invalid(e.to_string()),
            _ => JobError::Device(e.to_string()),
        }
    }
}

/// `compare`'s renderer of `gpu:NAME` (pt, ibpt or lt; skelight::compare::External), for
/// the comparison's time budget from the moment its kernels are ready: the setup
/// (flattening, upload, kernel compilation) is a renderer's start, not its estimator's work,
/// and is not counted.
pub struct CompareOnGpu;

/// A registry estimator's name and its `name=value` parameters.
type NamedParams = (String, Vec<(String, String)>);

impl CompareOnGpu {
    /// `gpu:NAME[:param=value…]` as the registry's name and parameters, checked for the GPU
    /// with the scene's `<integrator>` properties as its render will read them.
    fn spec(name: &str, scene: &Scene) -> Option<Result<NamedParams, JobError>> {
        let spec = name.strip_prefix("gpu:")?;
        let checked = registry::parse_spec(spec).map_err(JobError::from).and_then(|(e, params)| {
            let (_, parsed, _) = registry::params_for_scene(&e, &scene.settings, &params)?;
            kernels_for(&parsed).map(|_| (e, params))
        });
        Some(checked)
    }
}

impl External for CompareOnGpu {
    fn check(&mut self, name: &str, scene: &Scene) -> Option<Result<(), JobError>> {
        let spec = CompareOnGpu::spec(name, scene)?;
        Some(spec.and_then(|_| Ok(GpuRenderer::check(scene)?)))
    }

    fn render(
        &mut self,
        name: &str,
        scene: &Scene,
        opts: &RenderOptions,
        on_pass: &mut dyn FnMut(&Progress, &Film) -> bool,
    ) -> Result<RenderResult, JobError> {
        let (integrator, params) = CompareOnGpu::spec(name, scene)
            .unwrap_or_else(|| Err(JobError::Invalid("not a GPU estimator (gpu:NAME)".into())))?;
        let job_spec = JobSpec {
            integrator,
            params,
            spp: opts.spp,
            time: opts.time,
            seed: opts.seed,
            device: Device::Gpu,
            ..Default::default()
        };
        let mut job = Job::new(scene, name, &job_spec)?;
        let (mut render, _) = renderer_for(&job, scene)?;
        let mut on_pass = |p: &Progress, film: &Film| {
            if on_pass(p, film) {
                Ok(())
            } else {
                Err(JobError::Stopped("stopped".into()))
            }
        };
        let r = render(&mut job, scene, None, &mut on_pass)?;
        Ok(RenderResult { spp: r.spp(), film: r.film, elapsed: r.elapsed, preparation: r.preparation })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The GPU reads the registry's names and parameter specs: aliases resolve, the CPU's
    /// errors for unknown parameters and bad values are the GPU's, an estimator it lacks is
    /// refused by name, and a parameter its kernels do not honour is refused only when set
    /// away from its default.
    #[test]
    fn the_gpu_parses_the_registrys_names_and_parameters() {
        let pair = |k: &str, v: &str| vec![(k.to_string(), v.to_string())];
        assert_eq!(estimator_for("path", &[]).unwrap(), Estimator::Pt);
        assert_eq!(estimator_for("ptracer", &[]).unwrap(), Estimator::Lt);
        let unknown = estimator_for("pt", &pair("rr_depth", "3")).unwrap_err().to_string();
        assert!(unknown.contains("pt has no parameter 'rr_depth'"), "{unknown}");
        let missing = estimator_for("bpt", &[]).unwrap_err().to_string();
        assert_eq!(missing, "the GPU renders pt, ibpt, lt, not bpt");
        assert!(estimator_for("bpt", &pair("heuristic", "nope")).unwrap_err().to_string().contains("heuristic"));
        // A GPU estimator declaring a parameter its kernels do not read (as `vpl` will).
        static SPECS: &[skelight::integrator::params::ParamSpec] = &[skelight::integrator::params::MIS_HEURISTIC];
        let default = Params::new("ibpt", SPECS, &[]).unwrap();
        assert_eq!(kernels_for(&default).unwrap(), Estimator::Ibpt);
        let set = Params::new("ibpt", SPECS, &pair("heuristic", "power")).unwrap();
        let refused = kernels_for(&set).unwrap_err().to_string();
        assert!(refused.contains("ibpt on the GPU does not take heuristic"), "{refused}");
    }

    #[test]
    fn batches_end_on_the_devices_groups_or_fill_the_time_left() {
        // A sample count: up to the next multiple of READBACK_BATCH, whatever the speed.
        assert_eq!(next_batch(0, 0, Duration::ZERO, None), READBACK_BATCH);
        assert_eq!(next_batch(5, 5, Duration::from_secs(9), None), READBACK_BATCH - 5);
        let hour = Some(Duration::from_secs(3600));
        // A time budget: one sample first, then 100 samples in a second make 25 in a quarter,
        // 10 in the 0.1 s left.
        assert_eq!(next_batch(0, 0, Duration::ZERO, hour), 1);
        assert_eq!(next_batch(100, 100, Duration::from_secs(1), hour), 25);
        assert_eq!(next_batch(100, 100, Duration::from_secs(1), Some(Duration::from_millis(100))), 10);
        // Slow renders still take a sample per batch.
        assert_eq!(next_batch(1, 1, Duration::from_secs(60), hour), 1);
    }
}
