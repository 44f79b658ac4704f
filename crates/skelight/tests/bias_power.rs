//! The power study of issue 53, outside the suite: how often the default tier's conformance
//! test fails an estimator given a deliberate bias, and how often it passes the unmodified
//! code, each over 10 fresh seed pairs. Built only with the `mutation` feature:
//!
//! ```sh
//! cargo test --release -p skelight --features mutation --test bias_power -- --nocapture
//! SKELIGHT_POWER=pt,bpt SKELIGHT_POWER_SCENES=c01,c14 ...   # a subset
//! ```
//!
//! For each estimator and one conformance scene of each class (area light c01, delta light
//! c02, environment c06, glossy c07, specular c09, thin lens c14), where the estimator's
//! `limitation()` allows: the whole image scaled by 1.02 (every strategy), and each strategy
//! carrying at least a quarter of the image scaled by 1 + 0.02/share (so the image mean
//! moves by 2 % either way). A strategy's share is measured by rendering without it (its
//! factor 0) from the same random numbers.
#![cfg(feature = "mutation")]

mod common;

use common::*;
use skelight::estimators::registry;
use skelight::paths::mutation::{self, Strategy};

const ESTIMATORS: &[&str] = &["pt", "lt", "bpt", "ibpt", "skelpt", "skelpt:adaptive=false", "skelbpt", "icbpt"];
const SCENES: &[&str] = &["c01", "c02", "c06", "c07", "c09", "c14"];
/// Strategies that partition the image (the guided and resampled ones are parts of these).
const PARTITION: [Strategy; 4] = [Strategy::Hit, Strategy::Nee, Strategy::LightTrace, Strategy::Connection];
const PAIRS: u64 = 10;

/// The entries of `all` that the comma-separated list in `var` names (exactly, or by prefix
/// for scenes), or all of them.
fn selected<'a>(var: &str, all: &[&'a str], by_prefix: bool) -> Vec<&'a str> {
    match std::env::var(var) {
        Ok(list) => all
            .iter()
            .copied()
            .filter(|n| list.split(',').any(|p| *n == p || (by_prefix && n.starts_with(p))))
            .collect(),
        Err(_) => all.to_vec(),
    }
}

fn luminance_mean(film: &skelight::film::Film) -> f64 {
    film.image().mean().luminance() as f64
}

/// Fails out of `PAIRS` fresh seed pairs, the judged sample counts' range and the worst
/// detectable bias stated.
fn fails(target: &ConformanceScene, spec: &str) -> (u64, (u32, u32), f64) {
    let (name, params) = registry::parse_spec(spec).unwrap();
    let (mut failed, mut spp, mut detect) = (0, (u32::MAX, 0), 0.0f64);
    for pair in 0..PAIRS {
        let mut estimator = registry::create(&name, &params).unwrap();
        let seeds = (0xB1A5_0000 + 2 * pair, 0x5EED_0000_0000 + 2 * pair + 1);
        let v = target.judge(estimator.as_mut(), seeds);
        failed += u64::from(!v.ok);
        spp = (spp.0.min(v.spp), spp.1.max(v.spp));
        detect = detect.max(v.detectable_bias);
    }
    (failed, spp, detect)
}

#[test]
fn deliberate_biases_fail_the_default_tier() {
    assert_eq!(tier().name, "default", "the study measures the default tier");
    let mut rows = Vec::new();
    for scene in selected("SKELIGHT_POWER_SCENES", SCENES, true) {
        let target = ConformanceScene::load(scene);
        for spec in selected("SKELIGHT_POWER", ESTIMATORS, false) {
            let (name, params) = registry::parse_spec(spec).unwrap();
            let mut estimator = registry::create(&name, &params).unwrap();
            if let Some(why) = estimator.limitation(&target.scene) {
                println!("{spec} {}: skipped ({why})", target.name);
                continue;
            }
            mutation::reset();
            let base = luminance_mean(&render_spp(&target.scene, estimator.as_mut(), 32, 77));
            let mut shares = Vec::new();
            for s in Strategy::ALL {
                mutation::set(s, 0.0);
                let without = luminance_mean(&render_spp(&target.scene, estimator.as_mut(), 32, 77));
                mutation::reset();
                shares.push((s, 1.0 - without / base));
            }
            let (unmodified, spp, detect) = fails(&target, spec);
            let mut row = format!(
                "| {spec} | {} | {}–{} | {:.2} % | {}/{PAIRS} |",
                target.name,
                spp.0,
                spp.1,
                100.0 * detect,
                PAIRS - unmodified
            );
            for s in PARTITION {
                mutation::set(s, 1.02);
            }
            let (whole, _, _) = fails(&target, spec);
            mutation::reset();
            row += &format!(" {whole}/{PAIRS} |");
            let mut per_strategy = Vec::new();
            for &(s, share) in &shares {
                if share < 0.25 {
                    continue;
                }
                mutation::set(s, (1.0 + 0.02 / share) as f32);
                let (f, _, _) = fails(&target, spec);
                mutation::reset();
                per_strategy.push(format!("{} ({:.0} %): {f}/{PAIRS}", s.name(), 100.0 * share));
            }
            row += &format!(" {} |", per_strategy.join(", "));
            println!("{row}");
            rows.push(row);
        }
    }
    println!("\n| estimator | scene | spp judged | sees (99 %) | unmodified passes | 2 % on the image: fails | 2 %/share on a strategy: fails |");
    println!("|---|---|---|---|---|---|---|");
    for r in &rows {
        println!("{r}");
    }
}
