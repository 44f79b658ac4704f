//! The GPU's estimators against Mitsuba 3's references and the CPU's, on whatever Vulkan
//! adapter there is:
//! lavapipe in CI (scripts/test.sh installs it), slowly but exactly. Without an adapter the
//! tests say so and pass, unless SKELIGHT_REQUIRE_GPU=1 (set by scripts/test.sh when it has
//! Vulkan), so that a machine without one does not fail the suite by accident.

#[path = "../../skelight/tests/common/mod.rs"]
mod common;

use common::{
    batch_block_t, batch_mean_se, conformance_noise, judge_against_reference, render_spp, shared_dir, T_LIMIT, Z_LIMIT,
};
use skelight::film::Film;
use skelight::imageio::Image;
use skelight::scene::load::load;
use skelight::scene::Scene;
use skelight_gpu::{Estimator, GpuError, GpuRenderer, Splats};

/// Opens the GPU for `scene`, or `None` (with a note) when the machine has no adapter and
/// none is required.
fn open(scene: &Scene, estimator: Estimator) -> Result<Option<GpuRenderer>, GpuError> {
    open_with(scene, estimator, Splats::Auto)
}

fn open_with(scene: &Scene, estimator: Estimator, splats: Splats) -> Result<Option<GpuRenderer>, GpuError> {
    match GpuRenderer::with_splats(scene, estimator, splats) {
        Err(GpuError::NoAdapter(why)) if std::env::var("SKELIGHT_REQUIRE_GPU").as_deref() != Ok("1") => {
            println!("no Vulkan adapter ({why}): GPU tests skipped");
            Ok(None)
        }
        other => other.map(Some),
    }
}

fn render(gpu: &mut GpuRenderer, scene: &Scene, spp: u32, seed: u64) -> Film {
    let mut film = Film::new(scene.settings.width, scene.settings.height, scene.settings.filter);
    gpu.render_into(&mut film, seed, 0, spp, |_| {}).expect("GPU render");
    film
}

/// The largest relative difference between two images' pixel channels (absolute below 1e-3).
fn worst_relative_difference(a: &Image, b: &Image) -> f32 {
    let mut worst = 0f32;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for (u, v) in [(p.r, q.r), (p.g, q.g), (p.b, q.b)] {
            worst = worst.max((u - v).abs() / (u.abs() + v.abs()).max(1e-3));
        }
    }
    worst
}

/// `render --device gpu --shard K/N` and `--time` (skelight_gpu::job): the shards of a GPU
/// render merge into the single render (up to the order of float sums), refuse to merge with a
/// CPU shard, and a time budget renders sample indices from 0 as a sample count does.
#[test]
fn gpu_jobs_shard_and_stop_at_a_time_budget_as_cpu_jobs_do() {
    use skelight::job::{Device, Job, JobSpec};
    use skelight::shard::{merge, Shard, ShardError};
    let scene = common::load_small(&shared_dir().join("conformance/scenes/c01_cbox_area.xml"), 24, 24);
    let Some(mut gpu) = open(&scene, Estimator::Ibpt).unwrap() else { return };
    let run = |gpu: &mut GpuRenderer, spp, time, shard, device_gpu: bool| {
        let device = if device_gpu { Device::Gpu } else { Device::Cpu };
        let spec = JobSpec { integrator: "ibpt".into(), spp, time, seed: 3, shard, device, ..Default::default() };
        let mut job = Job::new(&scene, "c01", &spec).unwrap();
        if device_gpu {
            skelight_gpu::job::run(gpu, &scene, &job, None, |_, _| Ok(())).unwrap()
        } else {
            job.run(&scene, None, |_, _| Ok(())).unwrap()
        }
    };
    let whole = run(&mut gpu, Some(7), None, None, true);
    let shards: Vec<_> = (0..3)
        .map(|k| {
            let r = run(&mut gpu, Some(7), None, Some(Shard::new(k, 3).unwrap()), true);
            (format!("shard {k}"), r.shard_output().expect("a shard's output"))
        })
        .collect();
    assert_eq!(shards.iter().map(|(_, s)| s.spp()).collect::<Vec<_>>(), [2, 2, 3]);
    let merged = merge(shards.clone()).expect("the GPU's shards merge");
    assert_eq!(merged.spp, 7);
    let worst = worst_relative_difference(&merged.film.image(), &whole.film.image());
    println!("3 GPU shards merged against the whole render: worst relative difference {worst:.2e}");
    // f32 sums on the device over other groupings of the same samples.
    assert!(worst < 1e-5, "the merged shards differ from the single render ({worst})");
    // A CPU shard of the same render has other random numbers: never merged with the GPU's.
    let cpu = run(&mut gpu, Some(7), None, Some(Shard::new(2, 3).unwrap()), false);
    let mixed = vec![shards[0].clone(), shards[1].clone(), ("cpu shard 2".into(), cpu.shard_output().unwrap())];
    assert!(matches!(merge(mixed), Err(ShardError::OtherRender { .. })), "a CPU shard merged with the GPU's");
    // A time budget: whole batches from sample 0 until it is spent, the image of a sample
    // count of as many.
    let budget = std::time::Duration::from_millis(1500);
    let timed = run(&mut gpu, None, Some(budget), None, true);
    assert!(timed.elapsed >= budget && timed.spp() >= 1 && timed.samples.start == 0);
    let counted = run(&mut gpu, Some(timed.spp()), None, None, true);
    let worst = worst_relative_difference(&timed.film.image(), &counted.film.image());
    println!("{} spp in a budget of {budget:?}: worst relative difference {worst:.2e} to --spp", timed.spp());
    assert!(worst < 1e-5, "the timed render differs from the counted one ({worst})");
}

