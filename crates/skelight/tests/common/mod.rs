//! Shared helpers for integration tests: locating `../shared`, rendering, and the
//! statistical comparison against references described in shared/conformance/README.md.
#![allow(dead_code)]

use std::path::PathBuf;

use skelight::eval::{block_means, relative_block_t_statistic};
use skelight::film::Film;
use skelight::imageio::Image;
use skelight::integrator::{render, Integrator, RenderOptions};
use skelight::scene::load::load;
use skelight::scene::Scene;

/// A scene file of this repository's `scenes/`.
pub fn repo_scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name)
}

/// A scene loaded and set to a `w`×`h` film.
pub fn load_small(path: &std::path::Path, w: usize, h: usize) -> Scene {
    let mut s = load(path, &[]).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    s.set_resolution(w, h);
    s
}

/// The project's `../shared` folder (beside the repository), which CI provides.
pub fn shared_dir() -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared");
    assert!(
        p.join("conformance").exists(),
        "../shared/conformance not found next to the repository ({}); the tests need it",
        p.display()
    );
    p
}

pub fn render_spp(scene: &Scene, integrator: &mut dyn Integrator, spp: u32, seed: u64) -> Film {
    let opts = RenderOptions { spp: Some(spp), time: None, seed, threads: 0 };
    render(scene, integrator, &opts, None, |_, _| true).expect("render").film
}

/// Per-channel mean of a film's image and its standard error, from the per-pixel sample
/// variances (pixels are independent with a box filter).
pub fn film_mean_se(film: &Film) -> ([f64; 3], [f64; 3]) {
    let (img, var) = (film.image(), film.variance_image());
    let n = img.pixels.len() as f64;
    let mut m = [0.0; 3];
    let mut se = [0.0; 3];
    for c in 0..3 {
        m[c] = img.pixels.iter().map(|p| p.to_array()[c] as f64).sum::<f64>() / n;
        se[c] = var.pixels.iter().map(|p| p.to_array()[c] as f64).sum::<f64>().sqrt() / n;
    }
    (m, se)
}

/// Per 8×8 block and channel: the mean over independent renders (batches) of one estimator
/// and the variance of that mean, from the batches' spread (s²/n).
fn batch_block_stats(batches: &[&Image]) -> Vec<[(f64, f64); 3]> {
    assert!(batches.len() >= 2, "the spread needs two renders at least");
    let blocks: Vec<_> = batches.iter().map(|i| block_means(i, 8)).collect();
    let n = blocks.len() as f64;
    (0..blocks[0].len())
        .map(|b| {
            std::array::from_fn(|c| {
                let mean = blocks.iter().map(|x| x[b][c]).sum::<f64>() / n;
                let s2 = blocks.iter().map(|x| (x[b][c] - mean).powi(2)).sum::<f64>() / (n - 1.0);
                (mean, s2 / n)
            })
        })
        .collect()
}

/// Per-channel mean of independent renders and its standard error from their 8×8 blocks'
/// spread — usable for splat-only estimators, which record no pixel variance.
pub fn batch_mean_se(batches: &[&Image]) -> ([f64; 3], [f64; 3]) {
    let stats = batch_block_stats(batches);
    let nb = stats.len() as f64;
    let m = std::array::from_fn(|c| stats.iter().map(|b| b[c].0).sum::<f64>() / nb);
    let se = std::array::from_fn(|c| stats.iter().map(|b| b[c].1).sum::<f64>().sqrt() / nb);
    (m, se)
}

/// The two-render case of [`batch_mean_se`].
pub fn pair_mean_se(a: &Image, b: &Image) -> ([f64; 3], [f64; 3]) {
    batch_mean_se(&[a, b])
}

/// Block T between two estimators, each rendered several times: Σ_b (mean_a − mean_b)² over
/// Σ_b of both means' variances from their own renders' spread. ≈ 1 when the two estimate the
/// same image. More renders make the variance estimate robust against the heavy tails of
/// light tracing's splats (with two, a pair that happens to agree makes T large).
pub fn batch_block_t(a: &[&Image], b: &[&Image]) -> f64 {
    let (sa, sb) = (batch_block_stats(a), batch_block_stats(b));
    let (mut num, mut den) = (0.0, 0.0);
    for (x, y) in sa.iter().zip(&sb) {
        for c in 0..3 {
            num += (x[c].0 - y[c].0).powi(2);
            den += x[c].1 + y[c].1;
        }
    }
    if den > 0.0 {
        num / den
    } else {
        1.0
    }
}

