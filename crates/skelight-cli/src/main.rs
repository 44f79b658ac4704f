//! `skelight`: render scenes, compare images, measure throughput.

mod bench;
mod compare;
mod gpu_cmd;
mod render_cmd;
mod skeleton;

use render_cmd::{
    check_output, print_preparation, print_report, summary, write_debug_files, write_outputs, Job, RenderArgs,
};
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use skelight::estimators::registry;
use skelight::eval;
use skelight::guided::analysis::AnalysisBounds;
use skelight::imageio::Image;
use skelight::integrator::{self, RenderOptions};
use skelight::job::JobSpec;
use skelight::paths::mis::Heuristic;
use skelight::scene::{self, Scene};
use skelight_shape::pipeline::{AnalysisSettings, Resolution};
use skelight_shape::thinning::EdgeConstraint;

#[derive(Parser)]
#[command(name = "skelight", version, about = "Physically based renderer guided by the shape of empty space")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (.xml, .gltf/.glb, .toml, .obj, .ply); without SCENE, the embedded
    /// two-room default scene.
    Render(RenderArgs),
    /// A long render that checkpoints and resumes after being killed.
    Reference(ReferenceArgs),
    /// Error metrics of an image against a reference (MAE, RMSE, relMSE, NRMSE).
    Diff {
        image: PathBuf,
        reference: PathBuf,
        /// Also write a false-colour relative-error image (black 0 → red ≥ --max-error).
        #[arg(long)]
        error_image: Option<PathBuf>,
        /// The relative error shown red (positive).
        #[arg(long, default_value = "0.5", value_parser = parse_positive)]
        max_error: f32,
    },
    /// Equal-time comparison of estimators against a reference, with a report.
    Compare(CompareArgs),
    /// Analyse the empty space: the curvilinear skeleton, its filtered graph, opening-forest
    /// labels and portals, written to DIR (JSON, PLY line sets, a timing report), and
    /// pictures: the skeleton over a render, node mapping and labels in false colours.
    Skeleton {
        /// Scene file. Omit for the embedded default scene.
        scene: Option<PathBuf>,
        /// Voxels on the longest side of the scene's box (grown by 10 %), or the grid's exact
        /// dimensions W,H,D (cubic voxels, the box centred).
        #[arg(long, default_value = "128", value_parser = parse_grid_resolution)]
        resolution: Resolution,
        /// Alg. 3's edge constraint: thesis (lifespan > DC + birth − D) or released-code
        /// (lifespan > DC + birth).
        #[arg(long, default_value = "thesis", value_parser = parse_constraint)]
        constraint: EdgeConstraint,
        #[arg(short, long, default_value = "skeleton")]
        output: PathBuf,
        /// Scene parameter substitution, as Mitsuba's -D name=value.
        #[arg(short = 'D', value_parser = parse_define)]
        define: Vec<(String, String)>,
        /// The box analysed: occupied (the default, as the guided estimators' `bounds`: the
        /// space around the camera and the lights, found by rays, or the scene's box where
        /// that is most of it; for a building inside a huge ground plane or sky, such as
        /// classroom), scene (the scene's bounds grown by 10 %), or XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX
        /// in world units.
        #[arg(long, default_value = "occupied", value_parser = parse_bounds, allow_hyphen_values = true)]
        bounds: AnalysisBounds,
        /// Analyse only the empty space enclosed by the scene (drop the air joined to the
        /// grid's border, such as the shell around a closed building).
        #[arg(long)]
        enclosed_only: bool,
        /// Scene elements the skeleton must reach (seed 001 §3.2), comma-separated: lights
        /// (area lights' centroids on their emitting side, point and spot lights), camera.
        #[arg(long, value_enum, value_delimiter = ',')]
        anchors: Vec<skeleton::AnchorKind>,
        /// Analyse every component of the empty space. By default only those holding the
        /// camera or a light are (the space light can reach), so the insides of closed
        /// solids — pillars, slabs, closed furniture — get no skeleton; a camera or light
        /// with no empty voxel within 4 voxels keeps everything, with a warning.
        #[arg(long)]
        keep_all_space: bool,
        /// Longest side, in pixels, of the pictures (the scene's camera, same aspect).
        #[arg(long, default_value_t = 640)]
        picture_size: usize,
        /// Write no pictures (no render).
        #[arg(long)]
        no_pictures: bool,
        #[arg(short, long)]
        quiet: bool,
    },
    /// Combine independent renders of one scene (weighted by their sample counts).
    Merge {
        parts: Vec<PathBuf>,
        /// Output image, named as render's -o (never one of the parts).
        #[arg(short, long)]
        output: PathBuf,
        /// Weight every part equally (for images without a recorded sample count).
        #[arg(long)]
        equal_weights: bool,
    },
    /// Measure throughput: ray tracing per backend, or an estimator's samples per second.
    Bench {
        #[command(subcommand)]
        what: BenchKind,
    },
    /// Print what a scene contains and any loader warnings.
    Info {
        scene: PathBuf,
        #[arg(short = 'D', value_parser = parse_define)]
        define: Vec<(String, String)>,
    },
}