/// `reference --device gpu`: a checkpointed GPU render resumed to more samples renders only
/// the samples after the checkpoint and, resumed at the end of one of the device's f32 groups
/// (16 samples), is the render of all of them at once bit for bit; a CPU job refuses the GPU's
/// checkpoint.
#[test]
fn a_gpu_reference_resumes_from_its_checkpoint() {
    use skelight::job::{Device, Job, JobSpec, Reference};
    let scene = common::load_small(&shared_dir().join("conformance/scenes/c01_cbox_area.xml"), 24, 24);
    let Some(mut gpu) = open(&scene, Estimator::Pt).unwrap() else { return };
    let whole = render(&mut gpu, &scene, 40, 9).image();
    let dir = std::env::temp_dir().join(format!("skelight-gpu-reference-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let output = dir.join("ref.exr");
    let every = std::time::Duration::from_secs(3600);
    let job = |spp, device| {
        let spec = JobSpec { integrator: "pt".into(), spp: Some(spp), seed: 9, device, ..Default::default() };
        Job::new(&scene, "c01", &spec).unwrap()
    };
    let mut render: Box<skelight::job::Render> =
        Box::new(move |job, scene, resume, on_pass| skelight_gpu::job::run(&mut gpu, scene, job, resume, on_pass));
    for (spp, resumed_from) in [(16, None), (40, Some(16))] {
        let mut j = job(spp, Device::Gpu);
        let reference = Reference::open(&mut j, &scene, &output, every).unwrap();
        assert_eq!(reference.resumed().map(|r| r.0), resumed_from);
        let mut passes = Vec::new();
        let on_pass = |p: &skelight::integrator::Progress, _: &Film| {
            passes.push(p.spp_done);
            Ok(())
        };
        let r = reference.run_on(&mut j, &scene, on_pass, &mut render).unwrap();
        assert_eq!(r.samples, 0..spp);
        // Only the samples after the checkpoint were rendered.
        assert!(passes[0] > resumed_from.unwrap_or(0), "passes {passes:?} after a checkpoint at {resumed_from:?}");
    }
    // pt adds no splats with atomics (whose order varies): bit for bit.
    let resumed = Image::load(&output).unwrap();
    let differ = resumed.pixels.iter().zip(&whole.pixels).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{differ} pixels of the resumed GPU reference differ from the single render's");
    assert!(
        Reference::open(&mut job(48, Device::Cpu), &scene, &output, every).is_err(),
        "a CPU job took a GPU checkpoint"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `compare`'s `gpu:NAME` estimators: run for the time budget beside the CPU's, their curve
/// measured on the GPU's film, their final image the GPU render of as many samples.
#[test]
fn compare_runs_gpu_estimators_beside_the_cpus() {
    use skelight::compare::run_with;
    use skelight::integrator::RenderOptions;
    use skelight_gpu::job::CompareOnGpu;
    let scene = common::load_small(&shared_dir().join("conformance/scenes/c01_cbox_area.xml"), 24, 24);
    let (mut bpt, _) = skelight::estimators::registry::create_for_scene("bpt", &scene.settings, &[]).unwrap();
    let reference = render_spp(&scene, bpt.as_mut(), 64, 1).image();
    let budget = std::time::Duration::from_millis(800);
    let opts = RenderOptions { spp: None, time: Some(budget), seed: 4, threads: 0 };
    let every = std::time::Duration::ZERO;
    // What the GPU cannot run (another estimator, parameters, a scene outside its subset) is
    // refused before the first run, not after the runs named before it (none of
    // these needs an adapter).
    let mut gaussian = common::load_small(&shared_dir().join("conformance/scenes/c01_cbox_area.xml"), 24, 24);
    gaussian.settings.filter = skelight::film::Filter::Gaussian { stddev: 0.5 };
    for (name, scene) in [("gpu:bpt", &scene), ("gpu:ibpt:rr_depth=2", &scene), ("gpu:pt", &gaussian)] {
        let mut passes = 0;
        let names = ["pt".to_string(), name.to_string()];
        let r = run_with(scene, &names, &reference, &opts, every, |_, _| passes += 1, &mut CompareOnGpu);
        let message = r.err().map(|e| e.to_string()).unwrap_or_default();
        println!("{name}: {message}");
        assert!(message.contains(name) && passes == 0, "{name} was not refused before pt ran ({passes} passes)");
    }
    let Some(mut gpu) = open(&scene, Estimator::Ibpt).unwrap() else { return };
    let names = ["gpu:ibpt".to_string(), "pt".to_string()];
    let series = run_with(&scene, &names, &reference, &opts, every, |_, _| {}, &mut CompareOnGpu).unwrap();
    assert_eq!(series.iter().map(|s| s.name.as_str()).collect::<Vec<_>>(), ["gpu:ibpt", "pt"]);
    let g = &series[0];
    let last = g.points.last().unwrap();
    assert!(g.points.windows(2).all(|w| w[1].spp > w[0].spp) && last.seconds >= budget.as_secs_f64());
    let same = render(&mut gpu, &scene, last.spp, 4).image();
    let worst = worst_relative_difference(&g.image, &same);
    println!(
        "gpu:ibpt {} spp in {:.2} s, relMSE {:.3e}; against a render of as many: {worst:.2e}",
        last.spp, last.seconds, last.metrics.relmse
    );
    assert!(worst < 1e-5, "compare's GPU image is not the GPU render of its samples ({worst})");
}

/// The launch shape (tiles, samples per dispatch, slices, the fused instant-BPT kernel,
/// workgroup) changes which thread takes a (pixel, sample), never its random numbers: the
/// same seed gives the same image up to the order of float sums. (It found tiles narrower
/// than a workgroup rendering their neighbour's pixels twice: now refused.)
#[test]
fn the_launch_shape_does_not_change_the_samples() {
    let mut scene = common::load_small(&shared_dir().join("scenes/veach-door/scene.xml"), 24, 16);
    scene.settings.max_depth = 4;
    for estimator in [Estimator::Pt, Estimator::Ibpt] {
        let Some(mut plain) = open_with(&scene, estimator, Splats::Auto).unwrap() else { return };
        let mut shaped = GpuRenderer::with_shape(&scene, estimator, Splats::Auto, |s| {
            (s.tile, s.samples_per_dispatch, s.slices, s.fused, s.workgroup) = (16, 4, 4, true, (16, 2));
        })
        .unwrap();
        // A tile narrower than a workgroup would render pixels of the next tile twice.
        let narrow = GpuRenderer::with_shape(&scene, estimator, Splats::Auto, |s| (s.tile, s.workgroup) = (8, (16, 2)));
        assert!(matches!(narrow, Err(GpuError::Invalid(_))), "a tile of 8 under workgroups of 16 is refused");
        let (a, b) = (render(&mut plain, &scene, 8, 5).image(), render(&mut shaped, &scene, 8, 5).image());
        let worst = worst_relative_difference(&a, &b);
        println!("{}: worst relative difference {worst:.2e} between the launch shapes", estimator.name());
        assert!(worst < 1e-4, "{}: the launch shape changed the image (relative difference {worst})", estimator.name());
    }
}

/// `bench rays --device gpu` measures the kernels' traversals alone: each must find what the
/// CPU's BVH finds. Rays from points of veach-door's bounding box in uniform directions.
/// Both triangle tests are watertight, so whether a ray hits does not depend on the tree: the
/// counts are equal; the closest distances agree up to rounding, which scales with the
/// coordinates (the scene's size) rather than with the distance (the GPU's edge test has no
/// double-precision fallback, and a box's entry distance is rounded too).
#[test]
fn the_gpu_traversals_hit_what_the_cpu_bvh_hits() {
    use skelight::geometry::{Accelerator, Bvh, NoFilter, Ray};
    use skelight::sampling::{uniform_sphere, Rng};
    use skelight_gpu::Traversal;
    let scene = common::load_small(&shared_dir().join("scenes/veach-door/scene.xml"), 8, 8);
    let Some(_) = open(&scene, Estimator::Pt).unwrap() else { return };
    let bvh = Bvh::build(&scene.build_triangles());
    let bounds = scene.bounds();
    let extent = (bounds.max - bounds.min).length();
    let rays: Vec<Ray> = (0..20_000u64)
        .map(|i| {
            let mut rng = Rng::new(3, i, 0);
            let (lo, hi) = (bounds.min, bounds.max);
            let mut at = |a: f32, b: f32| a + (b - a) * rng.next_f32();
            let o = skelight::math::vec3(at(lo.x, hi.x), at(lo.y, hi.y), at(lo.z, hi.z));
            Ray::new(o, uniform_sphere(rng.next_2d()))
        })
        .collect();
    let cpu: Vec<Option<f32>> = rays.iter().map(|r| bvh.intersect(r, &NoFilter).map(|h| h.t)).collect();
    let packed = |any: f32| -> Vec<[f32; 8]> {
        rays.iter().map(|r| [r.o.x, r.o.y, r.o.z, 1e30, r.d.x, r.d.y, r.d.z, any]).collect()
    };
    for traversal in Traversal::ALL {
        let gpu = GpuRenderer::with_shape(&scene, Estimator::Pt, Splats::Auto, |s| s.traversal = traversal).unwrap();
        let (_, closest) = gpu.trace(&packed(0.0), 1).unwrap();
        let (_, any) = gpu.trace(&packed(1.0), 1).unwrap();
        let hit = |t: &f32| *t < 1e30;
        let (mut hits, mut worst) = (0, 0f32);
        for (c, g) in cpu.iter().zip(&closest) {
            assert_eq!(c.is_some(), hit(g), "{traversal:?}: the GPU and the CPU disagree on whether a ray hits");
            if let Some(c) = c {
                hits += 1;
                worst = worst.max((c - g).abs() / (c + extent));
            }
        }
        println!("{traversal:?}: {hits} of 20 000 rays hit; closest distances within {worst:.1e} × (t + extent) of the CPU's");
        assert!(worst < 1e-6, "{traversal:?}: closest hits up to {worst} from the CPU's");
        assert!(closest.iter().zip(&any).all(|(c, a)| hit(c) == hit(a)), "{traversal:?}: closest and any hit disagree");
        assert!(closest.iter().zip(&any).all(|(c, a)| a >= c), "{traversal:?}: an any hit before the closest one");
    }
}

/// The ordered and hybrid traversals render what the stackless one renders: the same seed
/// gives the same image up to rounding (the same hits, found in another order).
#[test]
fn the_traversal_does_not_change_the_image() {
    let mut scene = common::load_small(&shared_dir().join("scenes/veach-door/scene.xml"), 24, 16);
    scene.settings.max_depth = 4;
    for estimator in [Estimator::Pt, Estimator::Ibpt] {
        let Some(mut stackless) = open_with(&scene, estimator, Splats::Auto).unwrap() else { return };
        let a = render(&mut stackless, &scene, 8, 5).image();
        for traversal in [skelight_gpu::Traversal::Ordered, skelight_gpu::Traversal::Hybrid] {
            let mut other =
                GpuRenderer::with_shape(&scene, estimator, Splats::Auto, |s| s.traversal = traversal).unwrap();
            let worst = worst_relative_difference(&a, &render(&mut other, &scene, 8, 5).image());
            println!("{} {traversal:?}: worst relative difference {worst:.2e} from stackless", estimator.name());
            assert!(worst < 1e-4, "{} {traversal:?}: the traversal changed the image ({worst})", estimator.name());
        }
    }
}

/// The wavefront passes (wavefront.wgsl) render the megakernels' image: the same random
/// numbers along the same walks, so the same seed gives the same image up to float order,
/// with bounded depth, unbounded depth (Russian roulette; the host checks for live paths every
/// 8 bounces) under the tent filter, with slices (several waves a dispatch) and with several
/// tiles; the light pass with the light seen directly through a pinhole and a thin lens (the
/// splats its first kernel makes: forgetting to trace them left c14 at depth 1 black).
#[test]
fn the_wavefront_renders_the_megakernels_image() {
    let door = |depth: i32| {
        let mut s = common::load_small(&shared_dir().join("scenes/veach-door/scene.xml"), 24, 16);
        s.settings.max_depth = depth;
        s
    };
    let bounded = door(4);
    let mut unbounded = door(-1);
    unbounded.settings.rr_depth = 2;
    unbounded.settings.filter = skelight::film::Filter::Tent { radius: 1.0 };
    let conformance = |name: &str| common::load_small(&shared_dir().join("conformance/scenes").join(name), 24, 16);
    let (cbox, thin_lens) = (conformance("c01_cbox_area.xml"), conformance("c14_thinlens.xml"));
    let (pt, ibpt, lt) = (Estimator::Pt, Estimator::Ibpt, Estimator::Lt);
    let cases = [
        (&bounded, "veach-door, depth 4", vec![pt, ibpt]),
        (&unbounded, "veach-door, unbounded, tent filter", vec![pt, ibpt]),
        (&cbox, "c01", vec![lt]),
        (&thin_lens, "c14, thin lens", vec![lt, ibpt]),
    ];
    for (scene, what, estimators) in cases {
        for estimator in estimators {
            let Some(mut megakernel) = open_with(scene, estimator, Splats::Auto).unwrap() else { return };
            let a = render(&mut megakernel, scene, 8, 5).image();
            assert!(a.mean().r > 0.0, "a lit image");
            // One tile (24×16: rectangular path strides), and tiles of 16 pixels (16×16 and a
            // partial 8×16 one, whose paths keep the full tile's strides); the light pass as a
            // wavefront, and as the megakernel after the camera's wavefront.
            for (tile, light) in [(512, true), (16, true), (512, false)] {
                if !light && estimator == Estimator::Pt {
                    continue;
                }
                let mut wavefront = GpuRenderer::with_shape(scene, estimator, Splats::Auto, |s| {
                    (s.wavefront, s.wavefront_light, s.slices, s.samples_per_dispatch, s.tile) =
                        (true, light, 2, 4, tile);
                })
                .unwrap();
                let worst = worst_relative_difference(&a, &render(&mut wavefront, scene, 8, 5).image());
                println!(
                    "{} {what}, tile {tile}, light wavefront {light}: worst relative difference {worst:.2e}",
                    estimator.name()
                );
                assert!(worst < 1e-6, "{} {what}: the wavefront changed the image ({worst})", estimator.name());
            }
        }
    }
}

/// The fewest samples per pixel judged: one group of the device's 16 (lavapipe is slow; the
/// statistics take the noise into account).
const SPP: u32 = 16;

#[test]
fn gpu_pt_matches_mitsuba_on_the_conformance_scenes_it_renders() {
    matches_mitsuba(Estimator::Pt);
}

#[test]
fn gpu_ibpt_matches_mitsuba_on_the_conformance_scenes_it_renders() {
    matches_mitsuba(Estimator::Ibpt);
}

/// Scenes whose Mitsuba reference differs from the physically right image (the CPU's
/// tests/conformance.rs gives the evidence): c05's sky leaks through the floor in Mitsuba
/// (+0.094 % over the image); c13's mask counts as a bounce in Mitsuba (+0.31 % at its
/// depth 8). The GPU is compared with the CPU there instead.
const MITSUBA_DIFFERS: &[&str] = &["c05_constant_env", "c13_mask_twosided"];

fn matches_mitsuba(estimator: Estimator) {
    let label = estimator.name();
    let dir = shared_dir().join("conformance");
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("refs/manifest.json")).unwrap()).unwrap();
    let (mut tested, mut refused, mut failures) = (Vec::new(), Vec::new(), Vec::new());
    for (name, entry) in manifest.as_object().expect("manifest: an object of scenes") {
        if MITSUBA_DIFFERS.contains(&name.as_str()) {
            continue;
        }
        let scene = load(&dir.join("scenes").join(format!("{name}.xml")), &[]).unwrap();
        let mut gpu = match open(&scene, estimator) {
            Ok(Some(g)) => g,
            Ok(None) => return,
            Err(GpuError::Unsupported(why)) => {
                refused.push(format!("{name}: {}", why.split(';').next().unwrap_or_default()));
                continue;
            }
            Err(e) => panic!("{name}: {e}"),
        };
        let mean: Vec<f64> = entry["mean"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        let ref_mean = [mean[0], mean[1], mean[2]];
        let ref_spp = entry["spp"].as_u64().unwrap() as u32;
        let reference = Image::load(&dir.join("refs").join(format!("{name}.exr"))).unwrap();
        let noise = conformance_noise(&dir.join("scenes").join(format!("{name}.xml")), &scene, ref_spp);
        // As the CPU conformance test, at one group of the device's 16 samples (lavapipe's
        // minutes are the suite's dearest): each line states the bias it sees; a second look
        // at 4× the samples before a failure. The CPU's estimators carry the 2 % goal.
        let v = judge_against_reference(
            |spp, seed| render(&mut gpu, &scene, spp, seed),
            &reference,
            &noise,
            ref_mean,
            (SPP, SPP),
            (11, 12),
        );
        println!(
            "gpu {label:4} {name:24} {}  (ref {:.4} {:.4} {:.4}) {}  [{}]",
            v.line(),
            ref_mean[0],
            ref_mean[1],
            ref_mean[2],
            if v.ok { "ok" } else { "FAIL" },
            gpu.adapter
        );
        let (c, ok) = (v.comparison, v.ok);
        tested.push(name.clone());
        if !ok {
            failures.push(format!("{name}: T = {:.2}, z = {:?}", c.t, c.z));
        }
    }
    println!("refused (outside the GPU's feature subset):\n  {}", refused.join("\n  "));
    assert!(failures.is_empty(), "GPU {label} disagrees with Mitsuba 3 on:\n{}", failures.join("\n"));
    assert!(tested.iter().any(|n| n.starts_with("c01")), "c01 must be inside the GPU's subset; tested {tested:?}");
}

fn refused(s: &Scene, scene: &str, what: &str) {
    match GpuRenderer::new(s, Estimator::Ibpt) {
        Err(GpuError::Unsupported(why)) => assert!(why.contains(what), "{scene}: {why}"),
        Err(GpuError::NoAdapter(_)) => {}
        Err(e) => panic!("{scene}: {e}"),
        Ok(_) => panic!("{scene} should be refused"),
    }
}

/// A scene outside the subset is refused, naming what is outside it (never a silently
/// different image).
#[test]
fn scenes_outside_the_subset_are_refused_by_name() {
    let anisotropic = |t: String| {
        t.replace(
            r#"<float name="alpha" value="0.2"/>"#,
            r#"<float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.05"/>"#,
        )
    };
    refused(&common::edited_conformance_scene("c10_roughglass", anisotropic, 16, 16), "c10 anisotropic", "anisotropic");
    let sunsky = |t: String| {
        t.replace(
            r#"<emitter type="constant"><rgb name="radiance" value="1.0"/></emitter>"#,
            r#"<emitter type="sunsky"><vector name="sun_direction" value="0.4, 0.8, 0.45"/></emitter>"#,
        )
    };
    refused(&common::edited_conformance_scene("c05_constant_env", sunsky, 16, 16), "c05 under sunsky", "sun and sky");
}

/// `flatten::supported` (compare's check before its first run) refuses exactly the scenes
/// `flatten` refuses, with the same reason, on every conformance scene and the edited ones
/// above; it needs no adapter.
#[test]
fn supported_refuses_what_flatten_refuses() {
    use skelight::math::{vec3, Vec3};
    use skelight_gpu::flatten::{flatten, supported};
    let dir = shared_dir().join("conformance/scenes");
    let mut scenes: Vec<(String, Scene)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "xml"))
        .map(|p| (p.display().to_string(), load(&p, &[]).unwrap()))
        .collect();
    let mut sphere = common::load_small(&dir.join("c01_cbox_area.xml"), 8, 8);
    let unlit = sphere.meshes.iter_mut().find(|m| m.emission.is_none()).unwrap();
    unlit.sphere = Some(skelight::geometry::Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
        axes: [vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0)],
        inward: false,
    });
    scenes.push(("an exact sphere".into(), sphere));
    let mut empty = common::load_small(&dir.join("c01_cbox_area.xml"), 8, 8);
    empty.meshes.iter_mut().for_each(|m| m.indices.clear());
    scenes.push(("no triangles".into(), empty));
    let mut gaussian = common::load_small(&dir.join("c01_cbox_area.xml"), 8, 8);
    gaussian.settings.filter = skelight::film::Filter::Gaussian { stddev: 0.5 };
    scenes.push(("a Gaussian filter".into(), gaussian));
    let mut refused = 0;
    for (name, scene) in &scenes {
        let (a, b) = (supported(scene).err().map(|e| e.to_string()), flatten(scene).err().map(|e| e.to_string()));
        assert_eq!(a, b, "{name}: supported and flatten disagree");
        refused += a.is_some() as usize;
    }
    println!("{} scenes, {refused} refused by both", scenes.len());
    assert!(refused >= 3 && refused < scenes.len(), "{refused} of {} refused", scenes.len());
}

