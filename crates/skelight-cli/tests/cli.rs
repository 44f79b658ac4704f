//! The `skelight` command as a user runs it.

use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use skelight::eval::block_means;
use skelight::imageio::Image;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_skelight"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("skelight-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run_ok(args: &[&str]) -> String {
    let out = bin().args(args).output().unwrap();
    let text = String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "skelight {args:?} failed:\n{text}");
    text
}

#[test]
fn default_scene_renders_to_exr_and_png() {
    let d = tmp("default");
    let out = d.join("img.exr");
    let log = run_ok(&["render", "-o", out.to_str().unwrap(), "--spp", "2", "--resolution", "40", "30", "-q"]);
    assert!(log.contains("done: 2 spp"), "{log}");
    let (img, attrs) = Image::load_exr_with_attributes(&out).unwrap();
    assert_eq!((img.width, img.height), (40, 30));
    assert!(attrs.iter().any(|(k, v)| k == "skelight.spp" && *v == 2.0));
    assert!(d.join("img.png").exists());
    assert!(img.mean().max_component() > 0.0);
}

#[test]
fn bad_arguments_fail_with_a_message() {
    for args in [
        vec!["render", "--spp", "0"],
        vec!["render", "/nonexistent/scene.xml"],
        vec!["render", "--integrator", "magic"],
        vec!["render", "--resolution", "0", "10"],
        vec!["render", "--time", "-3"],
        vec!["render", "--max-depth", "-7"],
    ] {
        let out = bin().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains("error"), "{args:?} should fail: {err}");
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    }
}

/// `--debug` writes one image per (s, t) strategy of bpt; rendered with the same random
/// numbers, they add up, pixel by pixel, to the full render.
#[test]
fn bpt_strategy_images_add_up_to_the_render() {
    let d = tmp("strategies");
    let (dir, full) = (d.join("strategies"), d.join("full.exr"));
    run_ok(&[
        "render",
        "-i",
        "bpt",
        "--spp",
        "2",
        "--resolution",
        "24",
        "16",
        "--max-depth",
        "3",
        "--debug",
        dir.to_str().unwrap(),
        "-o",
        full.to_str().unwrap(),
        "-q",
    ]);
    let full = Image::load(&full).unwrap();
    let mut sum = vec![[0.0f64; 3]; full.pixels.len()];
    let mut count = 0;
    for vertices in 2..=4 {
        for s in 0..=vertices {
            let img = Image::load(&dir.join(format!("s{s}_t{}.exr", vertices - s))).unwrap();
            for (acc, p) in sum.iter_mut().zip(&img.pixels) {
                for (a, v) in acc.iter_mut().zip(p.to_array()) {
                    *a += v as f64;
                }
            }
            count += 1;
        }
    }
    assert_eq!(count, 12);
    let csv = std::fs::read_to_string(dir.join("strategies.csv")).unwrap();
    assert_eq!(csv.lines().count(), 13, "{csv}");
    for (acc, p) in sum.iter().zip(&full.pixels) {
        for (a, v) in acc.iter().zip(p.to_array()) {
            assert!((a - v as f64).abs() <= 1e-4 * (v as f64).abs().max(1e-2), "strategies sum to {a}, render {v}");
        }
    }
    let dbg = d.join("pt");
    let out = bin()
        .args(["render", "-i", "pt", "--spp", "1", "--resolution", "8", "8", "-o"])
        .arg(d.join("pt.exr"))
        .arg("--debug")
        .arg(&dbg)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && err.contains("pt offers no --debug output"), "{err}");
    let out = bin()
        .args(["render", "-i", "bpt", "--max-depth", "20", "--spp", "1", "--debug"])
        .arg(&dbg)
        .arg("-o")
        .arg(d.join("b.exr"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("max depth from 1 to 16") && !err.contains("panicked"), "{err}");
}