#[derive(clap::Args)]
struct CompareArgs {
    /// Scene file. Omit for the embedded default scene.
    scene: Option<PathBuf>,
    /// Converged reference image (EXR) of the same scene and resolution.
    #[arg(long)]
    reference: PathBuf,
    /// Estimators, comma-separated, each with its parameters as NAME:PARAM=VALUE:… (e.g.
    /// pt,skelpt:strength=16); speed-ups are relative to the first. gpu:pt, gpu:ibpt and
    /// gpu:lt run on the GPU (a build with `--features gpu`), timed from when its kernels are
    /// ready.
    #[arg(long, value_delimiter = ',', default_value = "pt")]
    integrators: Vec<String>,
    /// Wall time per estimator (300, 90s, 5m, 2h).
    #[arg(long, value_parser = parse_duration, default_value = "60")]
    time: Duration,
    /// Measure the error at most this often (default: after every pass).
    #[arg(long, value_parser = parse_duration)]
    every: Option<Duration>,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[command(flatten)]
    setup: SceneSetup,
    #[arg(short = 'D', value_parser = parse_define)]
    define: Vec<(String, String)>,
    /// Output folder for the report.
    #[arg(short, long)]
    output: PathBuf,
    #[arg(short, long)]
    quiet: bool,
}

#[derive(clap::Args)]
struct ReferenceArgs {
    /// Scene file. Omit for the embedded default scene.
    scene: Option<PathBuf>,
    /// Output image, named as render's -o; its checkpoint is OUT.exr.ckpt.
    #[arg(short, long)]
    output: PathBuf,
    #[arg(short, long, default_value = "pt")]
    integrator: String,
    /// An estimator parameter, NAME=VALUE (repeatable).
    #[arg(short = 'P', long = "param", value_parser = parse_param)]
    params: Vec<(String, String)>,
    /// Total wall time across interruptions (300, 90s, 5m, 2h).
    #[arg(long, value_parser = parse_duration)]
    time: Option<Duration>,
    /// Samples per pixel to reach (with --time: whichever comes first).
    #[arg(long)]
    spp: Option<u32>,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// How often to write the checkpoint (and the image so far).
    #[arg(long, value_parser = parse_duration, default_value = "5m")]
    checkpoint_every: Duration,
    /// Where to render: cpu, or gpu (pt, ibpt or lt; a build with `--features gpu`). A
    /// checkpoint resumes only on the device that wrote it.
    #[arg(long, default_value = "cpu", value_parser = crate::parse_device)]
    device: skelight::job::Device,
    #[command(flatten)]
    setup: SceneSetup,
    #[arg(short = 'D', value_parser = parse_define)]
    define: Vec<(String, String)>,
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Subcommand)]
enum BenchKind {
    /// BVH build time and incoherent closest-hit/any-hit Mrays/s, every compiled-in backend.
    Rays {
        scenes: Vec<PathBuf>,
        /// Rays per measurement (origins on surfaces, uniform directions).
        #[arg(long, default_value_t = 2_000_000)]
        rays: usize,
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Measurement rounds, each timing every backend in turn; the best of each is shown.
        #[arg(long, default_value_t = 5)]
        rounds: usize,
        /// cpu (the CPU's accelerators), or gpu (the GPU kernels' traversal alone).
        #[arg(long, default_value = "cpu", value_parser = crate::parse_device)]
        device: skelight::job::Device,
    },
    /// Time per stage and peak memory of the empty-space analysis (best of --runs).
    Skeleton {
        scene: PathBuf,
        /// As `skelight skeleton --resolution`: N or W,H,D.
        #[arg(long, default_value = "128", value_parser = parse_grid_resolution)]
        resolution: Resolution,
        /// As `skelight skeleton --bounds`, but the scene's box by default (the figures of
        /// docs/benchmarks.md).
        #[arg(long, default_value = "scene", value_parser = parse_bounds, allow_hyphen_values = true)]
        bounds: AnalysisBounds,
        #[arg(long)]
        enclosed_only: bool,
        /// As `skelight skeleton --keep-all-space` (by default, as there, only the space
        /// holding the camera or a light is analysed).
        #[arg(long)]
        keep_all_space: bool,
        #[arg(long, default_value_t = 3)]
        runs: usize,
    },
    /// Samples per second of an estimator on a scene.
    Render {
        scene: PathBuf,
        /// An estimator, with its parameters as NAME:PARAM=VALUE:…
        #[arg(short, long, default_value = "pt")]
        integrator: String,
        #[arg(long, default_value_t = 16)]
        spp: u32,
        /// cpu, or gpu (pt, ibpt or lt; reports rays/s and device memory too).
        #[arg(long, default_value = "cpu", value_parser = crate::parse_device)]
        device: skelight::job::Device,
        #[command(flatten)]
        setup: SceneSetup,
    },
}

