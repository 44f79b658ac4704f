//! The `render` command: one render of a scene by one estimator, with the pictures that
//! explain it (what guides skelpt, each strategy's share of bpt, each resampling
//! distribution's share of skelbpt), and the render job `reference` shares.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use skelight::imageio::Image;
use skelight::integrator::bpt::{Bpt, Recorded};
use skelight::integrator::mis::Heuristic;
use skelight::integrator::skelbpt::SkeletonBpt;
use skelight::integrator::{self, RenderOptions};
use skelight::scene::Scene;

use crate::{
    load_scene, parse_define, parse_duration, parse_heuristic, parse_param, skeleton_pictures, write_text, SceneSetup,
};

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// Scene file (.xml). Omit to render the embedded default scene.
    scene: Option<PathBuf>,
    /// Output image (.exr); a tone-mapped PNG is written beside it.
    #[arg(short, long, default_value = "render.exr")]
    output: PathBuf,
    /// Estimator: pt, lt, bpt, ibpt, skelpt (`--help` lists them with their parameters).
    #[arg(short, long, default_value = "pt")]
    integrator: String,
    /// An estimator parameter, NAME=VALUE (repeatable); overrides the scene's
    /// `<integrator>` properties when the scene names the same estimator.
    #[arg(short = 'P', long = "param", value_parser = parse_param)]
    params: Vec<(String, String)>,
    /// Samples per pixel (default: the scene's sampler, or 16 for the default scene).
    #[arg(long, conflicts_with = "time")]
    spp: Option<u32>,
    /// Render for this long instead of a sample count (300, 90s, 5m, 2h).
    #[arg(long, value_parser = parse_duration)]
    time: Option<Duration>,
    /// Random seed; equal seeds give identical images, different seeds independent ones.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[command(flatten)]
    setup: SceneSetup,
    /// PNG exposure in stops.
    #[arg(long, default_value_t = 0.0)]
    exposure: f32,
    /// Scene parameter substitution, as Mitsuba's -D name=value.
    #[arg(short = 'D', value_parser = parse_define)]
    define: Vec<(String, String)>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
    /// bpt's MIS heuristic: balance or power (as --param heuristic=…).
    #[arg(long, value_parser = parse_heuristic)]
    heuristic: Option<Heuristic>,
    /// skelpt only: also write pictures of what guides it to DIR: the importance nodes and
    /// directions over the skeleton (importance_view.png), the node each pixel's first hit
    /// maps to (node_per_pixel.png), and importance.json.
    #[arg(long, value_name = "DIR")]
    debug_skeleton: Option<PathBuf>,
    /// bpt only: also write each (s, t) strategy's weighted contribution to DIR/sS_tT.exr
    /// (and .png, and their means to DIR/strategies.csv). Renders once per strategy with the
    /// same random numbers, so the images add up to the full render.
    #[arg(long, value_name = "DIR")]
    debug_strategies: Option<PathBuf>,
    /// skelbpt and icbpt: also write the joins drawn from each resampling distribution (V, U,
    /// C, and the fallback; icbpt's V is Georgiev's full distribution) and the strategies not resampled to DIR/NAME.exr (and .png, their
    /// means to DIR/distributions.csv; thesis Fig. 106), rendered with the same random
    /// numbers so that they add up to the full render, and (skelbpt) the nodes the last pass
    /// built tables for over the skeleton (nodes_view.png).
    #[arg(long, value_name = "DIR")]
    debug_distributions: Option<PathBuf>,
}

/// A render ready to run: the scene, its estimator and when to stop.
pub(crate) struct Job {
    pub(crate) scene: Scene,
    pub(crate) integrator: Box<dyn integrator::Integrator>,
    pub(crate) opts: RenderOptions,
    pub(crate) label: String,
}

