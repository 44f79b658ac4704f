//! `render` and `reference --device gpu`: `pt`, `ibpt` or `lt` on the GPU (crates/skelight-gpu)
//! as a job like the CPU's (`--spp`, `--time`, `--shard`, checkpoints; the same EXRs, so
//! `merge` combines a GPU render with CPU renders of other seeds), and `bench … --device gpu`.

#[cfg(feature = "gpu")]
use anyhow::Context;
use anyhow::{bail, Result};

/// Refuses, before the scene loads, an estimator the GPU does not render
/// (skelight_gpu::Estimator::ALL) or a parameter its kernels do not take
/// (skelight_gpu::job::estimator_for).
#[cfg(feature = "gpu")]
pub(crate) fn check_estimator(integrator: &str, params: &[(String, String)]) -> Result<()> {
    skelight_gpu::job::estimator_for(integrator, params).context("--device gpu")?;
    Ok(())
}

/// What renders `job`: the CPU's estimator (`Job::run`), or for a GPU job its kernels, opened
/// here (skelight_gpu::job::run; the adapter is named on stderr).
#[cfg(feature = "gpu")]
pub(crate) fn job_renderer(job: &crate::render_cmd::Job) -> Result<Box<skelight::job::Render>> {
    let (render, line) = skelight_gpu::job::renderer_for(job, &job.scene).context("--device gpu")?;
    if let Some(line) = line {
        eprintln!("{line}");
    }
    Ok(render)
}

/// `bench render --device gpu`: samples/s and rays/s after one warm-up sample (shader
/// compilation and first dispatches), and what the renderer keeps on the device.
#[cfg(feature = "gpu")]
pub(crate) fn bench(path: &std::path::Path, scene: &skelight::scene::Scene, name: &str, spp: u32) -> Result<()> {
    let (name, params) = skelight::estimators::parse_spec(name)?;
    let estimator = skelight_gpu::job::estimator_for(&name, &params).context("--device gpu")?;
    let name = estimator.name();
    if spp == 0 {
        bail!("--spp must be at least 1");
    }
    let mut gpu = skelight_gpu::GpuRenderer::new(scene, estimator)?;
    let (w, h) = (scene.settings.width, scene.settings.height);
    let mut film = skelight::film::Film::new(w, h, scene.settings.filter);
    gpu.render_into(&mut film, 1, 0, 1, |_| {})?;
    let (rays_before, start) = (gpu.rays_traced(), std::time::Instant::now());
    gpu.render_into(&mut film, 1, 1, spp, |_| {})?;
    let secs = start.elapsed().as_secs_f64();
    let rays = (gpu.rays_traced() - rays_before) as f64;
    let samples = spp as f64 * (w * h) as f64;
    let memory = gpu.memory();
    println!("GPU: {} (splats by {:?}, {:?})", gpu.adapter, gpu.splat_mode, gpu.shape());
    println!(
        "{} {name} (gpu): {w}×{h} {spp} spp, max depth {}, {secs:.3} s, {:.3} Msamples/s, {:.1} Mrays/s ({:.1} rays per sample), mean {:?}",
        path.display(),
        scene.settings.max_depth,
        samples / secs / 1e6,
        rays / secs / 1e6,
        rays / samples,
        film.image().mean()
    );
    println!(
        "device memory: scene {:.2} MB, film {} bytes per pixel, path state {} bytes per path ({})",
        memory.scene_bytes as f64 / 1e6,
        memory.film_bytes_per_pixel,
        memory.path_state_bytes,
        if memory.path_state_bytes == 0 {
            "registers only"
        } else {
            "the wavefront's state and the traversal's stack, at most"
        }
    );
    Ok(())
}