/// The two-renders-each case of [`batch_block_t`].
pub fn pair_block_t(a1: &Image, a2: &Image, b1: &Image, b2: &Image) -> f64 {
    batch_block_t(&[a1, a2], &[b1, b2])
}

/// Outcome of comparing two independent renders with a reference.
#[derive(Debug)]
pub struct Comparison {
    /// Block-mean statistic: ≈ 1 for an unbiased estimator.
    pub t: f64,
    /// Per-channel z-scores of the image mean against the reference mean.
    pub z: [f64; 3],
    pub mean: [f64; 3],
    /// Per channel, the variance of our averaged image mean and of the reference's mean.
    pub var: [f64; 3],
    pub var_ref: [f64; 3],
}

/// Compares films `fa`, `fb` (independent seeds, `spp` each) with `reference`, whose mean is
/// `ref_mean` and whose per-pixel variance is `reference_variance` (see [`reference_noise`]).
pub fn compare(fa: &Film, fb: &Film, reference: &Image, reference_variance: &Image, ref_mean: [f64; 3]) -> Comparison {
    let (a, b) = (fa.image(), fb.image());
    let (va, vb) = (fa.variance_image(), fb.variance_image());
    let t = relative_block_t_statistic(&a, &b, reference, Some(reference_variance), 8);
    let (ba, bb) = (block_means(&a, 8), block_means(&b, 8));
    let (bva, bvb) = (block_means(&va, 8), block_means(&vb, 8));
    let nb = ba.len() as f64;
    let per_block = 64.0;
    let npix = reference_variance.pixels.len() as f64;
    let mut z = [0.0; 3];
    let mut mean = [0.0; 3];
    let (mut vars, mut vars_ref) = ([0.0; 3], [0.0; 3]);
    for c in 0..3 {
        let m: f64 = ba.iter().zip(&bb).map(|(x, y)| 0.5 * (x[c] + y[c])).sum::<f64>() / nb;
        // Variance of the averaged render's mean, from the per-pixel sample variances and
        // from the two renders' block differences. Per-pixel variances miss the noise of
        // splats (light paths land anywhere), so the larger of the two is used.
        let from_pixels: f64 =
            bva.iter().zip(&bvb).map(|(x, y)| (x[c] + y[c]) / 4.0 / per_block).sum::<f64>() / (nb * nb);
        let from_blocks: f64 = ba.iter().zip(&bb).map(|(x, y)| (x[c] - y[c]).powi(2) / 4.0).sum::<f64>() / (nb * nb);
        let var = from_pixels.max(from_blocks);
        let var_ref = reference_variance.pixels.iter().map(|p| p.to_array()[c] as f64).sum::<f64>() / (npix * npix);
        z[c] = (m - ref_mean[c]).abs() / (var + var_ref).sqrt().max(1e-12 * ref_mean[c].abs().max(1e-6));
        mean[c] = m;
        (vars[c], vars_ref[c]) = (var, var_ref);
    }
    Comparison { t, z, mean, var: vars, var_ref: vars_ref }
}

/// How hard the statistical tests look. The default tier gives each estimator the samples
/// its own variance needs to see a bias of `target_bias` of the image mean (in at least
/// 99 % of runs, see [`POWER_Z`]), between `pilot_spp` and `max_spp`; `--full`
/// (`SKELIGHT_TEST_TIER=full`, set by `scripts/test.sh --full`) starts where the suite used
/// to stand (128 samples) and looks for a 4× smaller bias.
#[derive(Clone, Copy, Debug)]
pub struct Tier {
    pub name: &'static str,
    /// Relative bias of the image mean the test must see.
    pub target_bias: f64,
    pub pilot_spp: u32,
    pub max_spp: u32,
}

pub fn tier() -> Tier {
    match std::env::var("SKELIGHT_TEST_TIER").as_deref() {
        Ok("full") => Tier { name: "full", target_bias: 0.005, pilot_spp: 128, max_spp: 512 },
        Ok("default") | Err(_) => Tier { name: "default", target_bias: 0.02, pilot_spp: 4, max_spp: 128 },
        Ok(other) => panic!("SKELIGHT_TEST_TIER={other}: expected default or full"),
    }
}