/// A GPU estimator against the CPU's of the same name (independent random numbers):
/// `batches` renders each (GPU seeds 21, 22, …, then the CPU's), image means by z-test and
/// 8×8 blocks by T with each side's variance from its renders' spread, as the CPU's
/// estimators are compared.
fn gpu_and_cpu_agree(estimator: Estimator, scene: &Scene, batches: u64, gpu_spp: u32, cpu_spp: u32) {
    gpu_and_cpu_agree_with(estimator, scene, batches, gpu_spp, cpu_spp, Splats::Auto);
}

fn gpu_and_cpu_agree_with(
    estimator: Estimator,
    scene: &Scene,
    batches: u64,
    gpu_spp: u32,
    cpu_spp: u32,
    splats: Splats,
) {
    let name = estimator.name();
    let Some(mut gpu) = open_with(scene, estimator, splats).expect("inside the GPU's subset") else { return };
    if splats == Splats::CompareAndSwap {
        assert_eq!(gpu.splat_mode, Splats::CompareAndSwap);
    }
    let g: Vec<Image> = (0..batches).map(|i| render(&mut gpu, scene, gpu_spp, 21 + i).image()).collect();
    let mut cpu = skelight::estimators::registry::create(name, &[]).unwrap();
    let c: Vec<Image> =
        (0..batches).map(|i| render_spp(scene, cpu.as_mut(), cpu_spp, 21 + batches + i).image()).collect();
    let (g, c): (Vec<&Image>, Vec<&Image>) = (g.iter().collect(), c.iter().collect());
    let ((mg, sg), (mc, sc)) = (batch_mean_se(&g), batch_mean_se(&c));
    let t = batch_block_t(&g, &c);
    println!("gpu vs cpu {name}: mean {mg:.4?} ± {sg:.4?} vs {mc:.4?} ± {sc:.4?}, block T {t:.2} [{}]", gpu.adapter);
    for c in 0..3 {
        let z = (mg[c] - mc[c]).abs() / (sg[c] * sg[c] + sc[c] * sc[c]).sqrt();
        assert!(
            z < Z_LIMIT,
            "channel {c}: GPU {name} {} ± {} vs CPU {name} {} ± {} (z {z:.2})",
            mg[c],
            sg[c],
            mc[c],
            sc[c]
        );
    }
    assert!(t < T_LIMIT, "GPU {name} vs CPU {name}: block T = {t:.2}");
}