/// `bench rays --device gpu`: the GPU kernels' traversal alone, closest and any hit, through
/// each of its traversals (bvh.rs: the hybrid's closest hits are the ordered traversal's and
/// its any hits the stackless one's) on two sets of rays: the incoherent rays of the CPU's
/// `bench rays` (origins on the surfaces, uniform directions) and primary rays (the scene's
/// camera, one ray through each pixel's centre, at its aspect ratio), which published GPU
/// figures often quote. Each row also gives the work per closest-hit ray, counted on the CPU
/// over the first 20 000 rays by a mirror of the kernel (nodes fetched, 48 bytes each stackless
/// and 64 ordered; boxes;
/// triangles), which does not depend on the device, and how many rays' closest hits differ
/// from the stackless traversal's on the device (0: all found the same distances).
#[cfg(feature = "gpu")]
pub(crate) fn bench_rays(scenes: &[std::path::PathBuf], n: usize, rounds: usize) -> Result<()> {
    use skelight_gpu::bvh::{pair_nodes, reference_traverse, tree_depth, Traversal, Work};
    use skelight_gpu::{Estimator, GpuRenderer, Splats};
    println!(
        "{:<24} {:>9} {:<10} {:<9} {:>12} {:>9} {:>6} {:>8} {:>7} {:>7} {:>7}",
        "scene",
        "triangles",
        "rays",
        "traversal",
        "closest Mr/s",
        "any Mr/s",
        "hit %",
        "fetches",
        "boxes",
        "tris",
        "differ"
    );
    for path in scenes {
        let mut scene = crate::load_scene(Some(path), &[])?;
        // Rays alone see the geometry: a filter the GPU does not render (sponza's Gaussian)
        // does not matter here.
        scene.settings.filter = skelight::film::Filter::Box;
        let tris = scene.build_triangles();
        let flat = skelight_gpu::flatten::flatten(&scene)?;
        let pairs = pair_nodes(&flat.nodes);
        let label = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
        let aspect = scene.camera.width as f64 / scene.camera.height as f64;
        let (w, h) = (
            ((n as f64 * aspect).sqrt().round() as usize).max(1),
            ((n as f64 / aspect).sqrt().round() as usize).max(1),
        );
        let primary = scene.camera.with_resolution(w, h).pixel_centre_rays();
        let sets = [("incoherent", crate::bench::incoherent_rays(&tris, n, 1)), ("primary", primary)];
        let mut adapter = String::new();
        for (set, rays) in &sets {
            // A large finite t_max: an infinite one is not promised to survive shader compilers.
            let packed = |any: f32| -> Vec<[f32; 8]> {
                rays.iter().map(|r| [r.o.x, r.o.y, r.o.z, r.tmax.min(1e30), r.d.x, r.d.y, r.d.z, any]).collect()
            };
            let mut first: Option<Vec<f32>> = None;
            for traversal in Traversal::ALL {
                let gpu = GpuRenderer::with_shape(&scene, Estimator::Pt, Splats::Auto, |s| s.traversal = traversal)?;
                let (closest, distances) = gpu.trace(&packed(0.0), rounds)?;
                let (any, _) = gpu.trace(&packed(1.0), rounds)?;
                let hits = rays.iter().zip(&distances).filter(|(r, &t)| t < r.tmax.min(1e30)).count();
                // Rays whose closest hits differ by more than rounding: a box test rounds its
                // entry distance, so a triangle on a box's face can be culled for another hit a
                // few ulps farther.
                let differ = first.as_ref().map_or(0, |f| {
                    f.iter().zip(&distances).filter(|(&a, &b)| (a - b).abs() > 1e-5 * a.abs().max(b.abs())).count()
                });
                first.get_or_insert(distances);
                adapter.clone_from(&gpu.adapter);
                let mut work = Work::default();
                let counted = rays.len().min(20_000);
                for r in &rays[..counted] {
                    let (o, d) = ([r.o.x, r.o.y, r.o.z], [r.d.x, r.d.y, r.d.z]);
                    work += reference_traverse(traversal, &flat.nodes, &pairs, &flat.tris, o, d, r.tmax.min(1e30)).1;
                }
                let per_ray = |x: u64| x as f64 / counted.max(1) as f64;
                let mrays = |t: std::time::Duration| rays.len() as f64 / t.as_secs_f64() / 1e6;
                println!(
                    "{label:<24} {:>9} {set:<10} {:<9} {:>12.1} {:>9.1} {:>6.2} {:>8.1} {:>7.1} {:>7.1} {:>7}",
                    tris.len(),
                    traversal.name(),
                    mrays(closest),
                    mrays(any),
                    100.0 * hits as f64 / rays.len() as f64,
                    per_ray(work.fetches),
                    per_ray(work.boxes),
                    per_ray(work.triangles),
                    differ,
                );
            }
        }
        println!(
            "  tree depth {}, {} stackless nodes ({} KiB), {} paired nodes ({} KiB); {n} incoherent rays, {w}×{h} primary; {adapter}",
            tree_depth(&flat.nodes),
            flat.nodes.len(),
            flat.nodes.len() * 48 / 1024,
            pairs.len(),
            pairs.len() * 64 / 1024,
        );
    }
    Ok(())
}