/// A bias of b standard errors is seen (z > [`Z_LIMIT`]) in 99 % of runs when
/// b ≥ Z_LIMIT + POWER_Z (the normal's 99th percentile).
pub const POWER_Z: f64 = 2.326;

/// What a test against a reference decided, and what it could have seen.
#[derive(Debug)]
pub struct Verdict {
    pub comparison: Comparison,
    pub ok: bool,
    /// Samples per pixel of each of the two renders judged.
    pub spp: u32,
    /// The smallest bias of the image mean, relative to it, that this test sees in 99 % of
    /// runs (the worst channel carrying at least 5 % of the brightest's mean).
    pub detectable_bias: f64,
    /// The reference's share of the variance of the difference of means: the floor no
    /// sample count of ours can lower.
    pub reference_share: f64,
    /// Whether the first look failed and a second one, at 4× the samples, decided.
    pub looked_again: bool,
}

impl Verdict {
    pub fn line(&self) -> String {
        let c = &self.comparison;
        format!(
            "T {:6.2}  z {:5.2} {:5.2} {:5.2}  mean {:.4} {:.4} {:.4}  {:4} spp{}  sees {:.2} % bias (reference {:4.1} % of the noise)",
            c.t,
            c.z[0],
            c.z[1],
            c.z[2],
            c.mean[0],
            c.mean[1],
            c.mean[2],
            self.spp,
            if self.looked_again { " (second look)" } else { "" },
            100.0 * self.detectable_bias,
            100.0 * self.reference_share
        )
    }
}

/// Relative bias of the image mean seen in 99 % of runs at `spp`, given a comparison at
/// `spp_measured` (our variance scales as 1/spp, the reference's does not), and the share of
/// the reference in that noise.
fn power_at(c: &Comparison, ref_mean: [f64; 3], spp_measured: u32, spp: u32) -> (f64, f64) {
    let brightest = ref_mean.iter().fold(0.0f64, |a, &m| a.max(m.abs()));
    let (mut worst, mut share) = (0.0f64, 0.0f64);
    for ((&m, &v), &v_ref) in ref_mean.iter().zip(&c.var).zip(&c.var_ref) {
        if m.abs() < 0.05 * brightest || brightest == 0.0 {
            continue;
        }
        let var = v * spp_measured as f64 / spp as f64 + v_ref;
        let d = (Z_LIMIT + POWER_Z) * var.sqrt() / m.abs();
        if d >= worst {
            (worst, share) = (d, v_ref / var.max(1e-300));
        }
    }
    (worst, share)
}

/// Judges an estimator against a reference image (its mean `ref_mean`, per-pixel variance
/// `noise`): two renders (seeds `seeds`) at the tier's pilot count, within `spp_range`,
/// tell the estimator's variance; the renders are then taken to the count at which a bias
/// of the tier's target is seen (doubling, at most the tier's `max_spp` or the range's end). The decision to add samples
/// depends on the spread alone, not on the difference of means, so it does not bias the test.
/// Rare bright paths (a caustic seen in a mirror, which only one strategy finds) make the
/// noise heavy-tailed: at few samples both renders usually miss them and the block
/// differences underestimate the variance. A failure is looked at again with 4× the
/// samples and fresh seeds, which tells this apart from a bias, whose T grows with the
/// sample count.
pub fn judge_against_reference(
    mut render: impl FnMut(u32, u64) -> Film,
    reference: &Image,
    noise: &Image,
    ref_mean: [f64; 3],
    spp_range: (u32, u32),
    seeds: (u64, u64),
) -> Verdict {
    let tier = tier();
    let (min_spp, max_spp) = (spp_range.0, spp_range.1.min(tier.max_spp).max(spp_range.0));
    let mut judge = |spp: u32, seeds: (u64, u64)| {
        let (a, b) = (render(spp, seeds.0), render(spp, seeds.1));
        let c = compare(&a, &b, reference, noise, ref_mean);
        let ok = c.t < T_LIMIT && c.z.iter().all(|z| *z < Z_LIMIT);
        (c, ok)
    };
    let mut spp = tier.pilot_spp.clamp(min_spp, max_spp);
    let (mut c, mut ok) = judge(spp, seeds);
    // The spread at few samples can underestimate heavy tails: the count is checked again at
    // each step and raised until the bias is seen or the tier's most samples are reached.
    while spp < max_spp && power_at(&c, ref_mean, spp, spp).0 > tier.target_bias {
        let measured = spp;
        while spp < max_spp && power_at(&c, ref_mean, measured, spp).0 > tier.target_bias {
            spp = (2 * spp).min(max_spp);
        }
        (c, ok) = judge(spp, seeds);
    }
    let mut looked_again = false;
    if !ok {
        looked_again = true;
        spp *= 4;
        (c, ok) = judge(spp, (seeds.0 ^ 0x0051_7CC1_B727, seeds.1 ^ 0x2545_F491_4F6C));
    }
    let (detectable_bias, reference_share) = power_at(&c, ref_mean, spp, spp);
    Verdict { comparison: c, ok, spp, detectable_bias, reference_share, looked_again }
}