/// `skelight skeleton` on the default scene writes the skeletons, portals, a report and the
/// pictures; absurd resolutions and boxes are refused with a reason.
#[test]
fn skeleton_writes_graphs_portals_a_report_and_pictures() {
    let d = tmp("skeleton");
    let log = run_ok(&["skeleton", "--resolution", "64", "--picture-size", "160", "-o", d.to_str().unwrap()]);
    assert!(log.contains("total") && log.contains("filtered"), "{log}");
    for f in ["skeleton.json", "skeleton_filtered.json", "skeleton.ply", "skeleton_filtered.ply", "portals.json"] {
        assert!(d.join(f).exists(), "{f} missing");
    }
    // Raw grids, described by grids.json; portals as OBJ quads.
    let grids = std::fs::read_to_string(d.join("grids.json")).unwrap();
    let grids: serde_json::Value = serde_json::from_str(&grids).expect("grids.json parses");
    let dims: Vec<usize> = serde_json::from_value(grids["dims"].clone()).expect("dims");
    for f in ["mapping_filtered.u32", "labels.u32"] {
        let len = std::fs::metadata(d.join(f)).unwrap().len() as usize;
        assert_eq!(len, 4 * dims.iter().product::<usize>(), "{f}");
    }
    let obj = std::fs::read_to_string(d.join("portals.obj")).unwrap();
    assert!(obj.contains("o portal_") && obj.contains("\nf "));
    // Pictures through the scene's camera: the skeleton drawn in its yellow or blue, the
    // two rooms' surfaces mapped to several nodes and regions.
    // Distinct hues: colour divided by its largest channel, so shading and the three
    // brightness levels do not count, and greys (unmapped points, the backdrop) are left out.
    let distinct = |name: &str| {
        let img = Image::load(&d.join(name)).unwrap();
        assert_eq!(img.width.max(img.height), 160, "{name}");
        let mut hues: Vec<[u32; 3]> = img
            .pixels
            .iter()
            .map(|p| [p.r, p.g, p.b])
            .filter(|c| c.iter().cloned().fold(0.0, f32::max) - c.iter().cloned().fold(1.0, f32::min) > 0.1)
            .map(|c| {
                let top = c.iter().cloned().fold(0.0, f32::max);
                c.map(|v| (v / top * 8.0).round() as u32)
            })
            .collect();
        hues.sort_unstable();
        hues.dedup();
        (img, hues.len())
    };
    let (view, _) = distinct("skeleton_view.png");
    // PNG values as stored (sRGB): the yellow (1, 0.8, 0.05) reads about (1, 0.91, 0.25).
    assert!(view.pixels.iter().any(|p| p.r > 0.9 && p.g > 0.75 && p.b < 0.4), "no yellow skeleton drawn");
    for name in ["mapping_filtered.png", "mapping.png", "labels.png"] {
        let (_, n) = distinct(name);
        assert!(n >= 3, "{name}: {n} hues");
    }
    // Anchored at the light and the camera: both placed, reported.
    let a = d.join("anchored");
    run_ok(&[
        "skeleton",
        "--resolution",
        "48",
        "--anchors",
        "lights,camera",
        "--no-pictures",
        "-o",
        a.to_str().unwrap(),
    ]);
    let report = std::fs::read_to_string(a.join("report.txt")).unwrap();
    assert!(report.contains("anchors: 2 of 2 placed"), "{report}");
    // By default only the space holding the camera or a light is analysed; on request, all.
    assert!(report.contains("empty space kept: the components holding the camera or a light"), "{report}");
    let all = d.join("all");
    run_ok(&["skeleton", "--resolution", "48", "--keep-all-space", "--no-pictures", "-o", all.to_str().unwrap()]);
    let report = std::fs::read_to_string(all.join("report.txt")).unwrap();
    assert!(report.contains("every component (--keep-all-space); 0 empty voxels dropped"), "{report}");
    let out = bin().args(["skeleton", "--bounds", "1,0,0,0,1,1", "-o", d.to_str().unwrap()]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("not a box"), "{err}");
    let json = std::fs::read_to_string(d.join("skeleton_filtered.json")).unwrap();
    assert!(json.contains("\"position\"") && json.contains("\"radius\"") && json.contains("\"edges\""));
    for res in ["0", "100000"] {
        let out = bin().args(["skeleton", "--resolution", res, "-o", d.to_str().unwrap()]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains("error") && !err.contains("panicked"), "{res}: {err}");
    }
}

