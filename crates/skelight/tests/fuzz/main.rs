//! Mutation fuzzing of every parser, on stable Rust: seed files (small ones written here and
//! ../shared's conformance scenes) are mutated by a seeded mutator and read as a user's
//! files would be. Each case must end in a scene or an error within a time bound, without a
//! panic, an abort or an allocation the file cannot justify. Failing inputs are kept in
//! the temporary folder and named in the report.
//!
//! `SKELIGHT_FUZZ_CASES` sets the cases per parser (default 60, a few seconds in all);
//! `SKELIGHT_FUZZ_SEED` changes the mutations (default 1); `SKELIGHT_FUZZ_ONLY=gltf,glb`
//! runs only the parsers named.

#[path = "../common/mod.rs"]
mod common;
mod mutate;
mod seeds;

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use skelight::eval;
use skelight::imageio::Image;
use skelight::scene::load::load;

/// Counts the largest single allocation while a case runs, and refuses absurd ones (the
/// process then aborts, and the newest case file is the culprit).
struct Counting;

static LARGEST: AtomicUsize = AtomicUsize::new(0);
const REFUSED: usize = 4 << 30;

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        if layout.size() > REFUSED {
            return std::ptr::null_mut();
        }
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        if layout.size() > REFUSED {
            return std::ptr::null_mut();
        }
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        if new_size > REFUSED {
            return std::ptr::null_mut();
        }
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// One parser under test: the file its cases are written to, how it is read, its seeds.
struct Target {
    name: &'static str,
    /// File the mutated bytes are written to, in the case folder.
    file: &'static str,
    text: bool,
    seeds: Vec<Vec<u8>>,
    read: fn(&Path) -> Result<(), String>,
}

fn scene(p: &Path) -> Result<(), String> {
    load(p, &[]).map(|_| ()).map_err(|e| e.to_string())
}

fn image(p: &Path) -> Result<(), String> {
    Image::load(p).map_err(|e| e.to_string())?;
    Image::load_alpha_or_luminance(p).map(|_| ()).map_err(|e| e.to_string())
}

/// What `skelight merge` and `skelight diff` do with an input, against a valid image.
fn merge_and_diff(p: &Path) -> Result<(), String> {
    let (img, _) = Image::load_exr_with_attributes(p).map_err(|e| e.to_string())?;
    if img.non_finite().is_some() {
        return Err("non-finite".into());
    }
    let other = Image::new(img.width, img.height);
    eval::merge_weighted(&[(img.clone(), 2.0), (other.clone(), 1.0)])?;
    eval::metrics(&img, &other).map_err(|e| e.to_string())?;
    eval::error_image(&img, &other, 1.0).map_err(|e| e.to_string())?;
    Ok(())
}

