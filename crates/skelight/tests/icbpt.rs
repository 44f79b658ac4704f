//! `icbpt` (thesis §11.5, Georgiev et al. 2012 adapted to BPT): its records' tables and the
//! combination of the records an eye vertex uses weigh every candidate exactly once in
//! expectation (the condition for an unbiased resampled estimate, eq. 186), a resampled join
//! averages the joins of all N candidates, the per-distribution images add up to the
//! render, and the estimator agrees with `bpt` on the door corner.

mod common;

use common::*;
use skelight::estimators::registry;
use skelight::estimators::resampling::candidates::{
    uniform_position_probability, uniform_position_start, Combination, Draw,
};
use skelight::estimators::resampling::importance_cache::{CacheInput, ImportanceCache, Nearby};
use skelight::estimators::resampling::join::{resampled_join, Join};
use skelight::estimators::resampling::node_tables::Origin;
use skelight::integrator::{render, RenderOptions};
use skelight::math::vec2;
use skelight::paths::mis::{running_sums, AllStrategies, Heuristic};
use skelight::paths::strategies::connect_vertices;
use skelight::paths::subpath::{camera_subpath, LightPaths};
use skelight::sampling::Rng;
use skelight::scene::Scene;

fn door_corner(w: usize, h: usize) -> Scene {
    load_small(&repo_scene("door-corner.toml"), w, h)
}

/// One iteration's cache on `scene` at 64×32: 2048 light sub-paths, 256 candidates, records
/// from 24 eye sub-paths.
fn cache(scene: &Scene, combination: Combination) -> (LightPaths, ImportanceCache) {
    assert_eq!(scene.settings.width * scene.settings.height, 64 * 32);
    let mut paths = LightPaths::default();
    paths.trace(scene, 64 * 32, 5, 0, scene.settings.max_depth);
    let mut cache = ImportanceCache::default();
    let input = CacheInput {
        record_paths: 24,
        candidates: 256,
        combination,
        heuristic: Heuristic::Balance,
        deepest: 5,
        max_depth: scene.settings.max_depth,
        seed: 5,
        iteration: 0,
    };
    cache.build(scene, &paths, &input);
    assert!(cache.records() > 24, "too few records: {}", cache.records());
    (paths, cache)
}

/// For one eye vertex and depth: every (kept record, table position) pair with the
/// probability of drawing it, π_j·p_j(i) (π_j the exact probability of record j's stratum of
/// uniform numbers), found by the first number of each record's stratum and a fine
/// stratified grid over the table's.
fn pairs(cache: &ImportanceCache, records: &[u32], s: usize) -> Vec<(usize, usize, f64)> {
    let k = records.len();
    let m = cache.eligible(s).len();
    let grid: u64 = 1 << 16;
    let mut found = Vec::new();
    for j in 0..k {
        let r1 = uniform_position_start(j, k);
        let mut seen = std::collections::HashMap::new();
        for g in 0..grid {
            let (picked, i, p) = cache.pick(records, s, (r1, (g * ((1u64 << 32) / grid) + 3) as u32)).expect("a pick");
            assert_eq!(picked, j, "the record stratum picks another record");
            assert!(p >= 1.0 / (3.0 * m as f64) * 0.999, "position {i} starved: {p}");
            assert_eq!(*seen.entry(i).or_insert(p), p, "one position, two probabilities");
        }
        assert_eq!(seen.len(), m, "record {j}: some candidate is never drawn");
        found.extend(seen.into_iter().map(|(i, p)| (j, i, p * uniform_position_probability(j, k))));
    }
    found
}