/// Per-pixel variance of a reference made by a path tracer with `ref_spp` samples per
/// pixel, estimated from skelight's own path tracer (the estimator Mitsuba used) at
/// `spp` samples and scaled to the reference's sample count.
pub fn reference_noise(scene: &Scene, spp: u32, ref_spp: u32) -> Image {
    let mut pt = skelight::estimators::by_name("pt").expect("pt");
    let var = render_spp(scene, pt.as_mut(), spp, 0x005E_ED0F_4E5E).variance_image();
    let scale = spp as f32 / ref_spp as f32;
    Image { pixels: var.pixels.iter().map(|p| *p * scale).collect(), ..var }
}

/// [`reference_noise`] of a conformance scene at 16 spp, made once per scene and test build:
/// every estimator's test (one process each under nextest) judges against the same reference,
/// so the path tracer's render that estimates its noise is kept in the tests' scratch folder
/// (`target/tmp`), keyed by the scene file's contents and the test binary's build time (a
/// changed scene, or changed code, renders it again). Writes are atomic: two processes that
/// make it at once write the same image.
pub fn conformance_noise(scene_file: &std::path::Path, scene: &Scene, ref_spp: u32) -> Image {
    use std::hash::{Hash, Hasher};
    let mut key = std::collections::hash_map::DefaultHasher::new();
    std::fs::read(scene_file).unwrap_or_else(|e| panic!("{}: {e}", scene_file.display())).hash(&mut key);
    let exe = std::env::current_exe().ok().and_then(|e| std::fs::metadata(e).ok()?.modified().ok());
    (exe, ref_spp, scene.settings.max_depth, scene.settings.width, scene.settings.height).hash(&mut key);
    let stem = scene_file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("reference-noise")
        .join(format!("{stem}-{:016x}.exr", key.finish()));
    if let Ok(noise) = Image::load(&path) {
        if (noise.width, noise.height) == (scene.settings.width, scene.settings.height) {
            return noise;
        }
    }
    let noise = reference_noise(scene, 16, ref_spp);
    if std::fs::create_dir_all(path.parent().unwrap()).is_ok() {
        let _ = noise.save_exr(&path);
    }
    noise
}

/// T limit: the README's validation found 0.7–1.9 for Mitsuba against itself and 22 for a
/// 6 % bias at 256 spp (a bias's excess over 1 scales with the sample count).
pub const T_LIMIT: f64 = 3.0;
/// z limit for 3 channels × ~20 scenes per estimator: a Gaussian exceeds 4.5 with p ≈ 7e-6.
pub const Z_LIMIT: f64 = 4.5;

/// Samples per pixel for an agreement test that the full tier runs at `full`: a quarter of
/// it in the default tier (4 at least). Each such test prints the difference it sees.
pub fn tier_spp(full: u32) -> u32 {
    if tier().name == "full" {
        full
    } else {
        (full / 4).max(4)
    }
}

/// Every estimator of the registry with the samples per pixel the agreement tests give it
/// in the full tier ([`tier_spp`] of it in the default one): `pt`'s count by default, more
/// where a sample is cheaper and noisier (light tracing), fewer where it is dearer and less
/// noisy (BPT). A new estimator is tested everywhere these lists are used without touching
/// the tests.
pub fn every_estimator() -> Vec<(&'static str, u32)> {
    every_estimator_at_full_count().into_iter().map(|(name, spp)| (name, tier_spp(spp))).collect()
}