/// How to run a loaded scene, shared by `render` and `bench render`.
#[derive(clap::Args)]
struct SceneSetup {
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Override image width and height (keeps the field of view).
    #[arg(long, num_args = 2, value_names = ["W", "H"])]
    resolution: Option<Vec<usize>>,
    /// Maximum path depth (Mitsuba's max_depth; -1 = unbounded). Overrides the scene.
    #[arg(long, allow_negative_numbers = true)]
    max_depth: Option<i32>,
    /// Ray-tracing backend: bvh (built in) or embree (when compiled with --features embree).
    #[arg(long, default_value = "bvh")]
    backend: String,
}

impl SceneSetup {
    fn apply(&self, scene: &mut Scene) -> Result<()> {
        if let Some(r) = &self.resolution {
            skelight::scene::check_resolution(r[0] as i64, r[1] as i64).map_err(anyhow::Error::msg)?;
            scene.set_resolution(r[0], r[1]);
        }
        if let Some(d) = self.max_depth {
            if d < -1 {
                bail!("--max-depth must be -1 (unbounded) or at least 0");
            }
            scene.settings.max_depth = d;
        }
        use_backend(scene, &self.backend)
    }
}

fn parse_param(s: &str) -> Result<(String, String), String> {
    integrator::params::parse_assignment(s).map_err(|e| e.to_string())
}

fn parse_constraint(s: &str) -> Result<EdgeConstraint, String> {
    match s {
        "thesis" => Ok(EdgeConstraint::Thesis),
        "released-code" => Ok(EdgeConstraint::ReleasedCode),
        _ => Err(format!("unknown constraint '{s}'; use thesis or released-code")),
    }
}

