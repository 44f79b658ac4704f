//! Every scene in ../shared/conformance must match its Mitsuba 3 reference within Monte
//! Carlo noise. The list is read from disk: new scenes are tested without code changes.

mod common;

use std::path::Path;

use common::*;
use skelight::integrator::Integrator;
use skelight::scene::load::load;

/// References that differ from the physically correct image, with the evidence: for each,
/// the variant of `bench/mitsuba_reference_differences.py` (which reruns Mitsuba 3 on the
/// variants that show its behaviour; its figures are in the `.json` beside it) whose image
/// mean is the physically right one, and the `max_depth` to render ours at for it. These
/// scenes are compared with that mean instead of the reference, and our estimators with each
/// other (`our_estimators_agree_where_mitsubas_reference_differs`).
struct KnownDifference {
    scene: &'static str,
    why: &'static str,
    variant: &'static str,
    max_depth: Option<i32>,
}

const KNOWN_REFERENCE_DIFFERENCES: &[KnownDifference] = &[
    KnownDifference {
        scene: "c05_constant_env",
        why: "Mitsuba 3.9.1 tests constant-emitter shadow rays only up to twice the radius of the \
              scene's bounding sphere, and the shape merging of load_file's default optimize=True \
              leaves the `rectangle` floor out of it (radius 1.18, while the floor spans ±4): sky \
              light leaks through the floor onto the cube and sphere standing on it (+0.88 % there, \
              +0.094 % over the image, 450 standard errors). With optimize=False, or the floor as a \
              mesh, Mitsuba gives the image ours does.",
        variant: "original, optimize=False",
        max_depth: None,
    },
    KnownDifference {
        scene: "c13_mask_twosided",
        why: "Mitsuba's path tracer counts passing through a mask's transparent part as a bounce \
              towards max_depth = 8 (a fully transparent leaf and no leaf differ by +0.31 % at \
              depth 8, 15 standard errors, and agree at depth 64); skelight treats it as empty \
              space. Compared at max_depth 64, where the two definitions agree.",
        variant: "original, max_depth 64",
        max_depth: Some(64),
    },
];

/// Mitsuba's mean and standard error of `variant` of `scene` from the evidence file.
fn mitsuba_variant_mean(scene: &str, variant: &str) -> ([f64; 3], [f64; 3]) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../bench/mitsuba_reference_differences.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let json: serde_json::Value = serde_json::from_str(&text).expect("evidence JSON");
    let v = &json["scenes"][scene]["variants"][variant];
    let triple = |key: &str| -> [f64; 3] {
        let a = v[key].as_array().unwrap_or_else(|| panic!("{scene}/{variant}: no {key} in {}", path.display()));
        [0, 1, 2].map(|c| a[c].as_f64().unwrap())
    };
    (triple("mean"), triple("se"))
}

/// Runs one estimator over every conformance scene and reports all failures together.
pub fn run_conformance(integrator_name: &str, min_tested: usize) {
    let dir = shared_dir().join("conformance");
    let entries = manifest(&dir);
    assert!(entries.len() >= 18, "expected the conformance manifest to list scenes");
    let (name, params) = skelight::estimators::registry::parse_spec(integrator_name).expect("estimator");
    let mut integrator = skelight::estimators::registry::create(&name, &params).expect("estimator");
    let mut failures = Vec::new();
    let mut tested = 0;
    // SKELIGHT_CONFORMANCE=c08,c11 restricts a run to scenes whose names start so.
    let only = std::env::var("SKELIGHT_CONFORMANCE").ok();
    let selected = |name: &str| only.as_deref().is_none_or(|o| o.split(',').any(|p| name.starts_with(p)));
    for (name, ref_mean, ref_spp) in entries.into_iter().filter(|e| selected(&e.0)) {
        let scene_path = dir.join("scenes").join(format!("{name}.xml"));
        let scene = load(&scene_path, &[]).unwrap_or_else(|e| panic!("{name}: {e}"));
        if let Some(why) = integrator.limitation(&scene) {
            println!("{integrator_name} {name:24} skipped: {why}");
            continue;
        }
        tested += 1;
        if let Some(known) = KNOWN_REFERENCE_DIFFERENCES.iter().find(|k| k.scene == name) {
            failures.extend(check_against_corrected_mitsuba(integrator_name, integrator.as_mut(), scene, known));
            continue;
        }
        let target = ConformanceScene::new(&dir, name, scene, ref_mean, ref_spp);
        let v = target.judge(integrator.as_mut(), CONFORMANCE_SEEDS);
        println!(
            "{integrator_name} {:24} {}  (ref {:.4} {:.4} {:.4}) {}",
            target.name,
            v.line(),
            ref_mean[0],
            ref_mean[1],
            ref_mean[2],
            if v.ok { "ok" } else { "FAIL" }
        );
        if !v.ok {
            failures.push(format!("{}: T = {:.2}, z = {:?}", target.name, v.comparison.t, v.comparison.z));
        }
    }
    assert!(failures.is_empty(), "{integrator_name} disagrees with Mitsuba 3 on:\n{}", failures.join("\n"));
    assert!(only.is_some() || tested >= min_tested, "{integrator_name}: only {tested} scenes could be tested");
}