/// Companion files every case folder holds: meshes, textures and an included scene.
fn companions() -> Vec<(&'static str, Vec<u8>)> {
    let shared = common::shared_dir().join("conformance/scenes");
    let tetra = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n".to_vec();
    vec![
        ("sphere.obj", tetra),
        ("m.obj", seeds::obj_files().remove(1)),
        ("m.mtl", seeds::mtl_files().remove(0)),
        (
            "host.obj",
            b"mtllib case.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl tex\nf 1/1 2/1 3/1\nusemtl red\nf 3 2 1\n"
                .to_vec(),
        ),
        ("m.ply", seeds::ply_files().remove(1)),
        ("m.serialized", seeds::serialized_files().remove(1)),
        (
            "ser.xml",
            br#"<scene version="3.0.0"><shape type="serialized"><string name="filename" value="case.serialized"/>
<integer name="shape_index" value="0"/></shape></scene>"#
                .to_vec(),
        ),
        ("inc.xml", br#"<scene version="3.0.0"><shape type="cube"/></scene>"#.to_vec()),
        ("checker.png", std::fs::read(shared.join("checker.png")).unwrap()),
        ("leaf.png", std::fs::read(shared.join("leaf.png")).unwrap()),
        ("sky.exr", std::fs::read(shared.join("sky.exr")).unwrap()),
    ]
}

fn targets(scratch: &Path) -> Vec<Target> {
    let (gltf, glb) = seeds::gltf_parts();
    let exr = seeds::exr_files(scratch);
    let t = |name, file, text, seeds, read| Target { name, file, text, seeds, read };
    vec![
        t("mitsuba-xml", "case.xml", true, seeds::xml_files(), scene),
        t("obj", "case.obj", true, seeds::obj_files(), scene),
        t("mtl", "case.mtl", true, seeds::mtl_files(), |d| scene(&d.with_file_name("host.obj"))),
        t("ply", "case.ply", false, seeds::ply_files(), scene),
        t("serialized", "case.serialized", false, seeds::serialized_files(), |d| scene(&d.with_file_name("ser.xml"))),
        t("gltf", "case.gltf", true, vec![gltf.into_bytes()], scene),
        t("glb", "case.glb", false, vec![glb], scene),
        t("toml", "case.toml", true, seeds::toml_files(), scene),
        t("exr-texture", "case.exr", false, exr.clone(), image),
        t("png", "case.png", false, seeds::png_files(), image),
        t("jpeg", "case.jpg", false, seeds::jpeg_files(), image),
        t("merge-diff-exr", "case.exr", false, exr, merge_and_diff),
    ]
}

fn env_number(name: &str, default: u64) -> u64 {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

/// Runs `read` on a thread of a 2 MiB stack (as test threads have) within `limit`: what it
/// returned, or what went wrong (a panic or a hang).
fn run_case(read: fn(&Path) -> Result<(), String>, path: &Path, limit: Duration) -> Result<Result<(), String>, String> {
    let (tx, rx) = std::sync::mpsc::channel();
    let p = path.to_path_buf();
    std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(move || {
            let r = std::panic::catch_unwind(|| read(&p));
            let _ = tx.send(r.map_err(|e| {
                e.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| e.downcast_ref::<String>().cloned())
            }));
        })
        .unwrap();
    match rx.recv_timeout(limit) {
        Ok(Ok(result)) => Ok(result),
        Ok(Err(msg)) => Err(format!("panicked: {}", msg.unwrap_or_default())),
        Err(_) => Err(format!("did not finish within {limit:?}")),
    }
}

#[test]
fn every_parser_survives_mutated_input() {
    let cases = env_number("SKELIGHT_FUZZ_CASES", 60);
    let seed = env_number("SKELIGHT_FUZZ_SEED", 1);
    let base = std::env::temp_dir().join(format!("skelight-fuzz-{}", std::process::id()));
    let failures_dir = std::env::temp_dir().join("skelight-fuzz-failures");
    std::fs::create_dir_all(&base).unwrap();
    let companions = companions();
    let mut failures: Vec<String> = Vec::new();
    let only = std::env::var("SKELIGHT_FUZZ_ONLY").ok();
    // Panics are caught and reported per case with their message: keep the log readable.
    std::panic::set_hook(Box::new(|_| {}));
    for (ti, target) in targets(&base).into_iter().enumerate() {
        if only.as_ref().is_some_and(|o| !o.split(',').any(|n| n == target.name)) {
            continue;
        }
        let dir = base.join(target.name);
        std::fs::create_dir_all(&dir).unwrap();
        for (name, bytes) in &companions {
            std::fs::write(dir.join(name), bytes).unwrap();
        }
        let companion_bytes: usize = companions.iter().map(|c| c.1.len()).sum();
        let mut rng = mutate::Rng::new(seed.wrapping_mul(0x100).wrapping_add(ti as u64));
        let (start, mut loaded, mut largest) = (Instant::now(), 0u64, 0usize);
        for case in 0..cases {
            let input = if case < target.seeds.len() as u64 {
                target.seeds[case as usize].clone()
            } else {
                mutate::mutate(&mut rng, &target.seeds, target.text)
            };
            let path = dir.join(target.file);
            std::fs::write(&path, &input).unwrap();
            LARGEST.store(0, Ordering::Relaxed);
            let outcome = run_case(target.read, &path, Duration::from_secs(10));
            let allocated = LARGEST.load(Ordering::Relaxed);
            largest = largest.max(allocated);
            // What a file can justify: working memory, plus a generous multiple of its size
            // (decompression, tessellation, per-vertex arrays).
            let allowed = (256 << 20) + 1024 * (input.len() + companion_bytes);
            let problem = match outcome {
                Err(e) => Some(e),
                Ok(_) if allocated > allowed => Some(format!("allocated {allocated} bytes at once")),
                // Seeds must load: otherwise their mutations explore little.
                Ok(Err(e)) if case < target.seeds.len() as u64 => Some(format!("is a seed and does not load: {e}")),
                Ok(result) => {
                    loaded += result.is_ok() as u64;
                    None
                }
            };
            if let Some(problem) = problem {
                std::fs::create_dir_all(&failures_dir).unwrap();
                let keep = failures_dir.join(format!("{}-{seed}-{case}-{}", target.name, target.file));
                std::fs::write(&keep, &input).unwrap();
                failures.push(format!("{}: case {case} {problem} (input kept as {})", target.name, keep.display()));
                if problem.starts_with("did not finish") {
                    break;
                }
            }
        }
        eprintln!(
            "fuzz {:<15} {cases} cases ({loaded} loaded, the rest refused with an error) in {:.1} s, largest allocation {:.1} MB",
            target.name,
            start.elapsed().as_secs_f64(),
            largest as f64 / 1e6
        );
    }
    let _ = std::fs::remove_dir_all(&base);
    let _ = std::panic::take_hook();
    assert!(failures.is_empty(), "{} failing cases:\n{}", failures.len(), failures.join("\n"));
}