/// Eq. 186's condition and its consequence, for real eye vertices: (1) every eligible
/// candidate is weighted once in expectation, Σ_j (1/k)·p_j(i) / divisor(j, i) = 1 over the
/// kept records j that give it weight; (2) the expectation of the resampled join over those
/// draws equals the mean of the join over all N candidates (those without a vertex at s
/// counting as zero: N, not N_s). `draw` returns the same candidate and probability as the
/// two stages.
fn check_weights(scene: &Scene, combination: Combination, paths_end_early: bool) {
    let (paths, cache) = cache(scene, combination);
    let n = cache.candidates();
    if paths_end_early {
        assert!(
            (2..=cache.depths() + 1).any(|s| cache.eligible(s).len() < n * 9 / 10),
            "(almost) every candidate reaches every depth: the test would not tell N from N_s"
        );
    }
    let mut rng = Rng::new(4, 0, 0);
    let (mut camera, mut camera_sums, mut light_sums) = (Vec::new(), Vec::new(), Vec::new());
    let mut nearby = Nearby::default();
    let (mut checked, mut several) = (0, 0);
    for _ in 0..30 {
        camera_subpath(scene, vec2(rng.next_f32() * 64.0, rng.next_f32() * 32.0), &mut rng, 6, &mut camera);
        running_sums(scene, &camera, Heuristic::Balance, &mut camera_sums);
        for t in 2..=camera.len() {
            let z = &camera[t - 1];
            if !z.can_connect(scene) {
                continue;
            }
            cache.nearby(z, &mut nearby);
            let kept = nearby.records().to_vec();
            several += (kept.len() > 1) as usize;
            // The kept records, and lists the kd-tree never returns: a record twice (ties
            // under max), twice beside another, and none (the fallback).
            let mut lists = vec![kept.clone(), vec![]];
            if let Some(&r) = kept.first() {
                lists.push(vec![r, r]);
                lists.push(vec![r, r, kept.last().copied().unwrap_or(r)]);
            }
            for s in 2..=(7 - t).min(cache.depths() + 1) {
                if cache.eligible(s).is_empty() {
                    continue;
                }
                let join = Join { s, camera: &camera, camera_sums: &camera_sums, t, heuristic: Heuristic::Balance };
                let term = |candidate: usize, divisor: f64| {
                    let draw = Draw { candidate, probability: divisor as f32, origin: Origin::Uniform };
                    resampled_join(scene, &cache, &draw, &join).luminance() as f64
                };
                let mut mean = 0.0f64;
                for c in 0..n {
                    let light = paths.path(cache.paths[c] as usize);
                    if light.len() < s {
                        continue;
                    }
                    running_sums(scene, light, Heuristic::Balance, &mut light_sums);
                    let w = AllStrategies {
                        heuristic: Heuristic::Balance,
                        light_sums: &light_sums,
                        camera_sums: &camera_sums,
                    };
                    mean += connect_vertices(scene, light, s, &camera, t, &w).luminance() as f64 / n as f64;
                }
                for records in &lists {
                    let m = cache.eligible(s).len();
                    let mut expectation = 0.0f64;
                    if records.is_empty() {
                        // The fallback: each position with its exact probability.
                        for i in 0..m {
                            let d = cache.draw(records, s, (0, uniform_position_start(i, m)), combination).unwrap();
                            assert_eq!((d.candidate, d.origin), (cache.eligible(s)[i] as usize, Origin::Fallback));
                            assert_eq!(d.probability, uniform_position_probability(i, m) as f32);
                            expectation += uniform_position_probability(i, m) * term(d.candidate, d.probability as f64);
                        }
                    } else {
                        let mut weight = vec![0.0f64; m];
                        for (j, i, q) in pairs(&cache, records, s) {
                            let Some(divisor) = cache.divisor(records, s, (j, i), combination) else { continue };
                            weight[i] += q / divisor;
                            expectation += q * term(cache.eligible(s)[i] as usize, divisor);
                        }
                        for (i, w) in weight.iter().enumerate() {
                            assert!(
                                (w - 1.0).abs() < 1e-9,
                                "t {t}, s {s}, {records:?}, position {i}: weighted {w} times"
                            );
                        }
                    }
                    // f32 rounding of c/(N·q) against c/N, summed in f64.
                    assert!(
                        (expectation - mean).abs() <= 1e-5 * mean.abs() + 1e-12,
                        "t {t}, s {s}, {records:?}: expectation over draws {expectation} vs mean over candidates {mean}"
                    );
                }
                checked += (mean > 0.0 && !kept.is_empty()) as usize;
                // The one-call draw matches its two stages.
                let random = (rng.next_u32(), rng.next_u32());
                if let Some((j, i, _)) = cache.pick(&kept, s, random) {
                    let two_stage = cache.divisor(&kept, s, (j, i), combination);
                    let draw = cache.draw(&kept, s, random, combination);
                    assert_eq!(draw.map(|d| d.probability), two_stage.map(|p| p as f32));
                    if let Some(d) = draw {
                        assert_eq!(d.candidate, cache.eligible(s)[i] as usize);
                    }
                }
            }
        }
    }
    println!("{checked} joins with light checked, {several} eye vertices with several records");
    assert!(checked >= 20, "too few joins with light checked: {checked}");
    assert!(several >= 10, "too few eye vertices combine records: {several}");
}

