//! A render job, as `skelight render` and `reference`, the Python package and Dask's workers
//! all run it: a loaded scene, an estimator built from the registry with its parameters,
//! when to stop, and optionally one shard of the render's samples ([`crate::shard`]).

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::checkpoint::Checkpoint;
use crate::film::Film;
use crate::imageio::{Image, ImageError, ImageOutput};
use crate::integrator::params::{ParamError, Params};
use crate::integrator::{self, Integrator, Preparation, Progress, RenderError, RenderOptions};
use crate::scene::load::LoadError;
use crate::scene::Scene;
use crate::shard::{Manifest, Shard, ShardError, ShardOutput};

#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error(transparent)]
    Load(#[from] LoadError),
    #[error(transparent)]
    Params(#[from] ParamError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Shard(#[from] ShardError),
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error("{0}")]
    Invalid(String),
    /// The device the job ran on failed (a GPU: its adapter, kernels or readback).
    #[error("{0}")]
    Device(String),
    /// The caller stopped the render (Ctrl-C, a failed checkpoint write).
    #[error("{0}")]
    Stopped(String),
    #[error("{path}: {reason}")]
    Checkpoint { path: PathBuf, reason: String },
}

impl JobError {
    /// This error prefixed by what it is about (`compare`'s entry), keeping the kinds a
    /// caller tells apart: the device's failure and a stop; the rest is invalid input.
    pub fn about(self, what: &str) -> JobError {
        let message = format!("{what}: {self}");
        match self {
            JobError::Device(_) => JobError::Device(message),
            JobError::Stopped(_) => JobError::Stopped(message),
            _ => JobError::Invalid(message),
        }
    }
}

/// Where a job renders. The CPU runs its estimator here ([`Job::run`]); the GPU's kernels are
/// another crate's (`skelight_gpu::job::run`), with other random numbers and float sums, so
/// the render's key names the device: shards and checkpoints never mix the two.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Device {
    #[default]
    Cpu,
    Gpu,
}

impl Device {
    pub fn name(self) -> &'static str {
        match self {
            Device::Cpu => "cpu",
            Device::Gpu => "gpu",
        }
    }
}

/// `cpu` or `gpu`, as `--device` and Python's `device =` write it.
impl std::str::FromStr for Device {
    type Err = JobError;
    fn from_str(s: &str) -> Result<Device, JobError> {
        match s {
            "cpu" => Ok(Device::Cpu),
            "gpu" => Ok(Device::Gpu),
            other => Err(JobError::Invalid(format!("device '{other}': give 'cpu' or 'gpu'"))),
        }
    }
}

/// What to render with, and for how long.
#[derive(Clone, Debug, Default)]
pub struct JobSpec {
    /// A registry estimator's name.
    pub integrator: String,
    /// Its parameters as NAME=VALUE pairs (over the scene's `<integrator>` properties).
    pub params: Vec<(String, String)>,
    /// Samples per pixel (of the whole render when sharded).
    pub spp: Option<u32>,
    /// Wall-clock budget instead of (or as a cap with) `spp`; not with a shard.
    pub time: Option<Duration>,
    pub seed: u64,
    /// Worker threads; 0 = all cores.
    pub threads: usize,
    /// Render only this slice of the samples.
    pub shard: Option<Shard>,
    pub device: Device,
}

/// A render ready to run on a scene.
pub struct Job {
    pub integrator: Box<dyn Integrator>,
    /// The registry's parameters it was built from (defaults, the scene's `<integrator>`
    /// properties, the job's): what a GPU job's kernels read too.
    pub params: Params,
    pub opts: RenderOptions,
    /// Names the scene in reports and manifests (its path, or the default scene).
    pub label: String,
    pub shard: Option<Shard>,
    pub device: Device,
    /// What the registry and the estimator had to say (ignored scene properties, light the
    /// estimator cannot render).
    pub warnings: Vec<String>,
}

/// A finished job: its film holds exactly `samples`.
pub struct Rendered {
    pub film: Film,
    /// The sample indices rendered (0..spp without a shard).
    pub samples: Range<u32>,
    /// Wall time, preparation included.
    pub elapsed: Duration,
    pub preparation: Preparation,
    /// Set for a shard.
    pub manifest: Option<Manifest>,
}

impl Rendered {
    pub fn spp(&self) -> u32 {
        self.samples.len() as u32
    }

