//! `skelight bench`: ray-tracing and estimator throughput, measured in one run so that
//! backends can be compared as ratios on the same machine, and the empty-space analysis'
//! time per stage and peak memory.

use std::time::{Duration, Instant};

use rayon::prelude::*;
use skelight::geometry::{offset_origin, Accelerator, BuildTriangle, Bvh, NoFilter, Ray};
use skelight::math::Vec3;
use skelight::sampling::{uniform_sphere, uniform_triangle, Distribution1D, Rng};
use skelight_shape::pipeline::{analyse, Analysis, AnalysisSettings};

/// Incoherent rays: origins on the surfaces (area-weighted), directions uniform on the
/// sphere — what secondary bounces of a path tracer look like to the accelerator.
pub fn incoherent_rays(tris: &[BuildTriangle], n: usize, seed: u64) -> Vec<Ray> {
    let areas: Vec<f32> = tris.iter().map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length()).collect();
    let dist = Distribution1D::new(&areas);
    (0..n)
        .into_par_iter()
        .map(|i| {
            let mut rng = Rng::new(seed, i as u64, 0);
            let (k, _, rem) = dist.sample_discrete(rng.next_f32());
            let b = uniform_triangle(skelight::math::vec2(rem, rng.next_f32()));
            let [a, bb, c] = tris[k].v;
            let p = a * (1.0 - b.x - b.y) + bb * b.x + c * b.y;
            let ng = (bb - a).cross(c - a);
            let ng = if ng.length_squared() > 0.0 { ng.normalize() } else { Vec3::ZERO };
            let d = uniform_sphere(rng.next_2d());
            Ray::new(offset_origin(p, ng, d), d)
        })
        .collect()
}

pub struct RayResult {
    pub build: Duration,
    pub closest_mrays: f64,
    pub any_mrays: f64,
    pub hits: usize,
    /// The backend's description of what it built.
    pub structure: Option<String>,
}

fn best_of<T>(runs: usize, mut f: impl FnMut() -> (Duration, T)) -> (Duration, T) {
    let mut best = f();
    for _ in 1..runs {
        let r = f();
        if r.0 < best.0 {
            best = r;
        }
    }
    best
}

/// Times building each backend (best of 3), then tracing `rays` with each, closest-hit
/// and any-hit, in `rounds` rounds that take the backends in turn, keeping each one's best
/// time. Taking turns spreads this machine's bursts of load over all backends, so their
/// ratios hold even when the absolute figures move.
pub fn measure(tris: &[BuildTriangle], rays: &[Ray], backends: &[(&str, Builder)], rounds: usize) -> Vec<RayResult> {
    let built: Vec<(Duration, Box<dyn Accelerator>)> = backends
        .iter()
        .map(|(_, build)| {
            best_of(3, || {
                let t = Instant::now();
                let a = build(tris);
                (t.elapsed(), a)
            })
        })
        .collect();
    let mut best = vec![(Duration::MAX, Duration::MAX, 0usize); built.len()];
    for _ in 0..rounds.max(1) {
        for ((_, accel), best) in built.iter().zip(&mut best) {
            let t = Instant::now();
            let hits = rays
                .par_chunks(4096)
                .map(|c| c.iter().filter(|r| accel.intersect(r, &NoFilter).is_some()).count())
                .sum::<usize>();
            let closest = t.elapsed();
            let t = Instant::now();
            rays.par_chunks(4096).for_each(|c| c.iter().for_each(|r| _ = accel.occluded(r, &NoFilter)));
            *best = (best.0.min(closest), best.1.min(t.elapsed()), hits);
        }
    }
    let m = rays.len() as f64 / 1e6;
    built
        .into_iter()
        .zip(best)
        .map(|((build, accel), (closest, any, hits))| RayResult {
            build,
            closest_mrays: m / closest.as_secs_f64(),
            any_mrays: m / any.as_secs_f64(),
            hits,
            structure: accel.describe(),
        })
        .collect()
}

/// Builds an accelerator over the scene's triangles.
pub type Builder = Box<dyn Fn(&[BuildTriangle]) -> Box<dyn Accelerator>>;

/// The accelerators compiled into this binary, by name.
#[allow(unused_mut)] // mutated only with the `embree` feature
pub fn backends() -> Vec<(&'static str, Builder)> {
    let mut v: Vec<(&'static str, Builder)> =
        vec![("bvh", Box::new(|t: &[BuildTriangle]| Box::new(Bvh::build(t)) as Box<dyn Accelerator>))];
    #[cfg(feature = "embree")]
    v.push((
        "embree",
        Box::new(|t: &[BuildTriangle]| {
            Box::new(skelight::geometry::EmbreeAccel::build(t).expect("Embree device")) as Box<dyn Accelerator>
        }),
    ));
    v
}

/// Runs the empty-space analysis of `scene` `runs` times and prints the stage times of the
/// fastest run, the node counts and the process' peak resident memory.
pub fn skeleton(scene: &skelight::scene::Scene, settings: &AnalysisSettings, runs: usize) -> anyhow::Result<()> {
    let triangles = crate::skeleton::scene_triangles(scene);
    let mut best: Option<(f64, Analysis)> = None;
    for _ in 0..runs {
        let a = analyse(&triangles, settings)?;
        let total: f64 = a.timings.iter().map(|t| t.1).sum();
        if best.as_ref().is_none_or(|(t, _)| total < *t) {
            best = Some((total, a));
        }
    }
    let (total, a) = best.expect("at least one run");
    let [w, h, d] = a.spec.dims;
    println!(
        "grid {w}×{h}×{d} ({:.2} M voxels), {} threads, best of {runs}",
        (w * h * d) as f64 / 1e6,
        rayon::current_num_threads()
    );
    for (stage, secs) in &a.timings {
        println!("  {stage:<60} {secs:9.4} s");
    }
    println!("  {:<60} {total:9.4} s", "total");
    println!("steps, each on its thread (a phase's steps overlap):");
    for (step, secs) in &a.steps {
        println!("  {step:<60} {secs:9.4} s");
    }
    println!("{}", crate::skeleton::space_kept(&a));
    println!(
        "skeleton {} nodes → filtered {}; peak memory {}",
        a.skeleton.nodes.len(),
        a.filtered.nodes.len(),
        peak_memory().map_or("unknown".into(), |kb| format!("{:.0} MB", kb as f64 / 1024.0))
    );
    Ok(())
}

/// Peak resident set size of this process in KiB (Linux), if the system reports it.
fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
