//! Every scene in ../shared/conformance must match its Mitsuba 3 reference within Monte
//! Carlo noise. The list is read from disk: new scenes are tested without code changes.

mod common;

use std::path::Path;

use common::*;
use skelight::imageio::Image;
use skelight::integrator::by_name;
use skelight::scene::load::load;

const SPP: u32 = 128;

/// References that differ from the physically correct image, with the evidence. These
/// scenes are still rendered and reported, but do not fail the suite.
const KNOWN_REFERENCE_DIFFERENCES: &[(&str, &str)] = &[
    (
        "c05_constant_env",
        "Mitsuba 3.9.1 tests constant-emitter shadow rays only up to twice the radius of a scene \
         bounding sphere that leaves out `rectangle` shapes (radius 1.18 here, while the floor \
         spans ±4), so sky light leaks through the floor onto the raised cube and sphere. \
         Checked with Mitsuba's own emitter sampling: 0.66 instead of the exact 0.35 on a vertical \
         face over an unbounded floor (see analytic::vertical_face_under_sky_over_a_floor).",
    ),
    (
        "c13_mask_twosided",
        "Mitsuba's path tracer counts passing through a mask's transparent part as a bounce \
         towards max_depth = 8; skelight treats it as empty space, so paths through the leaf's \
         holes keep one more bounce (+0.2 %). With max_depth = 64 the two agree: Mitsuba \
         (0.21758, 0.15379, 0.06533) vs skelight (0.2177, 0.1539, 0.0654) at 2048 spp.",
    ),
];

fn manifest(dir: &Path) -> Vec<(String, [f64; 3], u32)> {
    let text = std::fs::read_to_string(dir.join("refs/manifest.json")).expect("manifest.json");
    // Minimal reader for {"name": {"mean": [r, g, b], ..., "spp": n}, ...}.
    let mut out = Vec::new();
    let mut rest = text.as_str();
    while let Some(i) = rest.find("\"mean\"") {
        let head = &rest[..i];
        let name_end = head.rfind("\": {").expect("entry name");
        let name_start = head[..name_end].rfind('"').expect("entry name") + 1;
        let name = head[name_start..name_end].to_string();
        let body = &rest[i..];
        let lb = body.find('[').unwrap();
        let rb = body.find(']').unwrap();
        let v: Vec<f64> = body[lb + 1..rb].split(',').map(|s| s.trim().parse().unwrap()).collect();
        let spp_at = body.find("\"spp\"").unwrap();
        let spp: u32 = body[spp_at + 6..]
            .trim_start_matches([':', ' '])
            .split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap()
            .parse()
            .unwrap();
        out.push((name, [v[0], v[1], v[2]], spp));
        rest = &body[rb..];
    }
    out
}

/// Runs one estimator over every conformance scene and reports all failures together.
pub fn run_conformance(integrator_name: &str, min_tested: usize) {
    let dir = shared_dir().join("conformance");
    let entries = manifest(&dir);
    assert!(entries.len() >= 18, "expected the conformance manifest to list scenes");
    let integrator = by_name(integrator_name).expect("integrator");
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
        let reference = Image::load(&dir.join("refs").join(format!("{name}.exr"))).expect("reference");
        let noise = reference_noise(&scene, 16, ref_spp);
        let judge = |spp: u32, seeds: (u64, u64)| {
            let a = render_spp(&scene, integrator.as_ref(), spp, seeds.0);
            let b = render_spp(&scene, integrator.as_ref(), spp, seeds.1);
            let c = compare(&a, &b, &reference, &noise, ref_mean);
            let ok = c.t < T_LIMIT && c.z.iter().all(|z| *z < Z_LIMIT);
            (c, ok)
        };
        let defect = KNOWN_REFERENCE_DIFFERENCES.iter().find(|(n, _)| *n == name);
        let (mut c, mut ok) = judge(SPP, (0x1234_5678, 0x9E37_79B9_7F4A));
        if !ok && defect.is_none() {
            // Rare bright paths (a caustic seen in a mirror, which only one strategy finds)
            // make the noise heavy-tailed: at few samples both renders usually miss them and
            // the block differences underestimate the variance. A second look with 4× the
            // samples and fresh seeds tells this apart from a bias, whose T grows with the
            // sample count.
            println!(
                "{integrator_name} {name:24} T {:6.2}  z {:5.2} {:5.2} {:5.2}  at {SPP} spp: looking again at {} spp",
                c.t,
                c.z[0],
                c.z[1],
                c.z[2],
                4 * SPP
            );
            (c, ok) = judge(4 * SPP, (0x0051_7CC1_B727, 0x2545_F491_4F6C));
        }
        println!(
            "{integrator_name} {name:24} T {:6.2}  z {:5.2} {:5.2} {:5.2}  mean {:.4} {:.4} {:.4} (ref {:.4} {:.4} {:.4}) {}",
            c.t, c.z[0], c.z[1], c.z[2], c.mean[0], c.mean[1], c.mean[2], ref_mean[0], ref_mean[1], ref_mean[2],
            match (ok, defect) {
                (true, _) => "ok",
                (false, Some(_)) => "differs (known reference difference)",
                (false, None) => "FAIL",
            }
        );
        if !ok && defect.is_none() {
            failures.push(format!("{name}: T = {:.2}, z = {:?}", c.t, c.z));
        }
    }
    assert!(failures.is_empty(), "{integrator_name} disagrees with Mitsuba 3 on:\n{}", failures.join("\n"));
    assert!(only.is_some() || tested >= min_tested, "{integrator_name}: only {tested} scenes could be tested");
}

#[test]
fn pt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("pt", 18);
}

#[test]
fn lt_matches_mitsuba_where_light_tracing_applies() {
    run_conformance("lt", 10);
}

#[test]
fn bpt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("bpt", 18);
}

#[test]
fn ibpt_matches_mitsuba_on_every_conformance_scene() {
    run_conformance("ibpt", 18);
}