    /// Writes OUT.exr (with its sample count; a shard also with its manifest and film) and
    /// OUT.png, each atomically; returns the image.
    pub fn save(&self, output: &Path, exposure: f32) -> Result<Image, JobError> {
        if let Some(output_shard) = self.shard_output() {
            return Ok(output_shard.save(output, exposure)?);
        }
        save_film(&self.film, self.spp(), output, exposure)
    }

    /// The shard's output (film and manifest), if this job rendered a shard.
    pub fn shard_output(&self) -> Option<ShardOutput> {
        self.manifest.clone().map(|manifest| ShardOutput { film: self.film.clone(), manifest })
    }
}

/// More threads than any machine has: a typo, which would take minutes to spawn.
const MAX_THREADS: usize = 4096;

/// A hash of what the scene renders (geometry, materials, lights, camera, settings), stable
/// across processes and machines (FNV-1a over the values), for render keys.
pub fn fingerprint(scene: &Scene) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h = (h ^ *b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for m in &scene.meshes {
        for p in &m.positions {
            [p.x, p.y, p.z].iter().for_each(|v| eat(&v.to_bits().to_le_bytes()));
        }
        for n in &m.normals {
            [n.x, n.y, n.z].iter().for_each(|v| eat(&v.to_bits().to_le_bytes()));
        }
        m.indices.iter().flatten().for_each(|i| eat(&i.to_le_bytes()));
        eat(format!("{} {:?} {:?}", m.material, m.emission, m.sphere).as_bytes());
    }
    for m in &scene.materials {
        eat(format!("{:?} {:?}", m.bsdf, m.perturbation).as_bytes());
    }
    for l in &scene.lights {
        eat(format!("{l:?}").as_bytes());
    }
    eat(format!("{:?} {:?} {:?}", scene.camera.to_world, scene.camera.tan_half, scene.settings.filter).as_bytes());
    eat(format!("{} {}", scene.camera.aperture_radius, scene.camera.focus_distance).as_bytes());
    h
}

/// Writes a film's image to OUT.exr, with its sample count in the header (for `merge`), and
/// OUT.png, each atomically; returns the image.
pub fn save_film(film: &Film, spp: u32, output: &Path, exposure: f32) -> Result<Image, JobError> {
    let out = ImageOutput::of(output)?;
    let img = film.image();
    img.save_exr_with(&out.exr, &[("skelight.spp", spp as f64)])?;
    img.save_png(&out.png, exposure)?;
    Ok(img)
}

impl Job {
    pub fn new(scene: &Scene, label: impl Into<String>, spec: &JobSpec) -> Result<Job, JobError> {
        let (estimator, params, mut warnings) =
            crate::estimators::registry::params_for_scene(&spec.integrator, &scene.settings, &spec.params)?;
        let integrator = (estimator.create)(&params);
        match (spec.spp, spec.time) {
            (Some(0), _) => return Err(JobError::Invalid("the sample count must be at least 1".into())),
            (None, None) => return Err(JobError::Invalid("give a sample count or a time budget".into())),
            _ => {}
        }
        if let Some(t) = spec.time.filter(|t| t.is_zero()) {
            return Err(JobError::Invalid(format!("a time budget of {t:?} renders nothing")));
        }
        if let Some(shard) = spec.shard {
            let spp = spec.spp.filter(|_| spec.time.is_none()).ok_or_else(|| {
                JobError::Invalid("a shard needs a sample count and no time budget: shards split the samples".into())
            })?;
            shard.samples(spp)?;
            if integrator.learns_across_passes() {
                return Err(JobError::Invalid(format!(
                    "{} learns from its earlier passes, which a shard never sees: its shards would not merge into \
                     the single render. Render it whole, or merge independent renders (different seeds)",
                    integrator.describe()
                )));
            }
        }
        if spec.threads > MAX_THREADS {
            return Err(JobError::Invalid(format!(
                "{} threads: use at most {MAX_THREADS} (0: all cores)",
                spec.threads
            )));
        }
        if let Some(why) = integrator.limitation(scene) {
            warnings.push(format!("{why}; the image will miss that light"));
        }
        let opts = RenderOptions { spp: spec.spp, time: spec.time, seed: spec.seed, threads: spec.threads };
        Ok(Job { integrator, params, opts, label: label.into(), shard: spec.shard, device: spec.device, warnings })
    }