/// A scene whose reference is known to differ: our image mean (two renders) against the
/// mean of Mitsuba's physically right variant, within both standard errors.
fn check_against_corrected_mitsuba(
    integrator_name: &str,
    integrator: &mut dyn Integrator,
    mut scene: skelight::scene::Scene,
    known: &KnownDifference,
) -> Option<String> {
    if let Some(d) = known.max_depth {
        scene.settings.max_depth = d;
    }
    let (mitsuba, mitsuba_se) = mitsuba_variant_mean(known.scene, known.variant);
    // Splat-only estimators record no pixel variance: the two renders' block spread is the
    // statistic. As judge_against_reference: from the tier's pilot count, doubled until the
    // tier's bias is seen (a choice from the spread alone).
    let t = tier();
    let mut spp = t.pilot_spp.max(fewest_spp(integrator, &scene));
    let (m, z) = loop {
        let a = render_spp(&scene, integrator, spp, 0x1234_5678).image();
        let b = render_spp(&scene, integrator, spp, 0x9E37_79B9_7F4A).image();
        let (m, se) = pair_mean_se(&a, &b);
        let total = |c: usize| (se[c] * se[c] + mitsuba_se[c] * mitsuba_se[c]).sqrt();
        let sees = (0..3).map(|c| (Z_LIMIT + POWER_Z) * total(c) / mitsuba[c].abs()).fold(0.0f64, f64::max);
        if sees <= t.target_bias || spp >= t.max_spp {
            break (m, [0, 1, 2].map(|c| (m[c] - mitsuba[c]).abs() / total(c)));
        }
        spp = (2 * spp).min(t.max_spp);
    };
    let ok = z.iter().all(|z| *z < Z_LIMIT);
    println!(
        "{integrator_name} {:24} z {:5.2} {:5.2} {:5.2}  mean {:.4} {:.4} {:.4} (Mitsuba '{}' {:.4} {:.4} {:.4}) {}",
        known.scene,
        z[0],
        z[1],
        z[2],
        m[0],
        m[1],
        m[2],
        known.variant,
        mitsuba[0],
        mitsuba[1],
        mitsuba[2],
        if ok { "ok (reference known to differ: see KNOWN_REFERENCE_DIFFERENCES)" } else { "FAIL" }
    );
    (!ok).then(|| format!("{}: z = {z:?} against Mitsuba's '{}' ({})", known.scene, known.variant, known.why))
}

/// Where Mitsuba's reference is known to differ, our estimators must still agree with each
/// other: a bias of one of ours there fails here.
#[test]
fn our_estimators_agree_where_mitsubas_reference_differs() {
    for known in KNOWN_REFERENCE_DIFFERENCES {
        let path = shared_dir().join("conformance/scenes").join(format!("{}.xml", known.scene));
        let mut scene = load(&path, &[]).unwrap_or_else(|e| panic!("{}: {e}", known.scene));
        scene.set_resolution(64, 64);
        println!("{}:", known.scene);
        estimators_agree(&scene, &every_estimator());
    }
}

#[test]
fn pt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("pt", 18);
}

#[test]
fn lt_matches_mitsuba_where_light_tracing_applies() {
    run_conformance("lt", 15);
}

#[test]
fn bpt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("bpt", 18);
}

#[test]
fn ibpt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("ibpt", 18);
}

/// skelpt's default learns its strength and c_skel per node pass after pass...
#[test]
fn skelpt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("skelpt", 18);
}

/// ... and with them fixed (the thesis's form).
#[test]
fn skelpt_with_fixed_parameters_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("skelpt:adaptive=false", 18);
}

/// skelbpt resamples bpt's connections from tables at skeleton nodes; at the conformance
/// scenes' 128×128 there are 16 384 light sub-paths per iteration, 1024 of them candidates,
/// as in the seeds.
#[test]
fn skelbpt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("skelbpt", 18);
}

/// icbpt resamples them from tables at importance records (d = 0.001: 17 eye sub-paths'
/// records per iteration at 128×128).
#[test]
fn icbpt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("icbpt", 18);
}

/// portalpt draws directions through the opening portals towards the lit regions, weighted
/// by the exact density of the blended mixture: unbiased on every scene. With every portal
/// kept (`bottleneck=2`, the thesis' regions): the conformance scenes are single rooms, where
/// the default joins everything into the lit region and portalpt is pt; kept, their 10–166
/// mid-air portals route 2–46 regions and draw directions on every scene (through their
/// voxel faces: more than the rectangles' triangle budget).
#[test]
fn portalpt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("portalpt:bottleneck=2", 18);
}

/// The estimators the tests above check: every one the registry offers must be among them.
const CHECKED: &[&str] = &["pt", "lt", "bpt", "ibpt", "skelpt", "portalpt", "skelbpt", "icbpt"];

#[test]
fn every_registered_estimator_has_a_conformance_test() {
    for name in skelight::estimators::registry::names() {
        assert!(CHECKED.contains(&name), "{name} is registered but has no conformance test here");
    }
}
