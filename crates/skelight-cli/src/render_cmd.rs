//! The `render` command: one render of a scene by one estimator, with whatever pictures the
//! estimator offers of itself (`--debug`: [`Integrator::debug_parts`] and
//! [`Integrator::debug_files`]), and the render job `reference` shares.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use skelight::estimators::registry;
use skelight::imageio::{write_target, Image, ImageOutput};
use skelight::integrator;
use skelight::integrator::Integrator;
use skelight::job::{JobError, JobSpec, Reference, Rendered};
use skelight::paths::mis::Heuristic;
use skelight::scene::Scene;
use skelight::shard::Shard;

use crate::{load_scene, parse_define, parse_duration, parse_heuristic, parse_param, SceneSetup};

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// Scene file (.xml). Omit to render the embedded default scene.
    pub(crate) scene: Option<PathBuf>,
    /// Output image: OUT.exr and a tone-mapped OUT.png beside it (`-o x.png` writes x.exr
    /// too; other extensions are refused). Existing files are replaced; devices, FIFOs and
    /// folders never are.
    #[arg(short, long, default_value = "render.exr")]
    pub(crate) output: PathBuf,
    #[arg(short, long, default_value = "pt", help = crate::estimator_line())]
    pub(crate) integrator: String,
    /// An estimator parameter, NAME=VALUE (repeatable); overrides the scene's
    /// `<integrator>` properties when the scene names the same estimator.
    #[arg(short = 'P', long = "param", value_parser = parse_param)]
    pub(crate) params: Vec<(String, String)>,
    /// Samples per pixel (default: the scene's sampler, or 16 for the default scene).
    #[arg(long, conflicts_with = "time")]
    pub(crate) spp: Option<u32>,
    /// Render for this long instead of a sample count (300, 90s, 5m, 2h).
    #[arg(long, value_parser = parse_duration)]
    pub(crate) time: Option<Duration>,
    /// Random seed; equal seeds give identical images, different seeds independent ones.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    #[command(flatten)]
    pub(crate) setup: SceneSetup,
    /// PNG exposure in stops.
    #[arg(long, default_value = "0", value_parser = crate::parse_finite, allow_negative_numbers = true)]
    pub(crate) exposure: f32,
    /// Scene parameter substitution, as Mitsuba's -D name=value.
    #[arg(short = 'D', value_parser = parse_define)]
    pub(crate) define: Vec<(String, String)>,
    /// No progress bar.
    #[arg(short, long)]
    pub(crate) quiet: bool,
    /// bpt's MIS heuristic: balance or power (as --param heuristic=…).
    #[arg(long, value_parser = parse_heuristic)]
    pub(crate) heuristic: Option<Heuristic>,
    /// Also write what the estimator shows of itself to DIR: the parts its image splits
    /// into, each rendered with the same random numbers so that they add up to the full
    /// render (bpt: each (s, t) strategy, sS_tT.exr and strategies.csv; skelbpt and icbpt:
    /// each resampling distribution, thesis Fig. 106, NAME.exr and distributions.csv), and
    /// pictures of its internals after the render (skelpt: importance_view.png,
    /// node_per_pixel.png and importance.json; skelbpt: nodes_view.png).
    #[arg(long, value_name = "DIR")]
    pub(crate) debug: Option<PathBuf>,
    /// Render only shard K of N (from 0) of the --spp samples: a deterministic slice of the
    /// sample indices, written with its film and a manifest in the EXR header, so that
    /// `skelight merge` of all N shards gives the single render (up to f64 summation order;
    /// with --device gpu, up to the device's f32 sums of 16 samples).
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub(crate) shard: Option<Shard>,
    /// Where to render: cpu, or gpu (pt, ibpt or lt, on the first Vulkan adapter: a GPU, or
    /// lavapipe; needs a build with `--features gpu` and a scene inside the GPU's subset).
    #[arg(long, default_value = "cpu", value_parser = crate::parse_device)]
    pub(crate) device: skelight::job::Device,
}

fn parse_shard(s: &str) -> Result<Shard, String> {
    Shard::parse(s).map_err(|e| e.to_string())
}

/// What a render calls after every pass.
pub(crate) type OnPass<'a> = dyn FnMut(&integrator::Progress, &skelight::film::Film) -> Result<(), JobError> + 'a;

/// A render ready to run: the scene and the library's job (its estimator, when to stop,
/// which shard).
pub(crate) struct Job {
    pub(crate) scene: Scene,
    job: skelight::job::Job,
}

impl std::ops::Deref for Job {
    type Target = skelight::job::Job;
    fn deref(&self) -> &Self::Target {
        &self.job
    }
}

impl std::ops::DerefMut for Job {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.job
    }
}