    /// Identifies what is rendered, so that a checkpoint is resumed and shards merged only
    /// with the same render: the scene's content (not its path, which differs between
    /// machines), the estimator with its parameters, the seed, size and depth, and the device
    /// when it is not the CPU.
    pub fn key(&self, scene: &Scene) -> String {
        let s = &scene.settings;
        let mut key = format!(
            "scene {:016x}|{}|seed {}|{}x{}|depth {}",
            fingerprint(scene),
            self.integrator.describe(),
            self.opts.seed,
            s.width,
            s.height,
            s.max_depth
        );
        if self.shard.is_some() {
            key += &format!("|{} spp", self.opts.spp.unwrap_or(0));
        }
        if self.device != Device::Cpu {
            key += &format!("|device {}", self.device.name());
        }
        key
    }

    /// The sample indices this job renders when it has a shard.
    pub fn shard_samples(&self) -> Option<Range<u32>> {
        let spp = self.opts.spp?;
        self.shard.and_then(|s| s.samples(spp).ok())
    }

    /// Renders, from `resume` (a film and its sample count) if given. `on_pass` sees every
    /// pass (progress counted within this job's samples); its error stops the render and is
    /// returned.
    pub fn run(
        &mut self,
        scene: &Scene,
        resume: Option<(Film, u32)>,
        mut on_pass: impl FnMut(&Progress, &Film) -> Result<(), JobError>,
    ) -> Result<Rendered, JobError> {
        if self.device != Device::Cpu {
            return Err(JobError::Invalid("a GPU job runs on the GPU's kernels (skelight_gpu::job::run)".into()));
        }
        let shard_samples = self.shard_samples();
        if shard_samples.is_some() && resume.is_some() {
            return Err(JobError::Invalid("a shard cannot resume another render".into()));
        }
        let mut opts = self.opts.clone();
        // A shard is a render resumed at its first sample from an empty film, stopping after
        // its last: the render loop's passes stay aligned to the single render's.
        let resume = match &shard_samples {
            Some(r) => {
                opts.spp = Some(r.end);
                Some((Film::new(scene.settings.width, scene.settings.height, scene.settings.filter), r.start))
            }
            None => resume,
        };
        let first = resume.as_ref().map_or(0, |r| r.1);
        let origin = shard_samples.as_ref().map_or(0, |r| r.start);
        let pixels = (scene.settings.width * scene.settings.height) as f64;
        let mut failure = None;
        let r = integrator::render(scene, self.integrator.as_mut(), &opts, resume, |p, film| {
            let done = p.spp_done - first;
            let own = Progress {
                spp_done: p.spp_done - origin,
                spp_target: p.spp_target.map(|t| t - origin),
                samples_per_second: done as f64 * pixels / p.elapsed.as_secs_f64().max(1e-9),
                ..*p
            };
            match on_pass(&own, film) {
                Ok(()) => true,
                Err(e) => {
                    failure = Some(e);
                    false
                }
            }
        })?;
        if let Some(e) = failure {
            return Err(e);
        }
        let manifest = match (self.shard, shard_samples) {
            (Some(shard), Some(samples)) => {
                if r.spp != samples.end {
                    return Err(JobError::Stopped(format!("shard {shard} stopped at sample {} of {samples:?}", r.spp)));
                }
                Some(Manifest { render: self.key(scene), shard, samples })
            }
            _ => None,
        };
        Ok(Rendered { film: r.film, samples: origin..r.spp, elapsed: r.elapsed, preparation: r.preparation, manifest })
    }
}

/// A job's renderer: the job, the scene, the film and sample count to resume from, and the
/// callback after every pass (its error stops the render).
pub type Render = dyn FnMut(
    &mut Job,
    &Scene,
    Option<(Film, u32)>,
    &mut dyn FnMut(&Progress, &Film) -> Result<(), JobError>,
) -> Result<Rendered, JobError>;

/// The CPU's renderer: the job's own estimator ([`Job::run`]); the device switch
/// (`skelight_gpu::job::renderer_for`) returns it for a CPU job.
pub fn cpu_renderer() -> Box<Render> {
    Box::new(|job, scene, resume, on_pass| job.run(scene, resume, on_pass))
}

