//! The `render` command: one render of a scene by one estimator, with the pictures that
//! explain it (what guides skelpt, each strategy's share of bpt, each resampling
//! distribution's share of skelbpt), and the render job `reference` shares.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use skelight::imageio::Image;
use skelight::integrator;
use skelight::integrator::bpt::{Bpt, Recorded};
use skelight::integrator::mis::Heuristic;
use skelight::integrator::skelbpt::SkeletonBpt;
use skelight::job::{JobError, JobSpec, Reference, Rendered};
use skelight::scene::Scene;
use skelight::shard::Shard;

use crate::{
    load_scene, parse_define, parse_duration, parse_heuristic, parse_param, skeleton_pictures, write_text, SceneSetup,
};

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// Scene file (.xml). Omit to render the embedded default scene.
    pub(crate) scene: Option<PathBuf>,
    /// Output image (.exr); a tone-mapped PNG is written beside it.
    #[arg(short, long, default_value = "render.exr")]
    pub(crate) output: PathBuf,
    /// Estimator: pt, lt, bpt, ibpt, skelpt (`--help` lists them with their parameters).
    #[arg(short, long, default_value = "pt")]
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
    #[arg(long, default_value_t = 0.0)]
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
    /// skelpt only: also write pictures of what guides it to DIR: the importance nodes and
    /// directions over the skeleton (importance_view.png), the node each pixel's first hit
    /// maps to (node_per_pixel.png), and importance.json.
    #[arg(long, value_name = "DIR")]
    pub(crate) debug_skeleton: Option<PathBuf>,
    /// bpt only: also write each (s, t) strategy's weighted contribution to DIR/sS_tT.exr
    /// (and .png, and their means to DIR/strategies.csv). Renders once per strategy with the
    /// same random numbers, so the images add up to the full render.
    #[arg(long, value_name = "DIR")]
    pub(crate) debug_strategies: Option<PathBuf>,
    /// skelbpt and icbpt: also write the joins drawn from each resampling distribution (V, U,
    /// C, and the fallback; icbpt's V is Georgiev's full distribution) and the strategies not resampled to DIR/NAME.exr (and .png, their
    /// means to DIR/distributions.csv; thesis Fig. 106), rendered with the same random
    /// numbers so that they add up to the full render, and (skelbpt) the nodes the last pass
    /// built tables for over the skeleton (nodes_view.png).
    #[arg(long, value_name = "DIR")]
    pub(crate) debug_distributions: Option<PathBuf>,
    /// Render only shard K of N (from 0) of the --spp samples: a deterministic slice of the
    /// sample indices, written with its film and a manifest in the EXR header, so that
    /// `skelight merge` of all N shards gives the single render (up to f64 summation order;
    /// with --device gpu, up to the device's f32 sums of 16 samples).
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub(crate) shard: Option<Shard>,
    /// Where to render: cpu, or gpu (pt, ibpt or lt, on the first Vulkan adapter: a GPU, or
    /// lavapipe; needs a build with `--features gpu` and a scene inside the GPU's subset).
    #[arg(long, default_value = "cpu", value_parser = ["cpu", "gpu"])]
    pub(crate) device: String,
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
pub(crate) fn print_report(integrator: &dyn integrator::Integrator) {
    for line in integrator.report() {
        eprintln!("  {line}");
    }
}

pub(crate) fn summary(r: &Rendered, pixels: usize, img: &Image, output: &Path) {
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
        output.display(),
        output.with_extension("png").display()
    );
}