/// Kill a reference render between checkpoints, resume it: the result is identical, bit for
/// bit, to an uninterrupted render with the same seed.
#[test]
fn killed_reference_render_resumes_to_the_identical_image() {
    let d = tmp("resume");
    let (a, b) = (d.join("a.exr"), d.join("b.exr"));
    let args = |out: &Path| -> Vec<String> {
        [
            "reference",
            "-o",
            out.to_str().unwrap(),
            "--resolution",
            "24",
            "16",
            "--spp",
            "3000",
            "--seed",
            "5",
            "--checkpoint-every",
            "0.05",
            "-q",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let mut child = bin().args(args(&a)).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    let ckpt = d.join("a.exr.ckpt");
    let t = Instant::now();
    while !ckpt.exists() && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    let finished_early = child.try_wait().unwrap().is_some();
    child.kill().ok();
    child.wait().unwrap();
    let partial = skelight::checkpoint::Checkpoint::load(&ckpt).unwrap();
    assert!(finished_early || partial.spp < 3000, "the kill should land mid-render");
    let log = run_ok(&args(&a).iter().map(String::as_str).collect::<Vec<_>>());
    assert!(finished_early || log.contains("resuming"), "{log}");
    run_ok(&args(&b).iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(Image::load(&a).unwrap(), Image::load(&b).unwrap());
    // A checkpoint of another render is not silently reused.
    let other = bin()
        .args(["reference", "-o", a.to_str().unwrap(), "--resolution", "24", "16", "--spp", "10", "--seed", "6", "-q"])
        .output()
        .unwrap();
    assert!(!other.status.success() && String::from_utf8_lossy(&other.stderr).contains("another render"));
}

/// Merging k renders of n spp each (different seeds) estimates the same image as one
/// render of k·n spp: block means agree within the noise of the two estimates.
#[test]
fn merged_renders_match_one_longer_render() {
    let d = tmp("merge");
    let mut parts = Vec::new();
    for seed in 1..=4 {
        let p = d.join(format!("part{seed}.exr"));
        run_ok(&[
            "render",
            "-o",
            p.to_str().unwrap(),
            "--resolution",
            "32",
            "24",
            "--spp",
            "64",
            "--seed",
            &seed.to_string(),
            "-q",
        ]);
        parts.push(p);
    }
    let merged = d.join("merged.exr");
    let mut args = vec!["merge".to_string()];
    args.extend(parts.iter().map(|p| p.to_str().unwrap().to_string()));
    args.extend(["-o".into(), merged.to_str().unwrap().into()]);
    run_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let (m, attrs) = Image::load_exr_with_attributes(&merged).unwrap();
    assert!(attrs.iter().any(|(k, v)| k == "skelight.spp" && *v == 256.0));
    let single = d.join("single.exr");
    run_ok(&[
        "render",
        "-o",
        single.to_str().unwrap(),
        "--resolution",
        "32",
        "24",
        "--spp",
        "256",
        "--seed",
        "99",
        "-q",
    ]);
    let s = Image::load(&single).unwrap();
    // The parts' spread estimates, per block, the variance of one 64-spp render; both the
    // merged and the single image have 256 spp, so their difference has variance var64/2.
    // Pooled over all blocks and channels, T = Σ(diff²) / Σ(var64/2) is ≈ 1 without bias,
    // with sampling spread sqrt(2/n + 2/(3n)) (n terms; the variances have 3 dof each).
    let part_blocks: Vec<Vec<[f64; 3]>> = parts.iter().map(|p| block_means(&Image::load(p).unwrap(), 8)).collect();
    let (bm, bs) = (block_means(&m, 8), block_means(&s, 8));
    let (mut num, mut den, mut n) = (0.0f64, 0.0f64, 0.0f64);
    for i in 0..bm.len() {
        for c in 0..3 {
            let mean = part_blocks.iter().map(|b| b[i][c]).sum::<f64>() / 4.0;
            let var64 = part_blocks.iter().map(|b| (b[i][c] - mean).powi(2)).sum::<f64>() / 3.0;
            num += (bm[i][c] - bs[i][c]).powi(2);
            den += var64 / 2.0;
            n += 1.0;
        }
    }
    let t = num / den;
    let spread = (2.0 / n + 2.0 / (3.0 * n)).sqrt();
    assert!(t < 1.0 + 5.0 * spread, "merged vs single: T = {t:.2} (spread {spread:.2})");
    // A mismatched part is refused.
    let odd = d.join("odd.exr");
    run_ok(&["render", "-o", odd.to_str().unwrap(), "--resolution", "8", "8", "--spp", "1", "-q"]);
    let out = bin()
        .args(["merge", parts[0].to_str().unwrap(), odd.to_str().unwrap(), "-o", d.join("x.exr").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("sizes differ"));
}

/// `render --shard K/N` renders a slice of the samples; `merge` of all N gives the single
/// render (f64 sums added in another order: equal within one f32 rounding) and refuses a
/// missing shard, a shard given twice, a shard of another render and a plain image.
#[test]
fn shards_merge_into_the_single_render() {
    let d = tmp("shards");
    let render = |out: &Path, extra: &[&str]| {
        let mut args =
            vec!["render", "-o", out.to_str().unwrap(), "-i", "bpt", "--resolution", "32", "24", "--spp", "9"];
        args.extend_from_slice(extra);
        args.push("-q");
        run_ok(&args)
    };
    let single = d.join("single.exr");
    render(&single, &[]);
    let shards: Vec<PathBuf> = (0..3).map(|k| d.join(format!("s{k}.exr"))).collect();
    for (k, s) in shards.iter().enumerate() {
        let log = render(s, &["--shard", &format!("{k}/3")]);
        assert!(log.contains("done: 3 spp"), "{log}");
    }
    let merged = d.join("merged.exr");
    let p = |p: &PathBuf| p.to_str().unwrap().to_string();
    let log = run_ok(&["merge", &p(&shards[2]), &p(&shards[0]), &p(&shards[1]), "-o", &p(&merged)]);
    assert!(log.contains("merged 3 shards (9 spp in all)"), "{log}");
    let (m, attrs) = Image::load_exr_with_attributes(&merged).unwrap();
    assert!(attrs.iter().any(|(k, v)| k == "skelight.spp" && *v == 9.0));
    let s = Image::load(&single).unwrap();
    for (a, b) in m.pixels.iter().zip(&s.pixels) {
        for (x, y) in a.to_array().into_iter().zip(b.to_array()) {
            assert!((x - y).abs() <= 2e-7 * y.abs(), "merged {x} vs single {y}");
        }
    }
    let other = d.join("other.exr");
    render(&other, &["--shard", "1/3", "--seed", "7"]);
    for (inputs, message) in [
        (vec![p(&shards[0]), p(&shards[2])], "shards [1] of 3 are missing"),
        (vec![p(&shards[0]), p(&shards[1]), p(&shards[1]), p(&shards[2])], "are both shard 1/3"),
        (vec![p(&shards[0]), p(&other), p(&shards[2])], "is not a shard of"),
        (vec![p(&shards[0]), p(&single)], "is not a shard but other inputs are"),
    ] {
        let out = bin().arg("merge").args(&inputs).args(["-o", &p(&d.join("x.exr"))]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(message), "{inputs:?}: {err}");
    }
    for bad in [
        vec!["--spp", "9", "--shard", "3/3"],
        vec!["--spp", "9", "--shard", "0/10"],
        vec!["--shard", "0/2", "--time", "1"],
    ] {
        let mut args = vec!["render", "-o", "/nonexistent/x.exr", "--resolution", "8", "8"];
        args.extend(bad.iter().copied());
        let out = bin().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains("shard") && !err.contains("panicked"), "{bad:?}: {err}");
    }
}

/// A tiny equal-time study writes every part of the report, with consistent numbers.
#[test]
fn compare_writes_a_complete_report() {
    let d = tmp("compare");
    let reference = d.join("ref.exr");
    run_ok(&[
        "reference",
        "-o",
        reference.to_str().unwrap(),
        "--resolution",
        "24",
        "16",
        "--spp",
        "512",
        "--seed",
        "3",
        "-q",
    ]);
    let out = d.join("report");
    let log = run_ok(&[
        "compare",
        "--reference",
        reference.to_str().unwrap(),
        "--integrators",
        "pt,pt",
        "--time",
        "0.4",
        "-o",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert!(log.contains("report:"), "{log}");
    for f in [
        "errors.csv",
        "errors.json",
        "error_vs_time.svg",
        "error_vs_time.png",
        "pt.exr",
        "pt#2.exr",
        "pt_error.png",
        "side_by_side.png",
        "time_to_error.csv",
        "report.html",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let csv = std::fs::read_to_string(out.join("errors.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert!(rows.iter().filter(|r| r.starts_with("pt,")).count() >= 1 && rows.iter().any(|r| r.starts_with("pt#2,")));
    // Errors fall as samples accumulate (on average over the run).
    let relmse: Vec<f64> =
        rows.iter().filter(|r| r.starts_with("pt,")).map(|r| r.split(',').nth(6).unwrap().parse().unwrap()).collect();
    assert!(relmse.last().unwrap() <= relmse.first().unwrap(), "{relmse:?}");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("data:image/png;base64,") && html.contains("speed-up"));
    // The reference must match the render's size.
    let bad = bin()
        .args([
            "compare",
            "--reference",
            reference.to_str().unwrap(),
            "--resolution",
            "8",
            "8",
            "--time",
            "0.1",
            "-o",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    // A bad name fails before the first run, not after the runs named before it (pt here
    // would print its progress, "pt: …/2 s"); a GPU estimator this build cannot run is one.
    for bad in ["nosuch", "gpu:bpt"] {
        let names = format!("pt,{bad}");
        let args = ["compare", "--reference", reference.to_str().unwrap(), "--integrators", &names, "--time", "2"];
        let out = bin().args(args).args(["-o", d.join("bad").to_str().unwrap()]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{bad}: {err}");
        assert!(err.contains(bad) && !err.contains("/2 s"), "{bad} was not refused before pt ran: {err}");
    }
}

/// Runs `skelight args`, which must fail with an error (not a panic or an abort) whose
/// message mentions every one of `parts`.
fn run_fails(args: &[&str], parts: &[&str]) {
    let out = bin().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "skelight {args:?} should fail with an error: {err}");
    assert!(!err.contains("panicked"), "skelight {args:?} panicked: {err}");
    for p in parts {
        assert!(err.contains(p), "skelight {args:?}: {err:?} does not mention {p:?}");
    }
}

/// An EXR whose header claims a data window of 10^8 × 10^8 pixels around one scan line of
/// data (and no chunk count, which few writers give): decoding it would first allocate
/// 1.2e17 bytes.
fn huge_window_exr(path: &Path) {
    Image::new(1, 1).save_exr(path).unwrap();
    let mut bytes = std::fs::read(path).unwrap();
    let count = b"chunkCount\0";
    let at = bytes.windows(count.len()).position(|w| w == count).unwrap();
    bytes[at..at + count.len()].copy_from_slice(b"chunkCounx\0");
    let key = b"dataWindow\0box2i\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    for (k, v) in [0i32, 0, 99_999_999, 99_999_999].iter().enumerate() {
        bytes[at + 4 * k..at + 4 * k + 4].copy_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

/// A mesh vertex at 1e30 and no camera: both commands that load a scene say so.
#[test]
fn render_and_skeleton_refuse_far_off_geometry() {
    let d = tmp("far");
    let obj = d.join("far.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 1e30\nf 1 2 3\n").unwrap();
    let (obj, out) = (obj.to_str().unwrap(), d.join("out"));
    let out = out.to_str().unwrap();
    run_fails(&["render", obj, "--spp", "1", "-o", &format!("{out}.exr"), "-q"], &["far.obj", "too far to render"]);
    run_fails(&["skeleton", obj, "--resolution", "16", "-o", out, "--quiet"], &["far.obj", "too far to render"]);
}

#[test]
fn merge_and_diff_refuse_impossible_and_non_finite_inputs() {
    let d = tmp("badexr");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (ok, huge, nan, inf) = (d.join("ok.exr"), d.join("huge.exr"), d.join("nan.exr"), d.join("inf.exr"));
    let out = s(&d.join("out.exr"));
    Image::new(4, 4).save_exr_with(&ok, &[("skelight.spp", 4.0)]).unwrap();
    huge_window_exr(&huge);
    run_fails(&["merge", &s(&ok), &s(&huge), "-o", &out], &["huge.exr", "data window", "more than"]);
    run_fails(&["diff", &s(&huge), &s(&ok)], &["huge.exr", "data window"]);
    for (p, v) in [(&nan, f32::NAN), (&inf, f32::INFINITY)] {
        let mut img = Image::new(4, 4);
        img.pixels[5] = skelight::color::Rgb::splat(v);
        img.save_exr_with(p, &[("skelight.spp", 4.0)]).unwrap();
        let name = p.file_name().unwrap().to_str().unwrap();
        run_fails(&["merge", &s(&ok), &s(p), "-o", &out], &[name, "1 pixels are NaN or infinite", "x 1, y 1"]);
        run_fails(&["diff", &s(p), &s(&ok)], &[name, "NaN or infinite"]);
        run_fails(&["diff", &s(&ok), &s(p)], &[name, "NaN or infinite"]);
    }
    assert!(!d.join("out.exr").exists());
    for spp in [0.0, -1.0, 2.5, f64::NAN] {
        let p = d.join("spp.exr");
        Image::new(4, 4).save_exr_with(&p, &[("skelight.spp", spp)]).unwrap();
        for extra in [&[][..], &["--equal-weights"][..]] {
            let mut args = vec!["merge".to_string(), s(&ok), s(&p), "-o".into(), out.clone()];
            args.extend(extra.iter().map(|a| a.to_string()));
            run_fails(
                &args.iter().map(String::as_str).collect::<Vec<_>>(),
                &["spp.exr", "not a positive whole number"],
            );
        }
    }
    run_ok(&["merge", &s(&ok), &s(&ok), "-o", &out]);
}

/// The registry reaches the command line: `render --help` lists skelpt's parameters,
/// `--param` sets them, bad ones fail with a message naming the parameter, the preparation is
/// reported, and `--debug` writes the guidance pictures.
#[test]
fn estimator_parameters_from_the_command_line() {
    let help = run_ok(&["render", "--help"]);
    assert!(help.contains("skelpt") && help.contains("c_skel") && help.contains("adaptive"), "{help}");
    // `--integrator`'s own line lists every estimator of the registry.
    let line = run_ok(&["render", "-h"]);
    let line = line.lines().skip_while(|l| !l.contains("--integrator")).take(3).collect::<Vec<_>>().join(" ");
    for name in skelight::estimators::names() {
        assert!(line.contains(name), "--integrator's help misses {name}: {line}");
    }
    for (param, expected) in
        [("strength=-2", "strength"), ("nonsense=1", "no parameter 'nonsense'"), ("novalue", "name=value")]
    {
        let out = bin().args(["render", "-i", "skelpt", "--param", param, "--spp", "1"]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(expected) && !err.contains("panicked"), "{param}: {err}");
    }
    let d = tmp("skelpt");
    let (dbg, img) = (d.join("dbg"), d.join("img.exr"));
    let text = run_ok(&[
        "render",
        "-i",
        "skelpt",
        "--param",
        "strength=4",
        "--spp",
        "1",
        "--resolution",
        "32",
        "24",
        "--debug",
        dbg.to_str().unwrap(),
        "-o",
        img.to_str().unwrap(),
    ]);
    assert!(text.contains("preparation:") && text.contains("strength=4"), "{text}");
    for f in ["importance_view.png", "node_per_pixel.png", "importance.json"] {
        assert!(dbg.join(f).exists(), "{f} missing");
    }
}

/// Renders with `--debug` into a fresh folder: the output and the folder.
fn render_distributions(estimator: &str) -> (String, PathBuf, PathBuf) {
    let d = tmp(estimator);
    let (dbg, img) = (d.join("dbg"), d.join("img.exr"));
    let (dbg_s, img_s) = (dbg.to_str().unwrap(), img.to_str().unwrap());
    let args = ["render", "-i", estimator, "-P", "candidates=64", "--spp", "2", "--resolution", "32", "24"];
    let text = run_ok(&[&args[..], &["--debug", dbg_s, "-o", img_s]].concat());
    for f in ["V.exr", "U.png", "C.exr", "fallback.exr", "unresampled.exr", "distributions.csv"] {
        assert!(dbg.join(f).exists(), "{f} missing");
    }
    let csv = std::fs::read_to_string(dbg.join("distributions.csv")).unwrap();
    assert!(csv.starts_with("part,mean_r") && csv.lines().count() == 6, "{csv}");
    (text, dbg, img)
}

/// `--debug` writes skelbpt's per-distribution images, their means and the nodes picture;
/// the per-iteration cost of its tables is reported; it refuses time budgets (the parts
/// must see the same samples).
#[test]
fn skelbpt_distribution_pictures() {
    let (text, dbg, img) = render_distributions("skelbpt");
    let (dbg_s, img_s) = (dbg.to_str().unwrap(), img.to_str().unwrap());
    assert!(text.contains("resampling tables:") && text.contains("per iteration"), "{text}");
    assert!(dbg.join("nodes_view.png").exists(), "nodes_view.png missing");
    let out = bin().args(["render", "-i", "skelbpt", "--time", "1", "--debug", dbg_s, "-o", img_s]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--debug") && err.contains("--spp") && !err.contains("panicked"),
        "{err}"
    );
}

/// icbpt takes `--debug` too (no nodes picture: it has no skeleton), and
/// reports its records' tables.
#[test]
fn icbpt_distribution_pictures() {
    let (text, dbg, _) = render_distributions("icbpt");
    assert!(text.contains("importance records") && text.contains("per iteration"), "{text}");
    assert!(!dbg.join("nodes_view.png").exists());
}

/// Issue 59, "output onto a device node" and "output clobbering": an output that exists and
/// is not a regular file is refused before anything renders (a FIFO, a folder, a device
/// named without extension), a link is written through, `-o x.png` keeps the EXR as x.exr,
/// and no output replaces an input of the same run (the scene, a merged part).
#[test]
fn outputs_never_replace_devices_folders_or_inputs() {
    let d = tmp("outputs");
    let path = |name: &str| d.join(name).to_str().unwrap().to_string();
    let render = ["render", "--spp", "1", "--resolution", "8", "6", "-q", "-o"];
    let fifo = d.join("pipe.exr");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    std::fs::create_dir(d.join("folder.exr")).unwrap();
    for target in ["pipe.exr", "folder.exr", "folder.png"] {
        std::fs::create_dir_all(d.join("folder.png")).unwrap();
        run_fails(&[&render[..], &[&path(target)]].concat(), &["not a regular file"]);
    }
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    // A name without extension that is a device: refused, nothing written beside it.
    let dev = d.join("device");
    std::os::unix::fs::symlink("/dev/null", &dev).unwrap();
    run_fails(&[&render[..], &[&path("device")]].concat(), &["not a regular file"]);
    assert!(!d.join("device.exr").exists() && !d.join("device.png").exists());

    run_ok(&[&render[..], &[&path("x.png")]].concat());
    assert!(Image::load_exr_with_attributes(&d.join("x.exr")).is_ok(), "-o x.png must keep the EXR");
    assert_eq!(&std::fs::read(d.join("x.png")).unwrap()[1..4], b"PNG");

    std::fs::write(d.join("kept.exr"), b"mine").unwrap();
    std::os::unix::fs::symlink(d.join("kept.exr"), d.join("link.exr")).unwrap();
    run_ok(&[&render[..], &[&path("link.exr")]].concat());
    assert!(std::fs::symlink_metadata(d.join("link.exr")).unwrap().file_type().is_symlink());
    assert!(Image::load(&d.join("kept.exr")).is_ok(), "the link's target holds the render");

    let scene = d.join("scene.xml");
    std::fs::write(&scene, "<scene version=\"3.0.0\"/>").unwrap();
    run_fails(&[&render[..], &[&path("scene.xml")]].concat(), &["scene.xml", ".exr", ".png"]);
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), "<scene version=\"3.0.0\"/>");
    let x = path("x.exr");
    run_fails(&["merge", &x, "-o", &x], &["would replace the input"]);
    run_fails(&["merge", &x, "-o", &path("x.png")], &["would replace the input"]);
    // compare refuses a file as its report folder before the timed runs, not after them.
    let started = Instant::now();
    run_fails(&["compare", "--reference", &x, "--time", "30", "-o", &path("kept.exr")], &["not a folder"]);
    assert!(started.elapsed() < Duration::from_secs(20));
}

/// Issue 59, "command line": `--max-depth -1` (documented as unbounded) was refused by the
/// argument parser, `--time 1e20` read as the unit `e20`, `--exposure nan` and
/// `diff --max-error nan` were accepted, `--time 0.000001` wrote a black 0-spp image with exit 0.
#[test]
fn command_line_numbers_mean_what_they_say() {
    let d = tmp("numbers");
    let out = d.join("x.exr");
    let o = out.to_str().unwrap();
    let base = ["render", "--resolution", "8", "6", "-q", "-o", o];
    run_ok(&[&base[..], &["--spp", "1", "--max-depth", "-1"]].concat());
    run_ok(&[&base[..], &["--time", "2e-1s"]].concat());
    // The argument parser's refusals exit with 2.
    let refused = |args: &[&str], part: &str| {
        let out = bin().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(part) && !err.contains("panicked"), "{args:?}: {err}");
    };
    refused(&[&base[..], &["--time", "1e20"]].concat(), "at most 1e8 s");
    refused(&[&base[..], &["--spp", "1", "--exposure", "nan"]].concat(), "not a finite number");
    run_ok(&[&base[..], &["--spp", "1", "--exposure", "-2"]].concat());
    refused(&["diff", o, o, "--max-error", "nan"], "not a finite number");
    refused(&["diff", o, o, "--max-error", "0"], "must be above 0");
    let late = d.join("late.exr");
    let out = bin().args([&base[..6], &[late.to_str().unwrap(), "--time", "0.000001"]].concat()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "a render of no sample exited 0: {err}");
    assert!(err.contains("nothing was rendered") && !late.exists(), "{err}");
}