impl Job {
    /// Loads the scene (the embedded default without a path), applies `setup`, and builds
    /// the job; without `--spp` or `--time`, the scene's sample count (16 for the default
    /// scene).
    pub(crate) fn new(
        scene_path: Option<&Path>,
        define: &[(String, String)],
        setup: &SceneSetup,
        mut spec: JobSpec,
    ) -> Result<Job> {
        let mut scene = load_scene(scene_path, define)?;
        setup.apply(&mut scene)?;
        spec.threads = setup.threads;
        if spec.spp.is_none() && spec.time.is_none() {
            spec.spp = Some(if scene_path.is_some() { scene.settings.spp } else { 16 });
        }
        let label = scene_path
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "default scene (two rooms, door ajar)".into());
        let job = skelight::job::Job::new(&scene, label, &spec)?;
        for w in &job.warnings {
            eprintln!("warning: {w}");
        }
        Ok(Job { scene, job })
    }

    /// The long render to `output` with checkpoints beside it, resuming one found there.
    pub(crate) fn open_reference(&mut self, output: &Path, every: std::time::Duration) -> Result<Reference> {
        Ok(Reference::open(&mut self.job, &self.scene, output, every)?)
    }

    /// Renders with a progress bar.
    pub(crate) fn run(&mut self, quiet: bool) -> Result<Rendered> {
        self.run_with(quiet, |job, scene, on_pass| job.run(scene, None, on_pass))
    }

    /// Runs `render` (the library's job run, or a reference's) with a progress bar fed by the
    /// progress callback it is handed.
    pub(crate) fn run_with(
        &mut self,
        quiet: bool,
        render: impl FnOnce(&mut skelight::job::Job, &Scene, &mut OnPass) -> Result<Rendered, JobError>,
    ) -> Result<Rendered> {
        let s = &self.scene.settings;
        let shard = self.job.shard.map(|k| format!(", shard {k}")).unwrap_or_default();
        eprintln!(
            "{}: {} triangles, {} lights, {}×{}, {}, max depth {}{shard}",
            self.job.label,
            self.scene.triangle_count(),
            self.scene.lights.len(),
            s.width,
            s.height,
            self.job.integrator.describe(),
            s.max_depth
        );
        let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(1000) };
        bar.set_style(
            ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {msg}")
                .expect("valid template")
                .progress_chars("=> "),
        );
        let mut on_pass = |p: &integrator::Progress, _: &skelight::film::Film| {
            let fraction = match (p.spp_target, p.time_budget) {
                (Some(t), None) => p.spp_done as f64 / t as f64,
                (_, Some(b)) => p.elapsed.as_secs_f64() / b.as_secs_f64(),
                _ => 0.0,
            };
            bar.set_position((fraction.min(1.0) * 1000.0) as u64);
            let eta = if fraction > 0.0 { p.elapsed.as_secs_f64() * (1.0 / fraction.min(1.0) - 1.0) } else { 0.0 };
            bar.set_message(format!(
                "{} spp, {:.2} Msamples/s, ETA {:.0} s",
                p.spp_done,
                p.samples_per_second / 1e6,
                eta
            ));
            Ok(())
        };
        let result = render(&mut self.job, &self.scene, &mut on_pass);
        bar.finish_and_clear();
        let result = result?;
        if !quiet {
            print_preparation(&result.preparation);
            print_report(self.job.integrator.as_ref());
        }
        Ok(result)
    }
}

/// Writes OUT.exr (with its sample count) and OUT.png; returns the image.
pub(crate) fn write_outputs(film: &skelight::film::Film, spp: u32, output: &Path, exposure: f32) -> Result<Image> {
    skelight::job::save_film(film, spp, output, exposure).with_context(|| format!("writing {}", output.display()))
}

/// What the estimator's preparation did and how long it took (nothing for estimators
/// without one).
pub(crate) fn print_preparation(p: &integrator::Preparation) {
    if p.stages.is_empty() && p.notes.is_empty() {
        return;
    }
    eprintln!("preparation: {:.3} s (counted in the render's time)", p.elapsed.as_secs_f64());
    for (stage, secs) in &p.stages {
        eprintln!("  {stage:<58} {secs:8.3} s");
    }
    for note in &p.notes {
        eprintln!("  {note}");
    }
}

/// What the estimator reports of its per-iteration work.
pub(crate) fn print_report(integrator: &dyn Integrator) {
    for line in integrator.report() {
        eprintln!("  {line}");
    }
}