pub(crate) fn render(args: RenderArgs) -> Result<()> {
    let mut params = args.params.clone();
    if let Some(h) = args.heuristic {
        params.push(("heuristic".into(), format!("{h:?}").to_lowercase()));
    }
    let device = if args.device == "gpu" { skelight::job::Device::Gpu } else { skelight::job::Device::Cpu };
    if device == skelight::job::Device::Gpu {
        crate::gpu_cmd::check_estimator(&args.integrator, &params)?;
        if args.debug_skeleton.is_some() || args.debug_strategies.is_some() || args.debug_distributions.is_some() {
            bail!("--device gpu writes no --debug-… pictures (they belong to CPU estimators)");
        }
    }
    if args.shard.is_some()
        && (args.debug_skeleton.is_some() || args.debug_strategies.is_some() || args.debug_distributions.is_some())
    {
        bail!("--shard renders a slice of the samples; render the --debug-… pictures without it");
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
    if job.integrator.name() != "bpt" && (args.heuristic.is_some() || args.debug_strategies.is_some()) {
        bail!("--heuristic and --debug-strategies apply to --integrator bpt");
    }
    if let Some(dir) = &args.debug_skeleton {
        if job.integrator.name() != "skelpt" {
            bail!("--debug-skeleton applies to --integrator skelpt");
        }
        let (_, p, _) = integrator::registry::params_for_scene("skelpt", &job.scene.settings, &params)?;
        write_guidance_pictures(&job.scene, &p, dir)?;
    }
    let heuristic = args.heuristic.unwrap_or_default();
    let bpt = |only| -> Box<dyn integrator::Integrator> { Box::new(Bpt { max_depth: None, heuristic, only }) };
    if let Some(dir) = &args.debug_strategies {
        let max_depth = job.scene.settings.max_depth;
        if !(1..=16).contains(&max_depth) {
            bail!("--debug-strategies needs a max depth from 1 to 16 (--max-depth), not {max_depth}");
        }
        // Paths of k segments have k + 1 vertices: strategies s + t = k + 1.
        let parts = (2..=max_depth as usize + 1)
            .flat_map(|vertices| (0..=vertices).map(move |s| (s, vertices - s)))
            .map(|(s, t)| Part {
                stem: format!("s{s}_t{t}"),
                columns: format!("{s},{t},{}", s + t - 2),
                integrator: bpt(Recorded::Strategy(s, t)),
            });
        render_parts(&mut job, "--debug-strategies", dir, ("strategies.csv", "s,t,segments"), parts, &args)?;
        job.integrator = bpt(Recorded::All);
    }
    if let Some(dir) = &args.debug_distributions {
        let name = job.integrator.name();
        if !matches!(name, "skelbpt" | "icbpt") {
            bail!("--debug-distributions applies to --integrator skelbpt or icbpt");
        }
        let mut parts = Vec::new();
        for only in ["V", "U", "C", "fallback", "unresampled"] {
            let mut p = params.clone();
            p.push(("only".into(), only.into()));
            let (integrator, _) = integrator::registry::create_for_scene(name, &job.scene.settings, &p)?;
            parts.push(Part { stem: only.into(), columns: only.into(), integrator });
        }
        render_parts(&mut job, "--debug-distributions", dir, ("distributions.csv", "part"), parts, &args)?;
        let (integrator, _) = integrator::registry::create_for_scene(name, &job.scene.settings, &params)?;
        job.integrator = integrator;
    }
    // The CPU's estimator, or the GPU's kernels (gpu_cmd::job_renderer).
    let mut render = crate::gpu_cmd::job_renderer(&job)?;
    let r = job.run_with(args.quiet, |job, scene, on_pass| render(job, scene, None, on_pass))?;
    let img = r.save(&args.output, args.exposure).with_context(|| format!("writing {}", args.output.display()))?;
    summary(&r, job.scene.settings.width * job.scene.settings.height, &img, &args.output);
    if let Some(dir) = &args.debug_distributions {
        let skelbpt = job.integrator.as_any().and_then(|a| a.downcast_ref::<SkeletonBpt>());
        if let Some((guide, accepted, mapped)) = skelbpt.and_then(|s| s.nodes()) {
            let path = skeleton_pictures::write_node_use(&job.scene, guide, accepted, mapped, dir)?;
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// One part of a render split by contribution: its file stem, its CSV columns and the
/// estimator recording only it.
struct Part {
    stem: String,
    columns: String,
    integrator: Box<dyn integrator::Integrator>,
}

/// Renders `job` once per part, each with the same random numbers (so the images add up to
/// the full render), into DIR/STEM.exr (and .png), and their means into DIR/CSV.
fn render_parts(
    job: &mut Job,
    option: &str,
    dir: &Path,
    (csv_name, columns): (&str, &str),
    parts: impl IntoIterator<Item = Part>,
    args: &RenderArgs,
) -> Result<()> {
    if job.opts.spp.is_none() {
        bail!("{option} needs --spp: every part must see the same samples");
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut csv = format!("{columns},mean_r,mean_g,mean_b\n");
    for part in parts {
        job.integrator = part.integrator;
        let r = job.run(args.quiet)?;
        let m = write_outputs(&r.film, r.spp(), &dir.join(format!("{}.exr", part.stem)), args.exposure)?.mean();
        csv += &format!("{},{},{},{}\n", part.columns, m.r, m.g, m.b);
    }
    write_text(&dir.join(csv_name), &csv)
}

/// Prepares skelpt with `params` for `scene` and writes the pictures of what guides it.
pub(crate) fn write_guidance_pictures(scene: &Scene, params: &integrator::params::Params, dir: &Path) -> Result<()> {
    use integrator::Integrator as _;
    let mut skelpt = integrator::skelpt::SkeletonPathTracer::from_params(params);
    skelpt.prepare(scene)?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let files = skeleton_pictures::write_guidance(scene, &skelpt, dir)?;
    for f in files {
        eprintln!("wrote {}", f.display());
    }
    Ok(())
}
