//! `skelight`: render scenes, compare images.

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
    /// Print what a scene contains and any loader warnings.
    Info {
        scene: PathBuf,
        #[arg(short = 'D', value_parser = parse_define)]
        define: Vec<(String, String)>,
    },
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
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Override image width and height (keeps the field of view).
    #[arg(long, num_args = 2, value_names = ["W", "H"])]
    resolution: Option<Vec<usize>>,
    /// Maximum path depth (Mitsuba's max_depth; -1 = unbounded). Overrides the scene.
    #[arg(long)]
    max_depth: Option<i32>,
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

fn render(args: RenderArgs) -> Result<()> {
    let mut scene = load_scene(args.scene.as_deref(), &args.define)?;
    if let Some(r) = &args.resolution {
        let (w, h) = (r[0], r[1]);
        skelight::scene::load::mitsuba::check_resolution(w as i64, h as i64).map_err(anyhow::Error::msg)?;
        scene.set_resolution(w, h);
    }
    if let Some(d) = args.max_depth {
        if d < -1 {
            bail!("--max-depth must be -1 (unbounded) or at least 0");
        }
        scene.settings.max_depth = d;
    }
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
    let opts = RenderOptions { spp, time, seed: args.seed, threads: args.threads };
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
