//! `skelbpt` (thesis ch. 11): its resampling tables draw candidates with the probabilities
//! the estimator divides by, every candidate that can contribute can be drawn (eq. 186's
//! condition for an unbiased resampled estimate), the MIS weights of resampled joins are
//! those of the paths they make, the per-distribution images add up to the render, and the
//! estimator agrees with `bpt` where resampling matters (the door corner, lit through a gap).

mod common;

use common::*;
use skelight::estimators::registry;
use skelight::estimators::resampling::join::{resampled_join, Join};
use skelight::estimators::resampling::node_tables::NodeSelection;
use skelight::estimators::resampling::node_tables::{BuildInput, Combination, Origin, Resampling};
use skelight::guided::GuideSettings;
use skelight::integrator::params::Params;
use skelight::integrator::Preparation;
use skelight::math::vec2;
use skelight::paths::mis::{running_sums, weight, AllStrategies, Heuristic, PathWeight, SubPath};
use skelight::paths::strategies::connect_vertices;
use skelight::paths::subpath::{camera_subpath, LightPaths};
use skelight::sampling::Rng;

fn door_corner(w: usize, h: usize) -> skelight::scene::Scene {
    load_small(&repo_scene("door-corner.toml"), w, h)
}

/// A prepared skelbpt and one iteration's tables on the door corner at 64×32 (2048 light
/// sub-paths, 256 candidates).
fn door_corner_tables(combination: Combination) -> (skelight::scene::Scene, NodeSelection, LightPaths, Resampling) {
    tables(door_corner(64, 32), combination)
}

/// … on any scene at 64×32.
fn tables(
    scene: skelight::scene::Scene,
    combination: Combination,
) -> (skelight::scene::Scene, NodeSelection, LightPaths, Resampling) {
    assert_eq!(scene.settings.width * scene.settings.height, 64 * 32);
    let skelbpt = node_selection(&scene);
    let prep = &skelbpt.1;
    let skelbpt = skelbpt.0;
    println!("{}", prep.notes.join("\n"));
    let mut paths = LightPaths::default();
    paths.trace(&scene, 64 * 32, 5, 0, scene.settings.max_depth);
    let mut table = Resampling::default();
    {
        let (guide, accepted, _) = (&*skelbpt.guide, &skelbpt.accepted[..], &skelbpt.mapped[..]);
        assert!(!accepted.is_empty(), "the pilot accepted no node");
        let input = BuildInput {
            guide,
            accepted,
            candidates: 256,
            combination,
            heuristic: Heuristic::Balance,
            deepest: 5,
            seed: 5,
            iteration: 0,
        };
        table.build(&scene, &paths, &input);
    }
    (scene, skelbpt, paths, table)
}

/// Over a fine stratified grid of uniform numbers, each node's table (and the fallback)
/// returns every eligible candidate, as often as the probability it reports, and those
/// probabilities sum to one; no candidate gets less than a third of the uniform share.
fn check_draws(combination: Combination) {
    let (_, skelbpt, _, table) = door_corner_tables(combination);
    let (_, accepted, _) = (&*skelbpt.guide, &skelbpt.accepted[..], &skelbpt.mapped[..]);
    assert_eq!(table.candidates(), 256);
    let grid: u64 = 1 << 17;
    let mut checked = 0;
    for node in accepted.iter().map(|&n| Some(n)).take(6).chain([None]) {
        for s in 2..=table.depths() + 1 {
            let eligible = table.eligible(s);
            if eligible.is_empty() {
                assert!(table.draw(node, s, 1 << 31).is_none());
                continue;
            }
            let mut counts = std::collections::HashMap::<usize, (u64, f32, Origin)>::new();
            for k in 0..grid {
                let d = table.draw(node, s, (k * ((1u64 << 32) / grid) + 7) as u32).expect("a draw");
                let e = counts.entry(d.candidate).or_insert((0, d.probability, d.origin));
                e.0 += 1;
                assert_eq!(e.1, d.probability, "one candidate, two probabilities");
            }
            assert_eq!(counts.len(), eligible.len(), "node {node:?}, s = {s}: some candidate is never drawn");
            let total: f64 = counts.values().map(|c| c.1 as f64).sum();
            assert!((total - 1.0).abs() < 1e-4, "node {node:?}, s = {s}: probabilities sum to {total}");
            for (c, (n, p, origin)) in &counts {
                assert!(eligible.contains(&(*c as u32)));
                assert!(*p as f64 >= 1.0 / (3.0 * eligible.len() as f64) * 0.999, "candidate {c} starved: {p}");
                // Stratified counts are within one stratum of the exact share per cdf step.
                let expected = *p as f64 * grid as f64;
                assert!(
                    (*n as f64 - expected).abs() <= 2.0 + 1e-3 * expected,
                    "node {node:?}, s = {s}, {c}: {n} vs {expected}"
                );
                if node.is_none() {
                    assert_eq!(*origin, Origin::Fallback);
                }
            }
            checked += 1;
        }
    }
    assert!(checked >= 10, "too few tables checked: {checked}");
}