fn parse_grid_resolution(s: &str) -> Result<Resolution, String> {
    let v: Vec<usize> =
        s.split(',').map(|t| t.trim().parse::<usize>()).collect::<Result<_, _>>().map_err(|e| e.to_string())?;
    match v[..] {
        [n] => Ok(Resolution::Longest(n)),
        [w, h, d] => Ok(Resolution::Dims([w, h, d])),
        _ => Err("expected N (voxels on the longest side) or W,H,D".into()),
    }
}

fn parse_bounds(s: &str) -> Result<AnalysisBounds, String> {
    AnalysisBounds::parse(s)
}

fn parse_heuristic(s: &str) -> Result<Heuristic, String> {
    Heuristic::parse(s).ok_or_else(|| format!("unknown heuristic '{s}'; use balance or power"))
}

fn parse_define(s: &str) -> Result<(String, String), String> {
    let (k, v) = s.split_once('=').ok_or_else(|| format!("expected name=value, got '{s}'"))?;
    if k.is_empty() {
        return Err("empty parameter name".into());
    }
    Ok((k.to_string(), v.to_string()))
}

fn load_scene(path: Option<&Path>, defines: &[(String, String)]) -> Result<Scene> {
    let scene = match path {
        Some(p) => scene::load::load(p, defines)?,
        None => scene::builtin::two_rooms(),
    };
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// Switches the scene to the named ray-tracing backend.
fn use_backend(scene: &mut Scene, name: &str) -> Result<()> {
    let (_, build) = bench::backends().into_iter().find(|(n, _)| *n == name).with_context(|| {
        format!(
            "unknown or not compiled-in backend '{name}'; available: {}",
            bench::backends().iter().map(|b| b.0).collect::<Vec<_>>().join(", ")
        )
    })?;
    if name != "bvh" {
        let tris = scene.build_triangles();
        scene.set_accelerator(build(&tris));
    }
    Ok(())
}

fn bench(what: BenchKind) -> Result<()> {
    match what {
        BenchKind::Skeleton { scene, resolution, bounds, enclosed_only, keep_all_space, runs } => {
            let scene = load_scene(Some(&scene), &[])?;
            let settings = AnalysisSettings {
                resolution,
                region: bounds.region(&scene),
                enclosed_only,
                sources: skeleton::sources(&scene),
                keep_all_space,
                ..AnalysisSettings::default()
            };
            bench::skeleton(&scene, &settings, runs.max(1))
        }
        BenchKind::Rays { scenes, rays, threads, rounds, device } => {
            rayon::ThreadPoolBuilder::new().num_threads(threads).build_global().ok();
            if device == skelight::job::Device::Gpu {
                return gpu_cmd::bench_rays(&scenes, rays, rounds);
            }
            println!(
                "{:<28} {:>9} {:>8} {:>10} {:>13} {:>11} {:>7}",
                "scene", "triangles", "backend", "build ms", "closest Mr/s", "any Mr/s", "hit %"
            );
            for path in scenes {
                let scene = load_scene(Some(&path), &[])?;
                let tris = scene.build_triangles();
                let rs = bench::incoherent_rays(&tris, rays, 1);
                let mut first: Option<(f64, f64, f64)> = None;
                let backends = bench::backends();
                for ((name, _), r) in backends.iter().zip(bench::measure(&tris, &rs, &backends, rounds)) {
                    let label = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
                    let ratio = first
                        .map(|(b, c, a)| {
                            format!(
                                "  (vs bvh: build ×{:.2}, closest ×{:.2}, any ×{:.2})",
                                r.build.as_secs_f64() / b,
                                r.closest_mrays / c,
                                r.any_mrays / a
                            )
                        })
                        .unwrap_or_default();
                    println!(
                        "{:<28} {:>9} {:>8} {:>10.1} {:>13.2} {:>11.2} {:>7.2}{ratio}",
                        label,
                        tris.len(),
                        name,
                        r.build.as_secs_f64() * 1e3,
                        r.closest_mrays,
                        r.any_mrays,
                        100.0 * r.hits as f64 / rs.len() as f64
                    );
                    if let Some(structure) = &r.structure {
                        println!("{:<28} {structure}", "");
                    }
                    first.get_or_insert((r.build.as_secs_f64(), r.closest_mrays, r.any_mrays));
                }
            }
            Ok(())
        }
        BenchKind::Render { scene: path, integrator: name, spp, device, setup } => {
            let mut scene = load_scene(Some(&path), &[])?;
            setup.apply(&mut scene)?;
            if device == skelight::job::Device::Gpu {
                return gpu_cmd::bench(&path, &scene, &name, spp);
            }
            let (estimator, params) = registry::parse_spec(&name)?;
            let mut integrator = registry::create(&estimator, &params)?;
            let opts = RenderOptions { spp: Some(spp), time: None, seed: 1, threads: setup.threads };
            let r = integrator::render(&scene, integrator.as_mut(), &opts, None, |_, _| true)?;
            print_preparation(&r.preparation);
            print_report(integrator.as_ref());
            let samples = r.spp as f64 * (scene.settings.width * scene.settings.height) as f64;
            println!(
                "{} {}: {}×{} {} spp, max depth {}, {:.3} s, {:.3} Msamples/s, mean {:?}",
                path.display(),
                name,
                scene.settings.width,
                scene.settings.height,
                r.spp,
                scene.settings.max_depth,
                r.elapsed.as_secs_f64(),
                samples / r.elapsed.as_secs_f64() / 1e6,
                r.film.image().mean()
            );
            Ok(())
        }
    }
}

/// `--device`: cpu or gpu (skelight::job::Device, as Python's `device =` parses it too).
pub(crate) fn parse_device(s: &str) -> Result<skelight::job::Device, String> {
    s.parse().map_err(|e: skelight::job::JobError| e.to_string())
}

/// Durations as `300` (seconds), `90s`, `5m`, `2h` or `1.5h`.
/// The longest time budget: three years, past any render and within what a `Duration` holds.
const MAX_SECONDS: f64 = 1e8;

fn parse_duration(s: &str) -> Result<Duration, String> {
    let t = s.trim();
    // The unit is a trailing word, so that an exponent (1e3) stays part of the number.
    let split = t.trim_end_matches(|c: char| c.is_ascii_alphabetic()).len();
    let (num, unit) = t.split_at(split);
    let v: f64 = num.trim().parse().map_err(|_| format!("'{s}' is not a duration (e.g. 300, 90s, 5m, 2h)"))?;
    let secs = match unit {
        "" | "s" => v,
        "m" | "min" => v * 60.0,
        "h" => v * 3600.0,
        other => return Err(format!("unknown time unit '{other}' in '{s}' (s, m or h)")),
    };
    if !(secs > 0.0 && secs <= MAX_SECONDS) {
        return Err(format!("duration '{s}' must be above 0 and at most {MAX_SECONDS:e} s"));
    }
    Ok(Duration::from_secs_f64(secs))
}

/// A finite number (an exposure in stops).
pub(crate) fn parse_finite(s: &str) -> Result<f32, String> {
    s.trim().parse::<f32>().ok().filter(|v| v.is_finite()).ok_or_else(|| format!("'{s}' is not a finite number"))
}

/// A finite positive number.
fn parse_positive(s: &str) -> Result<f32, String> {
    Some(parse_finite(s)?).filter(|v| *v > 0.0).ok_or_else(|| format!("'{s}' must be above 0"))
}

/// Writes a text file through a temporary name, with an error naming the file.
pub(crate) fn write_text(path: &Path, text: &str) -> Result<()> {
    skelight::imageio::write_file_atomically(path, text.as_bytes())
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("writing {}", path.display()))
}

