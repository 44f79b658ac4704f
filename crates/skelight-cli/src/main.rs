//! `skelight`: render scenes, compare images, measure throughput.

mod bench;

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use skelight::eval;
use skelight::imageio::Image;
use skelight::integrator::{self, RenderOptions};
use skelight::scene::{self, Scene};

#[derive(Parser)]
#[command(name = "skelight", version, about = "Physically based renderer guided by the shape of empty space")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (Mitsuba XML); without SCENE, the embedded two-room default scene.
    Render(RenderArgs),
    /// Error metrics between two images (MAE, RMSE, relMSE, NRMSE).
    Diff { a: PathBuf, b: PathBuf },
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
    },
    /// Samples per second of an estimator on a scene.
    Render {
        scene: PathBuf,
        #[arg(short, long, default_value = "pt")]
        integrator: String,
        #[arg(long, default_value_t = 16)]
        spp: u32,
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
    #[arg(long)]
    max_depth: Option<i32>,
    /// Ray-tracing backend: bvh (built in) or embree (when compiled with --features embree).
    #[arg(long, default_value = "bvh")]
    backend: String,
}

impl SceneSetup {
    fn apply(&self, scene: &mut Scene) -> Result<()> {
        if let Some(r) = &self.resolution {
            skelight::scene::load::mitsuba::check_resolution(r[0] as i64, r[1] as i64).map_err(anyhow::Error::msg)?;
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

#[derive(clap::Args)]
struct RenderArgs {
    /// Scene file (.xml). Omit to render the embedded default scene.
    scene: Option<PathBuf>,
    /// Output image (.exr); a tone-mapped PNG is written beside it.
    #[arg(short, long, default_value = "render.exr")]
    output: PathBuf,
    /// Estimator: one of pt.
    #[arg(short, long, default_value = "pt")]
    integrator: String,
    /// Samples per pixel (default: the scene's sampler, or 16 for the default scene).
    #[arg(long, conflicts_with = "time")]
    spp: Option<u32>,
    /// Render for this many seconds instead of a sample count.
    #[arg(long)]
    time: Option<f64>,
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
        BenchKind::Rays { scenes, rays, threads } => {
            rayon::ThreadPoolBuilder::new().num_threads(threads).build_global().ok();
            println!(
                "{:<28} {:>9} {:>8} {:>10} {:>13} {:>11} {:>7}",
                "scene", "triangles", "backend", "build ms", "closest Mr/s", "any Mr/s", "hit %"
            );
            for path in scenes {
                let scene = load_scene(Some(&path), &[])?;
                let tris = scene.build_triangles();
                let rs = bench::incoherent_rays(&tris, rays, 1);
                let mut first: Option<(f64, f64, f64)> = None;
                for (name, build) in bench::backends() {
                    let r = bench::measure(&tris, &rs, build.as_ref());
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
                    first.get_or_insert((r.build.as_secs_f64(), r.closest_mrays, r.any_mrays));
                }
            }
            Ok(())
        }
        BenchKind::Render { scene: path, integrator: name, spp, setup } => {
            let mut scene = load_scene(Some(&path), &[])?;
            setup.apply(&mut scene)?;
            let integrator = integrator::by_name(&name).with_context(|| format!("unknown integrator '{name}'"))?;
            let opts = RenderOptions { spp: Some(spp), time: None, seed: 1, threads: setup.threads };
            let r = integrator::render(&scene, integrator.as_ref(), &opts, None, |_, _| true)?;
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

fn render(args: RenderArgs) -> Result<()> {
    let mut scene = load_scene(args.scene.as_deref(), &args.define)?;
    args.setup.apply(&mut scene)?;
    let integrator = integrator::by_name(&args.integrator).with_context(|| {
        format!("unknown integrator '{}'; available: {}", args.integrator, integrator::INTEGRATORS.join(", "))
    })?;
    let time = match args.time {
        Some(t) if !(t > 0.0 && t.is_finite() && t < 1e7) => {
            bail!("--time must be a positive number of seconds")
        }
        Some(t) => Some(Duration::from_secs_f64(t)),
        None => None,
    };
    let spp = match (args.spp, time) {
        (Some(0), _) => bail!("--spp must be at least 1"),
        (Some(s), _) => Some(s),
        (None, Some(_)) => None,
        (None, None) => Some(if args.scene.is_some() { scene.settings.spp } else { 16 }),
    };
    let opts = RenderOptions { spp, time, seed: args.seed, threads: args.setup.threads };
    let (w, h) = (scene.settings.width, scene.settings.height);
    eprintln!(
        "{}: {} triangles, {} lights, {}×{}, {} , max depth {}",
        args.scene
            .as_deref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "default scene (two rooms, door ajar)".into()),
        scene.triangle_count(),
        scene.lights.len(),
        w,
        h,
        integrator.name(),
        scene.settings.max_depth
    );
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(spp.map(u64::from).unwrap_or_else(|| (time.unwrap().as_secs_f64() * 10.0) as u64))
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let result = integrator::render(&scene, integrator.as_ref(), &opts, None, |p, _| {
        match (p.spp_target, p.time_budget) {
            (Some(_), None) => bar.set_position(p.spp_done as u64),
            (_, Some(b)) => bar.set_position(
                ((p.elapsed.as_secs_f64() / b.as_secs_f64()).min(1.0) * bar.length().unwrap_or(1) as f64) as u64,
            ),
            _ => {}
        }
        bar.set_message(format!("{} spp, {:.2} Msamples/s", p.spp_done, p.samples_per_second / 1e6));
        true
    })?;
    bar.finish_and_clear();
    let img = result.film.image();
    img.save_exr(&args.output).with_context(|| format!("writing {}", args.output.display()))?;
    let png = args.output.with_extension("png");
    img.save_png(&png, args.exposure)?;
    let secs = result.elapsed.as_secs_f64();
    eprintln!(
        "done: {} spp in {:.2} s ({:.2} Msamples/s), mean RGB {:.4} {:.4} {:.4}, {} non-finite samples rejected → {} and {}",
        result.spp,
        secs,
        (result.spp as f64 * (w * h) as f64) / secs.max(1e-9) / 1e6,
        img.mean().r,
        img.mean().g,
        img.mean().b,
        result.film.rejected,
        args.output.display(),
        png.display()
    );
    Ok(())
}

fn main() {
    let cli = Cli::parse();
    let r = match cli.command {
        Command::Render(a) => render(a),
        Command::Bench { what } => bench(what),
        Command::Diff { a, b } => (|| {
            let ia = Image::load(&a)?;
            let ib = Image::load(&b)?;
            let m = eval::metrics(&ia, &ib)?;
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
            Ok(())
        })(),
    };
    if let Err(e) = r {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