#[test]
fn tables_draw_with_the_probabilities_the_estimator_divides_by() {
    check_draws(Combination::Max);
}

#[test]
fn balance_tables_draw_with_their_probabilities() {
    check_draws(Combination::Balance);
}

/// A resampled join is weighted with the running sums of the candidate's own light
/// sub-path, and `bpt`'s weights from those sums equal exact MIS on the joined path.
#[test]
fn resampled_joins_carry_the_weights_of_the_paths_they_make() {
    let (scene, _, paths, table) = door_corner_tables(Combination::Max);
    let mut sums = Vec::new();
    let mut rng = Rng::new(9, 0, 0);
    let (mut camera, mut camera_sums) = (Vec::new(), Vec::new());
    let mut compared = 0;
    for c in 0..table.candidates() {
        let light = paths.path(table.paths[c] as usize);
        assert_eq!(table.path(c).len(), light.len(), "candidate {c}: a copy of another path");
        running_sums(&scene, light, Heuristic::Balance, &mut sums);
        assert_eq!(table.sums(c), &sums[..], "candidate {c}: running sums of another path");
        if c % 16 != 0 {
            continue;
        }
        camera_subpath(&scene, vec2(rng.next_f32() * 64.0, rng.next_f32() * 32.0), &mut rng, 6, &mut camera);
        running_sums(&scene, &camera, Heuristic::Balance, &mut camera_sums);
        let w = AllStrategies { heuristic: Heuristic::Balance, light_sums: table.sums(c), camera_sums: &camera_sums };
        for s in 2..=light.len() {
            for t in 2..=camera.len() {
                if s + t > 7 || !light[s - 1].connectible() || !camera[t - 1].connectible() {
                    continue;
                }
                let (l, e) = (SubPath::new(&light[..s], None), SubPath::new(&camera[..t], None));
                let exact = weight(&scene, l, e, &Default::default(), Heuristic::Balance, &|_, _| true);
                let fast = w.weight(&scene, l, e);
                assert!((exact - fast).abs() <= 1e-3 * exact.max(1e-3), "s {s} t {t}: {fast} vs exact {exact}");
                compared += 1;
            }
        }
    }
    assert!(compared > 20, "too few joins compared: {compared}");
}

/// The images of the joins drawn from each distribution, and of the strategies not
/// resampled, add up to the render (they see the same random numbers).
#[test]
fn per_distribution_images_add_up_to_the_render() {
    per_distribution_parts_add_up(&door_corner(32, 16), "skelbpt", &[], &[]);
}

/// Where most connections of `bpt` are blocked by the door, skelbpt (its default, every
/// node accepted, and the balance combination) estimates the same image.
#[test]
fn skelbpt_agrees_with_bpt_on_the_door_corner() {
    let scene = door_corner(48, 24);
    estimators_agree(
        &scene,
        &[
            ("bpt", 64),
            ("skelbpt", 64),
            ("skelbpt:acceptance=0:candidates=64", 64),
            ("skelbpt:combination=balance", 64),
        ],
    );
}

/// Absurd parameters are refused with the parameter named; a scene without lights renders
/// black, as bpt does, with a note.
#[test]
fn skelbpt_refuses_absurd_parameters() {
    for (name, value) in [("candidates", "0"), ("acceptance", "-1"), ("combination", "min"), ("only", "W")] {
        let err = registry::create("skelbpt", &[(name.into(), value.into())]).err().expect("refused").to_string();
        assert!(err.contains(name), "{err}");
    }
    let mut dark = door_corner(16, 8);
    dark.lights.clear();
    let mut i = registry::create("skelbpt", &[]).unwrap();
    let prep = i.prepare(&dark).unwrap();
    assert!(prep.notes.iter().any(|n| n.contains("no lights")), "{:?}", prep.notes);
}