/// [`every_estimator`] at the full tier's counts in every tier, for the scenes whose block
/// statistic needs them: light tracing's heavy-tailed splats make two renders' spread a poor
/// variance estimate at a quarter of the samples (the near-clipped box's pt-against-lt block
/// T reached 3.2 there).
pub fn every_estimator_at_full_count() -> Vec<(&'static str, u32)> {
    skelight::estimators::registry::names()
        .into_iter()
        .map(|name| {
            let spp = match name {
                "bpt" | "skelbpt" | "icbpt" => 64,
                "ibpt" => 128,
                _ => 256,
            };
            (name, spp)
        })
        .collect()
}

/// Every estimator renders `scene` twice (independent seeds); all pairs must agree in the
/// image mean (z-test) and block by block (8×8 block T between estimators ≈ 1).
pub fn estimators_agree(scene: &Scene, runs: &[(&str, u32)]) {
    let renders: Vec<(&str, Image, Image)> = runs
        .iter()
        .filter_map(|&(name, spp)| {
            let (estimator, params) = skelight::estimators::registry::parse_spec(name).unwrap();
            let mut i = skelight::estimators::registry::create(&estimator, &params).unwrap();
            if let Some(why) = i.limitation(scene) {
                println!("{name} skipped: {why}");
                return None;
            }
            let (a, b) =
                (render_spp(scene, i.as_mut(), spp, 11).image(), render_spp(scene, i.as_mut(), spp, 12).image());
            Some((name, a, b))
        })
        .collect();
    let (first, a0, b0) = &renders[0];
    let (m0, s0) = pair_mean_se(a0, b0);
    for (name, a, b) in &renders[1..] {
        let (m, se) = pair_mean_se(a, b);
        let t = pair_block_t(a0, b0, a, b);
        for c in 0..3 {
            let z = (m0[c] - m[c]).abs() / (s0[c] * s0[c] + se[c] * se[c]).sqrt();
            let sees = (Z_LIMIT + POWER_Z) * (s0[c] * s0[c] + se[c] * se[c]).sqrt() / m0[c].abs().max(1e-12);
            println!(
                "channel {c}: {first} {:.4} ± {:.4}, {name} {:.4} ± {:.4}, z {z:.2}, sees a {:.2} % difference",
                m0[c],
                s0[c],
                m[c],
                se[c],
                100.0 * sees
            );
            assert!(z < Z_LIMIT, "channel {c}: {first} {} ± {} vs {name} {} ± {}", m0[c], s0[c], m[c], se[c]);
        }
        println!("{first} vs {name}: block T {t:.2}");
        assert!(t < T_LIMIT, "{first} vs {name}: block T = {t:.2}");
    }
}