/// GPU pt and ibpt against the CPU's on a small conformance scene: 4 renders a side of 32 GPU
/// and 64 CPU spp.
fn gpu_pt_and_ibpt_agree_with_the_cpu(scene: &Scene) {
    gpu_and_cpu_agree(Estimator::Pt, scene, 4, 32, 64);
    gpu_and_cpu_agree(Estimator::Ibpt, scene, 4, 32, 64);
}

fn gpu_and_cpu_ibpt_agree(scene: &Scene, gpu_spp: u32, cpu_spp: u32) {
    gpu_and_cpu_agree(Estimator::Ibpt, scene, 2, gpu_spp, cpu_spp);
}

#[test]
fn gpu_ibpt_matches_cpu_ibpt_on_the_cornell_box() {
    let scene = common::load_small(&shared_dir().join("conformance/scenes/c01_cbox_area.xml"), 64, 64);
    gpu_and_cpu_ibpt_agree(&scene, 64, 64);
}

/// Splats by compare and swap (what adapters without float atomics get), chosen on one that
/// has them: GPU ibpt against CPU ibpt on the Cornell box with the box filter (the light
/// pass's splats) and the tent filter (the camera samples' weighted sums as well).
#[test]
fn gpu_ibpt_with_compare_and_swap_splats_matches_the_cpu() {
    let mut scene = common::load_small(&shared_dir().join("conformance/scenes/c01_cbox_area.xml"), 32, 32);
    gpu_and_cpu_agree_with(Estimator::Ibpt, &scene, 4, 32, 64, Splats::CompareAndSwap);
    scene.settings.filter = skelight::film::Filter::Tent { radius: 1.5 };
    gpu_and_cpu_agree_with(Estimator::Ibpt, &scene, 4, 32, 64, Splats::CompareAndSwap);
}