/// Long render that checkpoints to OUT.exr.ckpt and resumes from it after an interruption.
fn reference(args: ReferenceArgs) -> Result<()> {
    let device = args.device;
    if device == skelight::job::Device::Gpu {
        gpu_cmd::check_estimator(&args.integrator, &args.params)?;
    }
    let spec = JobSpec {
        integrator: args.integrator.clone(),
        params: args.params.clone(),
        spp: args.spp,
        time: args.time,
        seed: args.seed,
        device,
        ..JobSpec::default()
    };
    check_output(&args.output, &args.scene.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    let mut job = Job::new(args.scene.as_deref(), &args.define, &args.setup, spec)?;
    let reference = job.open_reference(&args.output, args.checkpoint_every)?;
    // A finished reference renders nothing: no device is set up for it.
    let mut render: Box<skelight::job::Render> = if reference.finished() {
        Box::new(|_, _, _, _| Err(skelight::job::JobError::Invalid("a finished reference renders nothing".into())))
    } else {
        gpu_cmd::job_renderer(&job)?
    };
    let checkpoint = reference.checkpoint.clone();
    if let Some((spp, elapsed)) = reference.resumed() {
        eprintln!("resuming from {} ({spp} spp, {:.1} s done)", checkpoint.display(), elapsed.as_secs_f64());
        if reference.finished() {
            eprintln!("the checkpoint already holds the samples or time asked for: nothing to render");
        }
    }
    let r = job.run_with(args.quiet, |job, scene, on_pass| reference.run_on(job, scene, on_pass, &mut render))?;
    let img = r.film.image();
    summary(&r, job.scene.settings.width * job.scene.settings.height, &img, &args.output);
    eprintln!("checkpoint kept at {} (rerun with a larger --spp or --time to extend)", checkpoint.display());
    Ok(())
}

fn compare_cmd(a: CompareArgs) -> Result<()> {
    // Checked before the timed runs, not after them.
    if a.output.exists() && !a.output.is_dir() {
        bail!("output {} exists and is not a folder; the report is a folder of files", a.output.display());
    }
    let reference = Image::load(&a.reference)?;
    refuse_non_finite(&a.reference, &reference, "compare against")?;
    let mut scene = load_scene(a.scene.as_deref(), &a.define)?;
    a.setup.apply(&mut scene)?;
    if a.setup.resolution.is_none()
        && (scene.settings.width, scene.settings.height) != (reference.width, reference.height)
    {
        eprintln!("rendering at the reference's resolution, {}×{}", reference.width, reference.height);
        scene.set_resolution(reference.width, reference.height);
    }
    if (scene.settings.width, scene.settings.height) != (reference.width, reference.height) {
        bail!("--resolution differs from the reference's {}×{}", reference.width, reference.height);
    }
    let opts = RenderOptions { spp: None, time: Some(a.time), seed: a.seed, threads: a.setup.threads };
    let mut current = String::new();
    let series = compare::run_with(
        &scene,
        &a.integrators,
        &reference,
        &opts,
        a.every.unwrap_or(Duration::ZERO),
        |name, p| {
            if a.quiet {
                return;
            }
            if current != name {
                if !current.is_empty() {
                    eprintln!();
                }
                current = name.to_string();
            }
            eprint!("\r{name}: {:.1}/{:.0} s, {} spp   ", p.elapsed.as_secs_f64(), a.time.as_secs_f64(), p.spp_done);
        },
        &mut gpu_cmd::compare_external(),
    )?;
    if !a.quiet {
        eprintln!();
    }
    let study = compare::Study {
        scene_label: a.scene.as_deref().map(|p| p.display().to_string()).unwrap_or_else(|| "default scene".into()),
        reference_label: a.reference.display().to_string(),
        time: a.time,
        every: a.every.unwrap_or(Duration::ZERO),
        seed: a.seed,
        threads: a.setup.threads,
        series,
    };
    compare::write_report(&study, &reference, &a.output)?;
    for s in &study.series {
        if let Some(p) = s.points.last() {
            eprintln!(
                "{}: {} spp in {:.2} s ({:.2} s preparation), relMSE {:.4e}, RMSE {:.4e}",
                s.name, p.spp, p.seconds, s.preparation, p.metrics.relmse, p.metrics.rmse
            );
        }
    }
    eprintln!("report: {}", a.output.join("report.html").display());
    Ok(())
}

/// Refuses an input with NaN or infinite pixels: merged or compared, they would spread into
/// every result without a word.
fn refuse_non_finite(path: &Path, img: &Image, verb: &str) -> Result<()> {
    if let Some((count, (x, y))) = img.non_finite() {
        bail!(
            "{}: {count} pixels are NaN or infinite (the first at x {x}, y {y}); refusing to {verb} it",
            path.display()
        );
    }
    Ok(())
}

/// Merges independent renders of one scene, weighted by their sample counts.
/// Shards of one render (`render --shard`) are merged exactly, by adding their films, and
/// only when each shard is given once.
fn merge(parts: &[PathBuf], output: &Path, equal_weights: bool) -> Result<()> {
    let out = check_output(output, &parts.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    let shards = parts.iter().map(|p| skelight::shard::is_shard_file(p)).collect::<Result<Vec<bool>, _>>()?;
    if shards.iter().any(|s| *s) {
        if equal_weights {
            bail!("--equal-weights is for independent renders; shards merge by their samples");
        }
        if let Some(i) = shards.iter().position(|s| !s) {
            bail!("{} is not a shard but other inputs are; merge the shards of one render alone", parts[i].display());
        }
        let merged = skelight::shard::merge_files(parts)?;
        write_outputs(&merged.film, merged.spp, output, 0.0)?;
        eprintln!(
            "merged {} shards ({} spp in all) of {} → {}",
            merged.shards,
            merged.spp,
            merged.render,
            output.display()
        );
        return Ok(());
    }
    let (img, total) = skelight::shard::merge_independent(parts, equal_weights)?;
    img.save_exr_with(&out.exr, &[("skelight.spp", total)])?;
    img.save_png(&out.png, 0.0)?;
    eprintln!("merged {} images ({} spp in all) → {}", parts.len(), total, out.exr.display());
    Ok(())
}

/// Keeps freed memory in the process rather than handing it back to the kernel. The analysis
/// allocates and frees arrays of up to tens of MB stage after stage, and by default glibc
/// maps each afresh and unmaps it on free, so every page of every array costs a fault
/// (cold runs, alternating: door on the thesis grid 0.223–0.264 → 0.199–0.234 s, peak
/// 134 → 152 MB; veach-ajar at 364 1.17–1.23 → 1.03–1.09 s, peak +17 MB).
/// Arrays above 32 MB are still mapped on their own and returned when freed.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn keep_freed_memory() {
    // SAFETY: mallopt only sets glibc's allocation thresholds; no thread has started yet.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, libc::c_int::MAX);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn keep_freed_memory() {}

/// The parsed command line; `render --help` and friends list the registry's estimators.
fn cli() -> Cli {
    use clap::{CommandFactory, FromArgMatches};
    let help = registry::help();
    let mut command = Cli::command();
    for sub in ["render", "reference", "compare"] {
        command = command.mut_subcommand(sub, |c| c.after_long_help(help.clone()));
    }
    let matches = command.get_matches();
    Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
}

fn main() {
    keep_freed_memory();
    let cli = cli();
    let r = match cli.command {
        Command::Render(a) => render_cmd::render(a),
        Command::Skeleton {
            scene,
            resolution,
            constraint,
            bounds,
            enclosed_only,
            anchors,
            keep_all_space,
            output,
            define,
            picture_size,
            no_pictures,
            quiet,
        } => (|| {
            let mut scene = load_scene(scene.as_deref(), &define)?;
            let anchors = skeleton::anchors(&scene, &anchors);
            let sources = skeleton::sources(&scene);
            let settings = AnalysisSettings {
                resolution,
                constraint,
                region: bounds.region(&scene),
                enclosed_only,
                anchors,
                sources,
                keep_all_space,
            };
            let analysis = skeleton::run(&scene, &settings, &output, quiet)?;
            if no_pictures {
                return Ok(());
            }
            if !(16..=8192).contains(&picture_size) {
                bail!("--picture-size must be 16 to 8192 pixels, not {picture_size}");
            }
            let (w, h) = (scene.settings.width as f64, scene.settings.height as f64);
            let scale = picture_size as f64 / w.max(h);
            scene.set_resolution(((w * scale).round() as usize).max(1), ((h * scale).round() as usize).max(1));
            let mut files = Vec::new();
            for (name, image) in skelight::guided::pictures::analysis_pictures(&scene, &analysis) {
                let path = output.join(name);
                image.save_png(&path, 0.0).with_context(|| format!("writing {}", path.display()))?;
                files.push(path);
            }
            if !quiet {
                eprintln!("pictures: {}", files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>().join(", "));
            }
            // What would guide skelpt at this resolution (its own anchors: lights and camera).
            if let Resolution::Longest(n) = resolution {
                if scene.lights.is_empty() {
                    eprintln!("no lights: no importance pictures");
                } else {
                    let mut skelpt = registry::create("skelpt", &[("resolution".into(), n.to_string())])?;
                    skelpt.prepare(&scene)?;
                    let files = write_debug_files(skelpt.as_ref(), &scene, &output)?;
                    if files.is_empty() {
                        eprintln!("skelpt found no lit skeleton node in this scene: nothing guides it");
                    }
                    for f in files {
                        eprintln!("wrote {}", f.display());
                    }
                }
            }
            Ok(())
        })(),
        Command::Bench { what } => bench(what),
        Command::Reference(a) => reference(a),
        Command::Compare(a) => compare_cmd(a),
        Command::Merge { parts, output, equal_weights } => merge(&parts, &output, equal_weights),
        Command::Diff { image, reference, error_image, max_error } => (|| {
            let ia = Image::load(&image)?;
            let ib = Image::load(&reference)?;
            refuse_non_finite(&image, &ia, "compare")?;
            refuse_non_finite(&reference, &ib, "compare")?;
            let m = eval::metrics(&ia, &ib)?;
            if let Some(p) = &error_image {
                eval::error_image(&ia, &ib, max_error)?.save(p)?;
            }
            println!(
                "MAE {:.6e}  RMSE {:.6e}  relMSE {:.6e}  NRMSE {:.6e}  (max over RGB)",
                m.mae, m.rmse, m.relmse, m.nrmse
            );
            println!(
                "MAE {:.6e}  RMSE {:.6e}  relMSE {:.6e}  NRMSE {:.6e}  (luminance)",
                m.mae_lum, m.rmse_lum, m.relmse_lum, m.nrmse_lum
            );
            Ok(())
        })(),
        Command::Info { scene, define } => (|| {
            let s = load_scene(Some(&scene), &define)?;
            println!(
                "{} meshes, {} triangles, {} materials, {} lights",
                s.meshes.len(),
                s.triangle_count(),
                s.materials.len(),
                s.lights.len()
            );
            println!(
                "{}×{}, {} spp, max depth {}, filter {:?}",
                s.settings.width, s.settings.height, s.settings.spp, s.settings.max_depth, s.settings.filter
            );
            let b = s.bounds();
            println!("bounds {:?} – {:?}", b.min, b.max);
            match skelight::guided::analysis::occupied_box(&s) {
                Some([lo, hi]) => {
                    println!("analysed box (bounds=occupied, around the camera and lights): {lo:.3?} – {hi:.3?}")
                }
                None => println!("analysed box (bounds=occupied): the scene's bounds grown by 10 %"),
            }
            Ok(())
        })(),
    };
    if let Err(e) = r {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// `--integrator`'s help line: every estimator of the registry.
pub(crate) fn estimator_line() -> String {
    format!("Estimator: {} (`--help` lists them with their parameters)", registry::names().join(", "))
}