/// The image files `output` names, checked before any work is done: each must be a regular
/// file or absent (never a device node, a FIFO or a folder) and none may be one of `inputs`.
pub(crate) fn check_output(output: &Path, inputs: &[&Path]) -> Result<ImageOutput> {
    let out = ImageOutput::of(output)?;
    // `-o /dev/null` names no extension, but the device itself must not be taken for a name.
    write_target(output).map_err(anyhow::Error::msg).with_context(|| format!("output {}", output.display()))?;
    let canonical = |p: &Path| p.canonicalize().ok();
    for file in [&out.exr, &out.png] {
        let target =
            write_target(file).map_err(anyhow::Error::msg).with_context(|| format!("output {}", file.display()))?;
        if let Some(input) = inputs.iter().find(|i| canonical(i).is_some_and(|c| Some(c) == canonical(&target))) {
            bail!("output {} would replace the input {}; choose another output", file.display(), input.display());
        }
    }
    Ok(out)
}

pub(crate) fn summary(r: &Rendered, pixels: usize, img: &Image, output: &Path) {
    let out = ImageOutput::of(output).unwrap_or(ImageOutput { exr: output.into(), png: output.with_extension("png") });
    let secs = r.elapsed.as_secs_f64();
    let m = img.mean();
    eprintln!(
        "done: {} spp in {:.2} s ({:.2} Msamples/s), mean RGB {:.4} {:.4} {:.4}, {} non-finite samples rejected → {} and {}",
        r.spp(),
        secs,
        r.spp() as f64 * pixels as f64 / secs.max(1e-9) / 1e6,
        m.r,
        m.g,
        m.b,
        r.film.rejected,
        out.exr.display(),
        out.png.display()
    );
}

pub(crate) fn render(args: RenderArgs) -> Result<()> {
    check_output(&args.output, &args.scene.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    let mut params = args.params.clone();
    if let Some(h) = args.heuristic {
        params.push(("heuristic".into(), format!("{h:?}").to_lowercase()));
    }
    let device = args.device;
    if device == skelight::job::Device::Gpu {
        crate::gpu_cmd::check_estimator(&args.integrator, &params)?;
    }
    if args.debug.is_some() {
        skelight::debug::check_request(device, args.shard.is_some()).context("--debug")?;
    }
    let spec = JobSpec {
        integrator: args.integrator.clone(),
        params: params.clone(),
        spp: args.spp,
        time: args.time,
        seed: args.seed,
        shard: args.shard,
        device,
        ..JobSpec::default()
    };
    let mut job = Job::new(args.scene.as_deref(), &args.define, &args.setup, spec)?;
    if job.integrator.name() != "bpt" && args.heuristic.is_some() {
        bail!("--heuristic applies to --integrator bpt");
    }
    let mut has_parts = false;
    if let Some(dir) = &args.debug {
        match job.integrator.debug_parts(&job.scene).map_err(|e| anyhow::anyhow!("--debug: {e}"))? {
            Some(parts) => {
                has_parts = true;
                skelight::debug::check_parts(&job)?;
                let full = job.integrator.describe();
                let quiet = args.quiet;
                let run = |estimator| {
                    job.integrator = estimator;
                    job.run(quiet).map_err(|e| JobError::Invalid(format!("{e:#}")))
                };
                skelight::debug::render_parts(dir, parts, args.exposure, run)?;
                let (integrator, _) = registry::create_for_scene(&args.integrator, &job.scene.settings, &params)?;
                debug_assert_eq!(integrator.describe(), full);
                job.integrator = integrator;
            }
            None => std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?,
        }
    }
    // The CPU's estimator, or the GPU's kernels (gpu_cmd::job_renderer).
    let mut render = crate::gpu_cmd::job_renderer(&job)?;
    let r = job.run_with(args.quiet, |job, scene, on_pass| render(job, scene, None, on_pass))?;
    if r.spp() == 0 {
        bail!("the time budget ended before the first sample: nothing was rendered and nothing written; give a longer --time");
    }
    let img = r.save(&args.output, args.exposure).with_context(|| format!("writing {}", args.output.display()))?;
    summary(&r, job.scene.settings.width * job.scene.settings.height, &img, &args.output);
    if let Some(dir) = &args.debug {
        let files = write_debug_files(job.integrator.as_ref(), &job.scene, dir)?;
        for f in &files {
            eprintln!("wrote {}", f.display());
        }
        if files.is_empty() && !has_parts {
            eprintln!("note: {} offers no --debug output for this scene", job.integrator.name());
        }
    }
    Ok(())
}

/// Writes the files `integrator` (prepared for `scene`, and rendered) offers of itself into
/// `dir`; returns their paths.
pub(crate) fn write_debug_files(integrator: &dyn Integrator, scene: &Scene, dir: &Path) -> Result<Vec<PathBuf>> {
    Ok(skelight::debug::write_files(integrator, scene, dir)?)
}