/// The caustic scene (seed 002's claim): a small light focused by a glass ball onto the floor,
/// which light tracing finds; the ball as a mesh (the GPU has no exact spheres).
#[test]
fn gpu_ibpt_matches_cpu_ibpt_on_the_caustic_scene() {
    let path = common::repo_scene("caustic-small-light.xml");
    let mut scene = load(&path, &[("face_normals".into(), "true".into())]).unwrap();
    scene.set_resolution(48, 48);
    gpu_and_cpu_ibpt_agree(&scene, 64, 64);
    gpu_and_cpu_agree(Estimator::Lt, &scene, 8, 64, 64);
}

/// Veach's door (the issue's scene): bitmap textures, a bump-mapped rough conductor, a coated
/// floor, glass, the room lit through the door left ajar; at max depth 4 and 32×24.
///
/// Its light-tracing splats have heavy tails: at 256 spp GPU ibpt's image mean over eight
/// seeds spread by 2 % (sd), the strip at the right edge by 6 %, and pairs of seeds 8 % high
/// there made a two-render test fail at T 11–14 (a bias sought for a session, which eight
/// seeds showed was none: GPU 0.1407 ± 0.0010 against CPU 0.1407, strip 0.815 ± 0.018
/// against 0.797). Hence eight renders a side, so that the variance comes from their spread.
/// What it catches: dropping light tracing's term from next-event estimation's weight (+11 %)
/// fails it at T 3.54; dropping the lens importance's cosine (light tracing's share only,
/// +3.6 % here) passes at T 0.76, which the c11 lt test catches instead (T 235).
#[test]
fn gpu_ibpt_matches_cpu_ibpt_on_veach_door() {
    let mut scene = common::load_small(&shared_dir().join("scenes/veach-door/scene.xml"), 32, 24);
    scene.settings.max_depth = 4;
    gpu_and_cpu_agree(Estimator::Ibpt, &scene, 8, 32, 512);
}