/// Eq. 186 term by term: for real camera sub-paths, the expectation of a resampled join
/// over the table's draws (each candidate's term times its probability) equals the mean of
/// that join over all N candidates, those without a vertex at depth s counting as zero.
/// On the door corner, and on an open box lit by a point light, where light sub-paths leave
/// the scene: dividing by the number of candidates that have a vertex at s, N_s, instead of
/// N would fail there.
#[test]
fn resampled_joins_average_the_joins_of_all_candidates() {
    check_average(door_corner_tables(Combination::Max), false);
    let open = load_small(&shared_dir().join("conformance/scenes/c02_point.xml"), 64, 32);
    check_average(tables(open, Combination::Max), true);
}

fn check_average(
    (scene, skelbpt, paths, table): (skelight::scene::Scene, NodeSelection, LightPaths, Resampling),
    paths_end_early: bool,
) {
    let (guide, _, _) = (&*skelbpt.guide, &skelbpt.accepted[..], &skelbpt.mapped[..]);
    let n = table.candidates();
    if paths_end_early {
        assert!(
            (2..=table.depths() + 1).any(|s| table.eligible(s).len() < n * 9 / 10),
            "(almost) every candidate reaches every depth: the test would not tell N from N_s"
        );
    }
    let mut rng = Rng::new(4, 0, 0);
    let (mut camera, mut camera_sums, mut light_sums) = (Vec::new(), Vec::new(), Vec::new());
    let mut checked = 0;
    let grid: u64 = 1 << 15;
    for _ in 0..40 {
        camera_subpath(&scene, vec2(rng.next_f32() * 64.0, rng.next_f32() * 32.0), &mut rng, 6, &mut camera);
        running_sums(&scene, &camera, Heuristic::Balance, &mut camera_sums);
        for t in 2..=camera.len() {
            let z = &camera[t - 1];
            let node = guide.node_at(z.p(), z.n(), z.si.wi);
            for s in 2..=(7 - t).min(table.depths() + 1) {
                let join = Join { s, camera: &camera, camera_sums: &camera_sums, t, heuristic: Heuristic::Balance };
                // Each candidate once, with its probability (stratified draws find them all).
                let mut seen = std::collections::HashSet::new();
                let mut expectation = 0.0f64;
                for k in 0..grid {
                    let Some(d) = table.draw(node, s, (k * ((1u64 << 32) / grid) + 7) as u32) else { break };
                    if seen.insert(d.candidate) {
                        let c = resampled_join(&scene, &table, &d, &join);
                        expectation += d.probability as f64 * c.luminance() as f64;
                    }
                }
                let mut mean = 0.0f64;
                for c in 0..n {
                    let light = paths.path(table.paths[c] as usize);
                    if light.len() < s {
                        continue;
                    }
                    running_sums(&scene, light, Heuristic::Balance, &mut light_sums);
                    let w = AllStrategies {
                        heuristic: Heuristic::Balance,
                        light_sums: &light_sums,
                        camera_sums: &camera_sums,
                    };
                    mean += connect_vertices(&scene, light, s, &camera, t, &w).luminance() as f64 / n as f64;
                }
                // The two sides differ only by f32 rounding (c/(N·p)·p against c/N, summed
                // over at most 256 candidates in f64): far below the N/N_s ≥ 1.1 a wrong
                // normaliser makes.
                assert!(
                    (expectation - mean).abs() <= 1e-5 * mean.abs() + 1e-12,
                    "t {t}, s {s}: expectation over draws {expectation} vs mean over candidates {mean}"
                );
                checked += (mean > 0.0) as usize;
            }
        }
    }
    println!(
        "{checked} joins checked; eligible per depth: {:?}",
        (2..=table.depths() + 1).map(|s| table.eligible(s).len()).collect::<Vec<_>>()
    );
    assert!(checked >= 20, "too few joins with light checked: {checked}");
}

/// skelbpt's preparation with its default parameters: the skeleton and the nodes accepted
/// for the first pass.
fn node_selection(scene: &skelight::scene::Scene) -> (NodeSelection, Preparation) {
    let p = Params::new("skelbpt", registry::find("skelbpt").unwrap().params, &[]).unwrap();
    let settings = GuideSettings::from_params(&p);
    let mut prep = Preparation::default();
    let nodes = NodeSelection::prepare(scene, &settings, p.float("acceptance"), scene.settings.max_depth, &mut prep)
        .expect("the door corner has a skeleton");
    (nodes, prep)
}