impl Job {
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        scene_path: Option<&Path>,
        define: &[(String, String)],
        setup: &SceneSetup,
        name: &str,
        params: &[(String, String)],
        spp: Option<u32>,
        time: Option<Duration>,
        seed: u64,
    ) -> Result<Job> {
        let mut scene = load_scene(scene_path, define)?;
        setup.apply(&mut scene)?;
        let (integrator, warnings) = integrator::registry::create_for_scene(name, &scene.settings, params)?;
        for w in warnings {
            eprintln!("warning: {w}");
        }
        let spp = match (spp, time) {
            (Some(0), _) => bail!("--spp must be at least 1"),
            (Some(s), _) => Some(s),
            (None, Some(_)) => None,
            (None, None) => Some(if scene_path.is_some() { scene.settings.spp } else { 16 }),
        };
        let label = scene_path
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "default scene (two rooms, door ajar)".into());
        if let Some(why) = integrator.limitation(&scene) {
            eprintln!("warning: {why}; the image will miss that light");
        }
        let opts = RenderOptions { spp, time, seed, threads: setup.threads };
        Ok(Job { scene, integrator, opts, label })
    }

    /// Identifies what is rendered, so a checkpoint is resumed only by the same render.
    pub(crate) fn key(&self) -> String {
        let s = &self.scene.settings;
        format!(
            "{}|{}|seed {}|{}x{}|depth {}",
            self.label,
            self.integrator.describe(),
            self.opts.seed,
            s.width,
            s.height,
            s.max_depth
        )
    }

    /// Renders with a progress bar; `on_pass` sees every pass (for checkpoints).
    pub(crate) fn run(
        &mut self,
        resume: Option<(skelight::film::Film, u32)>,
        quiet: bool,
        mut on_pass: impl FnMut(&integrator::Progress, &skelight::film::Film) -> Result<()>,
    ) -> Result<integrator::RenderResult> {
        let s = &self.scene.settings;
        eprintln!(
            "{}: {} triangles, {} lights, {}×{}, {}, max depth {}",
            self.label,
            self.scene.triangle_count(),
            self.scene.lights.len(),
            s.width,
            s.height,
            self.integrator.describe(),
            s.max_depth
        );
        let spp = self.opts.spp;
        let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(spp.map(u64::from).unwrap_or(1000)) };
        bar.set_style(
            ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {msg}")
                .expect("valid template")
                .progress_chars("=> "),
        );
        let mut failure = None;
        let result = integrator::render(&self.scene, self.integrator.as_mut(), &self.opts, resume, |p, film| {
            let fraction = match (p.spp_target, p.time_budget) {
                (Some(t), None) => p.spp_done as f64 / t as f64,
                (_, Some(b)) => p.elapsed.as_secs_f64() / b.as_secs_f64(),
                _ => 0.0,
            };
            bar.set_position((fraction.min(1.0) * bar.length().unwrap_or(1) as f64) as u64);
            let eta = if fraction > 0.0 { p.elapsed.as_secs_f64() * (1.0 / fraction.min(1.0) - 1.0) } else { 0.0 };
            bar.set_message(format!(
                "{} spp, {:.2} Msamples/s, ETA {:.0} s",
                p.spp_done,
                p.samples_per_second / 1e6,
                eta
            ));
            match on_pass(p, film) {
                Ok(()) => true,
                Err(e) => {
                    failure = Some(e);
                    false
                }
            }
        })?;
        bar.finish_and_clear();
        if !quiet {
            print_preparation(&result.preparation);
            print_report(self.integrator.as_ref());
        }
        if let Some(e) = failure {
            return Err(e);
        }
        Ok(result)
    }
}

/// Writes OUT.exr (with its sample count) and OUT.png; returns the image.
pub(crate) fn write_outputs(film: &skelight::film::Film, spp: u32, output: &Path, exposure: f32) -> Result<Image> {
    let img = film.image();
    img.save_exr_with(output, &[("skelight.spp", spp as f64)])
        .with_context(|| format!("writing {}", output.display()))?;
    img.save_png(&output.with_extension("png"), exposure)?;
    Ok(img)
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

pub(crate) fn summary(r: &integrator::RenderResult, pixels: usize, img: &Image, output: &Path) {
    let secs = r.elapsed.as_secs_f64();
    let m = img.mean();
    eprintln!(
        "done: {} spp in {:.2} s ({:.2} Msamples/s), mean RGB {:.4} {:.4} {:.4}, {} non-finite samples rejected → {} and {}",
        r.spp,
        secs,
        r.spp as f64 * pixels as f64 / secs.max(1e-9) / 1e6,
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
    let mut job = Job::new(
        args.scene.as_deref(),
        &args.define,
        &args.setup,
        &args.integrator,
        &params,
        args.spp,
        args.time,
        args.seed,
    )?;
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
    let r = job.run(None, args.quiet, |_, _| Ok(()))?;
    let img = write_outputs(&r.film, r.spp, &args.output, args.exposure)?;
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
        let r = job.run(None, args.quiet, |_, _| Ok(()))?;
        let m = write_outputs(&r.film, r.spp, &dir.join(format!("{}.exr", part.stem)), args.exposure)?.mean();
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