/// A long render to OUT.exr that checkpoints to OUT.exr.ckpt and, started again with the same
/// job, resumes from it: on the CPU the result is bit-identical to an uninterrupted render
/// (random numbers depend on seed, pixel and sample index only; passes are aligned to sample
/// 0); on the GPU ([`Reference::run_on`]) up to the device's float sums (see README).
pub struct Reference {
    pub output: PathBuf,
    pub checkpoint: PathBuf,
    /// How often to write the checkpoint (and the image so far).
    pub every: Duration,
    /// The checkpoint found: its film, samples per pixel and the time already spent.
    resume: Option<(Film, u32, Duration)>,
    /// The checkpoint already holds the job's samples or time: nothing is left to render.
    finished: bool,
}

impl Reference {
    /// Opens the reference of `job` at `output`, reading its checkpoint if there is one (and
    /// refusing one that belongs to another render). A time budget counts the time already
    /// spent.
    pub fn open(job: &mut Job, scene: &Scene, output: &Path, every: Duration) -> Result<Reference, JobError> {
        if job.shard.is_some() {
            return Err(JobError::Invalid("a reference renders all the samples; render shards with --shard".into()));
        }
        let output = &ImageOutput::of(output)?.exr;
        let checkpoint = PathBuf::from(format!("{}.ckpt", output.display()));
        let mut resume = None;
        let mut finished = false;
        if checkpoint.exists() {
            let c = Checkpoint::load(&checkpoint)
                .map_err(|reason| JobError::Checkpoint { path: checkpoint.clone(), reason })?;
            let key = job.key(scene);
            if c.key != key {
                return Err(JobError::Checkpoint {
                    path: checkpoint,
                    reason: format!("belongs to another render ({}); remove it or choose another output", c.key),
                });
            }
            finished = job.opts.time.is_some_and(|t| c.elapsed >= t) || job.opts.spp.is_some_and(|n| c.spp >= n);
            if let Some(t) = job.opts.time {
                job.opts.time = Some(t.saturating_sub(c.elapsed).max(Duration::from_millis(1)));
            }
            resume = Some((c.film, c.spp, c.elapsed));
        }
        Ok(Reference { output: output.to_path_buf(), checkpoint, every, resume, finished })
    }

    /// Whether the checkpoint already holds the job's samples or time (a rerun of a finished
    /// reference): [`Reference::run`] then renders nothing and writes the image it holds.
    pub fn finished(&self) -> bool {
        self.finished
    }

    /// Samples per pixel and seconds the checkpoint holds, if one was found.
    pub fn resumed(&self) -> Option<(u32, Duration)> {
        self.resume.as_ref().map(|r| (r.1, r.2))
    }

    /// Renders, writing the checkpoint and the image every `every` and at the end (the
    /// checkpoint is kept, so that a larger sample count or time extends the render). The
    /// result's samples and time are the whole reference's, checkpointed runs included.
    pub fn run(
        self,
        job: &mut Job,
        scene: &Scene,
        on_pass: impl FnMut(&Progress, &Film) -> Result<(), JobError>,
    ) -> Result<Rendered, JobError> {
        self.run_on(job, scene, on_pass, &mut |job, scene, resume, on_pass| job.run(scene, resume, on_pass))
    }