/// The constant environment (c05, whose Mitsuba reference differs): GPU pt and ibpt against
/// the CPU's.
#[test]
fn gpu_pt_and_ibpt_match_the_cpu_under_a_constant_environment() {
    let scene = common::load_small(&shared_dir().join("conformance/scenes/c05_constant_env.xml"), 48, 48);
    gpu_pt_and_ibpt_agree_with_the_cpu(&scene);
}

/// An opacity mask (c13, whose Mitsuba reference counts the mask as a bounce): GPU pt and ibpt
/// against the CPU's, the mask tested with probability its opacity: c13's leaf texture, then a
/// variant with opacity 0.5 (so that a mask handled wrong shows everywhere). In the variant the light is turned to face up from the floor, the leaf
/// lies flat above it and an opaque plate hangs under the ceiling: the ceiling's shadow rays
/// cross the plate first, then the leaf, while the traversal meets the leaf first (the BVH
/// orders by lower coordinate). An any-hit search that stopped at the masked leaf and went on
/// past it would miss the plate (checked: that mutation fails here).
#[test]
fn gpu_pt_and_ibpt_match_the_cpu_with_an_opacity_mask() {
    let plate = r#"<shape type="rectangle"><transform name="to_world"><scale value="0.5"/><rotate x="1" angle="90"/><translate y="0.5"/></transform><ref id="white"/></shape>"#;
    let upside_down = |t: String| {
        t.replace(r#"<rotate x="1" angle="90"/><translate y="0.99"/>"#, r#"<rotate x="1" angle="-90"/><translate y="-0.99"/>"#)
            .replace(r#"<rotate y="1" angle="-30"/><translate y="-0.3" z="0.1"/>"#, r#"<rotate x="1" angle="-90"/><translate y="-0.3"/>"#)
            .replace(r#"<texture name="opacity" type="bitmap"><string name="filename" value="leaf.png"/><boolean name="raw" value="true"/></texture>"#, r#"<float name="opacity" value="0.5"/>"#)
            .replace("</scene>", &format!("{plate}</scene>"))
    };
    let leaf = common::load_small(&shared_dir().join("conformance/scenes/c13_mask_twosided.xml"), 48, 48);
    let variant = common::edited_conformance_scene("c13_mask_twosided", upside_down, 48, 48);
    for scene in [leaf, variant] {
        gpu_pt_and_ibpt_agree_with_the_cpu(&scene);
    }
}

/// A thin lens (c14): GPU pt and ibpt against the CPU's, the camera rays leaving a point of
/// the aperture and the light pass joining its vertices to one (the GPU leaves out the CPU's
/// strategy of light paths hitting the aperture; both weightings are unbiased).
#[test]
fn gpu_pt_and_ibpt_match_the_cpu_through_a_thin_lens() {
    let scene = common::load_small(&shared_dir().join("conformance/scenes/c14_thinlens.xml"), 48, 48);
    gpu_pt_and_ibpt_agree_with_the_cpu(&scene);
}

/// A rough dielectric (c10's GGX glass sphere, and the same with Beckmann microfacets): GPU pt
/// and ibpt against the CPU's; the light pass's refractions carry importance, not radiance
/// (no 1/η² compression), and its connections evaluate the transmission from both sides.
#[test]
fn gpu_pt_and_ibpt_match_the_cpu_through_rough_glass() {
    let ggx = common::load_small(&shared_dir().join("conformance/scenes/c10_roughglass.xml"), 48, 48);
    let beckmann = common::edited_conformance_scene(
        "c10_roughglass",
        |t| t.replace(r#"value="ggx""#, r#"value="beckmann""#),
        48,
        48,
    );
    for scene in [ggx, beckmann] {
        gpu_pt_and_ibpt_agree_with_the_cpu(&scene);
    }
}

/// Sibenik in the seeds' two-lights configuration (scenes/sibenik-two-lights.toml: a real
/// scene of 75k triangles with textures, bump maps, alpha-masked windows, a textured Phong
/// floor and two small disk lights): GPU ibpt against CPU ibpt. Light tracing's splats are
/// heavy-tailed here (image means spread 3 % render to render at 64 spp), so the variance comes
/// from many short renders: 16 a side.
#[test]
fn gpu_ibpt_matches_cpu_ibpt_on_sibenik() {
    let scene = common::load_small(&common::repo_scene("sibenik-two-lights.toml"), 32, 16);
    gpu_and_cpu_agree(Estimator::Ibpt, &scene, 16, 32, 128);
}

/// Distant lights (c04: a directional light and a constant environment): GPU lt against CPU
/// lt, the light pass's rays from the disks behind the scene and the environment seen
/// directly (the Mitsuba comparisons above check pt and ibpt on it).
#[test]
fn gpu_lt_matches_cpu_lt_with_directional_and_environment_lights() {
    let scene = common::load_small(&shared_dir().join("conformance/scenes/c04_directional.xml"), 48, 48);
    gpu_and_cpu_agree(Estimator::Lt, &scene, 8, 64, 64);
}

/// An environment map (c06): GPU lt against CPU lt, the light pass's directions drawn by the
/// map's importance (the Mitsuba comparisons above check pt and ibpt on it); and GPU ibpt
/// against CPU ibpt with c06's cube a mirror and its sphere glass, so that paths from the
/// environment pass delta lobes next to both ends (the MIS's delta branches).
#[test]
fn gpu_lt_and_ibpt_match_the_cpu_under_an_environment_map() {
    let scene = common::load_small(&shared_dir().join("conformance/scenes/c06_envmap.xml"), 48, 48);
    gpu_and_cpu_agree(Estimator::Lt, &scene, 8, 64, 64);
    let specular = |t: String| {
        t.replace(
            r#"<translate x="-0.33" y="-0.4" z="-0.28"/></transform><ref id="white"/>"#,
            r#"<translate x="-0.33" y="-0.4" z="-0.28"/></transform><bsdf type="conductor"/>"#,
        )
        .replace(
            r#"<translate x="0.4" y="-0.6" z="0.3"/></transform><ref id="white"/>"#,
            r#"<translate x="0.4" y="-0.6" z="0.3"/></transform><bsdf type="dielectric"/>"#,
        )
    };
    let scene = common::edited_conformance_scene("c06_envmap", specular, 48, 48);
    assert_eq!(scene.materials.len(), 3, "the mirror and the glass are in");
    gpu_and_cpu_agree(Estimator::Ibpt, &scene, 4, 32, 64);
}

/// c11 at 48×48 with `swap` applied to each material (true where it changed one; `expected`
/// must change), GPU ibpt and GPU lt (the light pass unweighted) against the CPU's.
fn c11_variant_agrees(expected: usize, swap: impl Fn(&mut skelight::material::Material) -> bool) {
    let mut scene = common::load_small(&shared_dir().join("conformance/scenes/c11_plastic.xml"), 48, 48);
    let swapped = scene.materials.iter_mut().map(|m| swap(m) as usize).sum::<usize>();
    let names: Vec<_> = scene.materials.iter().map(|m| &m.name).collect();
    assert_eq!(swapped, expected, "c11's materials changed: {names:?}");
    gpu_and_cpu_agree(Estimator::Lt, &scene, 8, 64, 64);
    gpu_and_cpu_ibpt_agree(&scene, 64, 64);
}

/// A gold-like conductor (the door's copper-ish η, k) with the given microfacets.
fn rough_metal(kind: skelight::material::microfacet::MicrofacetType, alpha: f32) -> skelight::material::Bsdf {
    use skelight::color::Rgb;
    use skelight::material::microfacet::Microfacet;
    skelight::material::Bsdf::RoughConductor(skelight::material::RoughConductor {
        distribution: Microfacet::new(kind, alpha, alpha),
        eta: Rgb { r: 0.2, g: 0.92, b: 1.1 },
        k: Rgb { r: 3.9, g: 2.45, b: 2.14 },
        specular_reflectance: skelight::texture::Texture::Constant(Rgb::splat(1.0)),
    })
}

/// The BSDFs no conformance scene has (Phong, Oren–Nayar, Beckmann microfacets) and a
/// two-sided glossy one: c11 with its white walls Phong (the specular colour a texture), its
/// coloured walls Oren–Nayar and its
/// smooth plastic ball a two-sided Beckmann conductor, GPU ibpt against the CPU's (each BSDF
/// covers much of the image, so that a wrong lobe shows).
#[test]
fn gpu_ibpt_matches_cpu_ibpt_with_phong_oren_nayar_and_beckmann() {
    use skelight::color::Rgb;
    use skelight::material::microfacet::MicrofacetType;
    use skelight::material::{Bsdf, Phong, RoughDiffuse};
    use skelight::texture::Texture;
    let rgb = |r, g, b| Texture::Constant(Rgb { r, g, b });
    c11_variant_agrees(4, |m| {
        m.bsdf = match &m.bsdf {
            Bsdf::Plastic(_) => {
                let c = rough_metal(MicrofacetType::Beckmann, 0.2);
                Bsdf::TwoSided(Box::new(c.clone()), Box::new(c))
            }
            // The specular colour a checkerboard (as sibenik's floor in the seeds' configuration).
            Bsdf::Diffuse(_) if m.name == "white" => {
                let checker = Texture::Checkerboard {
                    color0: skelight::color::Rgb::splat(0.5),
                    color1: skelight::color::Rgb { r: 0.1, g: 0.3, b: 0.2 },
                    to_uv: skelight::texture::UvTransform::scale_offset(4.0, 4.0, 0.0, 0.0),
                };
                Bsdf::Phong(Phong::new(rgb(0.3, 0.3, 0.3), checker, 10.0))
            }
            Bsdf::Diffuse(d) if m.name == "red" || m.name == "green" => {
                Bsdf::RoughDiffuse(RoughDiffuse { reflectance: d.reflectance.clone(), alpha: 0.6 })
            }
            _ => return false,
        };
        true
    });
}

/// Coatings, textures and bump maps (what veach-door has), each over much of the image: c11
/// with its white walls a coating over a checkerboard diffuse, its smooth plastic ball a
/// bump-mapped GGX conductor (α 0.15, as the door's teapot; the height a small bitmap), GPU
/// ibpt against the CPU's.
#[test]
fn gpu_ibpt_matches_cpu_ibpt_with_coatings_textures_and_bump_maps() {
    use skelight::color::Rgb;
    use skelight::material::microfacet::MicrofacetType;
    use skelight::material::{Bsdf, Coating, Diffuse, Perturbation};
    use skelight::texture::{Bitmap, TexFilter, Texture, UvTransform};
    use std::sync::Arc;
    let rgb = |r, g, b| Rgb { r, g, b };
    let mut height = Image::new(8, 8);
    for (i, p) in height.pixels.iter_mut().enumerate() {
        *p = Rgb::splat(((i * 37) % 11) as f32 / 10.0);
    }
    let height = Texture::Bitmap {
        bitmap: Arc::new(Bitmap::new(height, false, TexFilter::Bilinear)),
        to_uv: UvTransform::IDENTITY,
    };
    c11_variant_agrees(2, |m| {
        match &m.bsdf {
            Bsdf::Plastic(_) => {
                m.bsdf = rough_metal(MicrofacetType::Ggx, 0.15);
                m.perturbation = Some(Perturbation::Bump { height: height.clone(), scale: 0.5 });
            }
            Bsdf::Diffuse(_) if m.name == "white" => {
                let checker = Texture::Checkerboard {
                    color0: rgb(0.8, 0.8, 0.8),
                    color1: rgb(0.2, 0.3, 0.6),
                    to_uv: UvTransform::scale_offset(4.0, 4.0, 0.0, 0.0),
                };
                let base = Bsdf::Diffuse(Diffuse { reflectance: checker });
                m.bsdf = Bsdf::Coating(Coating::new(1.5, rgb(1.0, 1.0, 1.0), rgb(0.0, 0.0, 0.0), base));
            }
            _ => return false,
        }
        true
    });
}