#[test]
fn records_weigh_every_candidate_once_under_the_max_heuristic() {
    check_weights(&door_corner(64, 32), Combination::Max, false);
}

#[test]
fn records_weigh_every_candidate_once_under_the_balance_heuristic() {
    check_weights(&door_corner(64, 32), Combination::Balance, false);
}

/// An open box lit by a point light, where light sub-paths leave the scene: dividing by
/// the number of candidates with a vertex at s instead of N would fail here.
#[test]
fn resampled_joins_average_over_all_candidates_where_light_paths_end_early() {
    let open = load_small(&shared_dir().join("conformance/scenes/c02_point.xml"), 64, 32);
    check_weights(&open, Combination::Max, true);
}

/// The images of the joins drawn from each distribution, and of the strategies not
/// resampled, add up to the render (they see the same random numbers).
#[test]
fn icbpt_per_distribution_images_add_up_to_the_render() {
    per_distribution_parts_add_up(&door_corner(32, 16), "icbpt", &[("density", "0.02")], &["fallback"]);
}

/// Where most connections of `bpt` are blocked by the door, icbpt (its default, the balance
/// combinations, and dense records with few candidates) estimates the same image.
#[test]
fn icbpt_agrees_with_bpt_on_the_door_corner() {
    let scene = door_corner(48, 24);
    estimators_agree(
        &scene,
        &[
            ("bpt", 64),
            ("icbpt", 64),
            ("icbpt:combination=balance:records=balance", 64),
            ("icbpt:density=0.05:candidates=64", 64),
        ],
    );
}

/// Absurd parameters are refused with the parameter named; a scene without lights renders
/// as bpt does, with a note.
#[test]
fn icbpt_refuses_absurd_parameters() {
    for (name, value) in [("candidates", "0"), ("density", "-1"), ("density", "2"), ("records", "min"), ("only", "W")] {
        let err = registry::create("icbpt", &[(name.into(), value.into())]).err().expect("refused").to_string();
        assert!(err.contains(name), "{err}");
    }
    let mut dark = door_corner(16, 8);
    dark.lights.clear();
    let mut i = registry::create("icbpt", &[]).unwrap();
    let prep = i.prepare(&dark).unwrap();
    assert!(prep.notes.iter().any(|n| n.contains("no lights")), "{:?}", prep.notes);
    let opts = RenderOptions { spp: Some(2), time: None, seed: 1, threads: 0 };
    let image = render(&dark, i.as_mut(), &opts, None, |_, _| true).unwrap().film.image();
    assert_eq!(image.mean().luminance(), 0.0);
}

/// The resampled joins cover exactly bpt's (s, t ≥ 2) strategies at every path length limit:
/// skelbpt and icbpt agree with bpt at max depth 2 (no join at all), 3 (s = t = 2 only) and
/// unlimited (a join at every light depth the candidates reach). At max depth 3 a join one
/// vertex too long adds 13 % to the image: at 256 spp that is z ≈ 10 (seen, breaking it once).
#[test]
fn resampling_estimators_agree_with_bpt_at_every_depth_limit() {
    for (max_depth, spp) in [(2, 64), (3, 256), (-1, 64)] {
        let mut scene = door_corner(32, 16);
        scene.settings.max_depth = max_depth;
        println!("max depth {max_depth}:");
        let spp = tier_spp(spp);
        estimators_agree(&scene, &[("bpt", spp), ("skelbpt", spp), ("icbpt", spp)]);
    }
}