    /// [`Reference::run`] with the job rendered by `render` (the job, the scene, the film to
    /// resume and the callback after every pass): the GPU's (`skelight_gpu::job::run`).
    pub fn run_on(
        mut self,
        job: &mut Job,
        scene: &Scene,
        mut on_pass: impl FnMut(&Progress, &Film) -> Result<(), JobError>,
        render: &mut Render,
    ) -> Result<Rendered, JobError> {
        let (mut resume, before) = match self.resume.take() {
            Some((film, spp, elapsed)) => (Some((film, spp)), elapsed),
            None => (None, Duration::ZERO),
        };
        let key = job.key(scene);
        let save = |film: &Film, spp: u32, elapsed: Duration| -> Result<(), JobError> {
            Checkpoint { key: key.clone(), spp, elapsed: before + elapsed, film: film.clone() }
                .save(&self.checkpoint)
                .map_err(|reason| JobError::Checkpoint { path: self.checkpoint.clone(), reason })?;
            save_film(film, spp, &self.output, 0.0).map(|_| ())
        };
        // Rendering even one more pass would change a finished reference on every rerun; its
        // checkpoint stays as it is, its image is written again.
        if let Some((film, spp)) = resume.take_if(|_| self.finished) {
            save_film(&film, spp, &self.output, 0.0)?;
            let preparation = Preparation::default();
            return Ok(Rendered { film, samples: 0..spp, elapsed: before, preparation, manifest: None });
        }
        let mut last = Instant::now();
        let r = render(job, scene, resume, &mut |p, film| {
            on_pass(p, film)?;
            if last.elapsed() >= self.every {
                save(film, p.spp_done, p.elapsed)?;
                last = Instant::now();
            }
            Ok(())
        })?;
        save(&r.film, r.spp(), r.elapsed)?;
        // As the checkpoint and the samples: the whole reference's, not this run's.
        Ok(Rendered { elapsed: before + r.elapsed, ..r })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A GPU job's key names the device (its shards and checkpoints never mix with the
    /// CPU's), and the CPU does not run it in its place.
    #[test]
    fn a_gpu_job_is_keyed_by_its_device_and_not_run_here() {
        let mut scene = crate::scene::builtin::two_rooms();
        scene.set_resolution(8, 8);
        let job = |device| {
            let spec = JobSpec { integrator: "pt".into(), spp: Some(1), device, ..Default::default() };
            Job::new(&scene, "two rooms", &spec).unwrap()
        };
        let (cpu, mut gpu) = (job(Device::Cpu), job(Device::Gpu));
        assert_eq!(gpu.key(&scene), format!("{}|device gpu", cpu.key(&scene)));
        assert!(matches!(gpu.run(&scene, None, |_, _| Ok(())), Err(JobError::Invalid(_))));
    }

    /// A rerun of a finished reference (its checkpoint holds the samples or the time asked
    /// for) renders nothing: the same film, not one more pass each time.
    #[test]
    fn a_finished_reference_renders_nothing_more() {
        let mut scene = crate::scene::builtin::two_rooms();
        scene.set_resolution(8, 8);
        let dir = std::env::temp_dir().join(format!("skelight-finished-reference-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let output = dir.join("ref.exr");
        let time = JobSpec { integrator: "pt".into(), time: Some(Duration::from_millis(100)), ..Default::default() };
        let spp = |n| JobSpec { integrator: "pt".into(), spp: Some(n), ..Default::default() };
        let both = JobSpec { time: Some(Duration::from_secs(60)), ..spp(4) };
        // (first run, rerun, whether the rerun finds it finished)
        let cases = [
            (time.clone(), time.clone(), true),
            (spp(4), spp(4), true),
            (spp(6), spp(4), true),
            (both.clone(), both, true),
            (spp(4), spp(6), false),
        ];
        for (first, again, finished) in cases {
            std::fs::remove_file(dir.join("ref.exr.ckpt")).ok();
            let mut job = Job::new(&scene, "two rooms", &first).unwrap();
            let done =
                Reference::open(&mut job, &scene, &output, Duration::MAX).unwrap().run(&mut job, &scene, |_, _| Ok(()));
            let done = done.unwrap();
            std::fs::remove_file(&output).unwrap();
            let mut job = Job::new(&scene, "two rooms", &again).unwrap();
            let reference = Reference::open(&mut job, &scene, &output, Duration::MAX).unwrap();
            assert_eq!(reference.finished(), finished, "{first:?} then {again:?}");
            // What the renderer is handed: the checkpoint's samples to resume from.
            let handed = std::rc::Rc::new(std::cell::Cell::new(None));
            let (mut passes, seen) = (0, handed.clone());
            let rerun = reference.run_on(
                &mut job,
                &scene,
                |_, _| {
                    passes += 1;
                    Ok(())
                },
                &mut move |job, scene, resume, on_pass| {
                    seen.set(Some(resume.as_ref().map(|r| r.1)));
                    job.run(scene, resume, on_pass)
                },
            );
            let rerun = rerun.unwrap();
            // The result's time is the whole reference's, and its image is written again.
            assert!(rerun.elapsed + Duration::from_millis(1) >= done.elapsed && output.exists());
            if finished {
                assert_eq!(
                    (passes, handed.get(), rerun.spp()),
                    (0, None, done.spp()),
                    "a finished reference rendered more"
                );
                assert!(rerun.film.image().pixels == done.film.image().pixels);
            } else {
                assert_eq!((handed.get(), rerun.spp()), (Some(Some(4)), 6), "not resumed from the checkpoint");
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