/// A conformance scene with its XML text edited by `edit`, loaded from a scratch folder.
pub fn edited_conformance_scene(name: &str, edit: impl Fn(String) -> String, w: usize, h: usize) -> Scene {
    let scenes = shared_dir().join("conformance/scenes");
    let text = std::fs::read_to_string(scenes.join(format!("{name}.xml"))).unwrap();
    let edited = edit(text.clone());
    assert_ne!(edited, text, "{name}: the edit changed nothing");
    let dir: PathBuf = std::env::temp_dir().join(format!("skelight-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // The meshes and textures scenes may refer to (inside their folder).
    for f in ["sphere.obj", "checker.png", "leaf.png", "sky.exr"] {
        std::fs::copy(scenes.join(f), dir.join(f)).unwrap();
    }
    let path = dir.join(format!("{name}.xml"));
    std::fs::write(&path, edited).unwrap();
    let mut scene = load(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
    std::fs::remove_dir_all(&dir).ok();
    scene.set_resolution(w, h);
    scene
}

/// Standard base64, for glTF data URIs.
pub fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                out.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The images of a resampling estimator's joins drawn from each distribution, and of the
/// strategies it does not resample, add up to its render (they see the same random
/// numbers); every part but those in `may_be_black` contributes.
pub fn per_distribution_parts_add_up(scene: &Scene, estimator: &str, params: &[(&str, &str)], may_be_black: &[&str]) {
    let opts = skelight::integrator::RenderOptions { spp: Some(4), time: None, seed: 2, threads: 0 };
    let image = |only: &str| {
        let mut p: Vec<(String, String)> = params.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        p.push(("only".into(), only.into()));
        let mut i = skelight::estimators::registry::create(estimator, &p).unwrap();
        skelight::integrator::render(scene, i.as_mut(), &opts, None, |_, _| true).unwrap().film.image()
    };
    let all = image("all");
    let parts: Vec<_> = ["V", "U", "C", "fallback", "unresampled"].iter().map(|o| (o, image(o))).collect();
    for (name, part) in &parts {
        println!("{estimator} {name}: mean {:?}", part.mean());
        assert!(may_be_black.contains(name) || part.mean().luminance() > 0.0, "{name} contributes nothing");
    }
    for (i, p) in all.pixels.iter().enumerate() {
        let sum = parts.iter().fold(skelight::color::Rgb::BLACK, |acc, (_, img)| acc + img.pixels[i]);
        let d = (sum - *p).luminance().abs();
        assert!(d <= 1e-4 * p.luminance().abs() + 1e-6, "pixel {i}: parts {sum:?} vs {p:?}");
    }
}

/// The conformance manifest's entries: name, Mitsuba's image mean and its sample count.
pub fn manifest(dir: &std::path::Path) -> Vec<(String, [f64; 3], u32)> {
    #[derive(serde::Deserialize)]
    struct Entry {
        mean: [f64; 3],
        spp: u32,
    }
    let text = std::fs::read_to_string(dir.join("refs/manifest.json")).expect("manifest.json");
    let entries: std::collections::BTreeMap<String, Entry> = serde_json::from_str(&text).expect("manifest.json parses");
    entries.into_iter().map(|(name, e)| (name, e.mean, e.spp)).collect()
}

/// The seeds of the conformance suite's two renders.
pub const CONFORMANCE_SEEDS: (u64, u64) = (0x1234_5678, 0x9E37_79B9_7F4A);

/// A conformance scene with what judging an estimator on it needs: Mitsuba's reference,
/// its mean, and the reference's per-pixel noise (estimated once, from our path tracer).
pub struct ConformanceScene {
    pub name: String,
    pub scene: Scene,
    pub reference: Image,
    pub noise: Image,
    pub ref_mean: [f64; 3],
}

impl ConformanceScene {
    pub fn new(dir: &std::path::Path, name: String, scene: Scene, ref_mean: [f64; 3], ref_spp: u32) -> Self {
        let reference = Image::load(&dir.join("refs").join(format!("{name}.exr"))).expect("reference");
        let noise = conformance_noise(&dir.join("scenes").join(format!("{name}.xml")), &scene, ref_spp);
        ConformanceScene { name, scene, reference, noise, ref_mean }
    }

    /// The scene of the manifest whose name starts with `prefix` (`c01`).
    pub fn load(prefix: &str) -> Self {
        let dir = shared_dir().join("conformance");
        let (name, ref_mean, ref_spp) =
            manifest(&dir).into_iter().find(|e| e.0.starts_with(prefix)).unwrap_or_else(|| panic!("no {prefix} scene"));
        let scene =
            load(&dir.join("scenes").join(format!("{name}.xml")), &[]).unwrap_or_else(|e| panic!("{name}: {e}"));
        Self::new(&dir, name, scene, ref_mean, ref_spp)
    }

    /// [`judge_against_reference`] for a CPU estimator. Estimators that learn from pass to
    /// pass are judged on three passes at least (16 samples each at 128×128 for `skelpt`, 4
    /// for `skelbpt`), so that what they learnt is used.
    pub fn judge(&self, integrator: &mut dyn Integrator, seeds: (u64, u64)) -> Verdict {
        let min_spp = fewest_spp(integrator, &self.scene);
        judge_against_reference(
            |spp, seed| render_spp(&self.scene, integrator, spp, seed),
            &self.reference,
            &self.noise,
            self.ref_mean,
            (min_spp, u32::MAX),
            seeds,
        )
    }
}

/// The fewest samples per pixel an estimator is judged on in `scene`: three passes for those
/// that learn from pass to pass (so that what they learnt is judged), one otherwise.
pub fn fewest_spp(integrator: &dyn Integrator, scene: &Scene) -> u32 {
    if integrator.learns_across_passes() {
        3 * skelight::integrator::samples_per_pass(integrator, scene.settings.width, scene.settings.height)
    } else {
        1
    }
}