#[cfg(not(feature = "gpu"))]
pub(crate) fn bench_rays(_: &[std::path::PathBuf], _: usize, _: usize) -> Result<()> {
    bail!("this skelight was built without the GPU: cargo build --release -p skelight-cli --features gpu")
}

/// `compare`'s `gpu:NAME` estimators (skelight_gpu::job::CompareOnGpu).
#[cfg(feature = "gpu")]
pub(crate) fn compare_external() -> impl skelight::compare::External {
    skelight_gpu::job::CompareOnGpu
}

/// `compare`'s `gpu:NAME` estimators: refused by a build without the GPU, before any run.
#[cfg(not(feature = "gpu"))]
pub(crate) fn compare_external() -> impl skelight::compare::External {
    NoGpu
}

#[cfg(not(feature = "gpu"))]
struct NoGpu;

#[cfg(not(feature = "gpu"))]
impl NoGpu {
    fn refusal() -> skelight::job::JobError {
        skelight::job::JobError::Invalid(
            "this skelight was built without the GPU: cargo build --release -p skelight-cli --features gpu".into(),
        )
    }
}

#[cfg(not(feature = "gpu"))]
impl skelight::compare::External for NoGpu {
    fn check(&mut self, name: &str, _: &skelight::scene::Scene) -> Option<Result<(), skelight::job::JobError>> {
        name.starts_with("gpu:").then(|| Err(NoGpu::refusal()))
    }

    fn render(
        &mut self,
        _: &str,
        _: &skelight::scene::Scene,
        _: &skelight::integrator::RenderOptions,
        _: &mut dyn FnMut(&skelight::integrator::Progress, &skelight::film::Film) -> bool,
    ) -> Result<skelight::integrator::RenderResult, skelight::job::JobError> {
        Err(NoGpu::refusal())
    }
}

#[cfg(not(feature = "gpu"))]
pub(crate) fn job_renderer(job: &crate::render_cmd::Job) -> Result<Box<skelight::job::Render>> {
    if job.device != skelight::job::Device::Cpu {
        bail!("this skelight was built without the GPU: cargo build --release -p skelight-cli --features gpu");
    }
    Ok(skelight::job::cpu_renderer())
}

#[cfg(not(feature = "gpu"))]
pub(crate) fn check_estimator(_: &str, _: &[(String, String)]) -> Result<()> {
    bail!("this skelight was built without the GPU: cargo build --release -p skelight-cli --features gpu")
}

#[cfg(not(feature = "gpu"))]
pub(crate) fn bench(_: &std::path::Path, _: &skelight::scene::Scene, _: &str, _: u32) -> Result<()> {
    bail!("this skelight was built without the GPU: cargo build --release -p skelight-cli --features gpu")
}
