//! What the camera sees and how the film records it, checked across estimators: a near
//! clip hides the same surfaces for every strategy (pt sees them through primary rays that
//! start on the near plane, light tracing and BPT through connections to the lens), and
//! light-tracing splats are normalised like camera samples on every pixel, border and
//! corners included.

mod common;

use common::*;
use skelight::estimators::by_name;
use skelight::scene::Scene;

/// The Cornell box seen through a near plane: at 2.5 (the camera is 3.9 from the box's
/// centre) the plane lies in front of the box and clips nothing, but a camera vertex taken
/// on it instead of the lens gave bpt +17 % and ibpt +23 %; at 4.3 it cuts through both
/// cubes, whose fronts hide the back wall from connections to the lens unless those are
/// clipped too, and whose nearer halves no strategy may see. With a thin lens, light paths
/// also reach the aperture through the clipped region.
#[test]
fn every_estimator_sees_the_same_near_clipped_cornell_box() {
    // A card 2e-4 beyond the plane at 2.5 (z = 1.4 − 2e-4), in front of the open box: shadow
    // rays from the plane must not step over it.
    let card = r#"<shape type="rectangle"><transform name="to_world"><scale x="0.3" y="0.3"/><translate z="1.3998"/></transform><ref id="white"/></shape></scene>"#;
    for (name, near, with_card) in [
        ("c01_cbox_area", 2.5, false),
        ("c01_cbox_area", 2.5, true),
        ("c01_cbox_area", 4.3, false),
        ("c14_thinlens", 4.3, false),
    ] {
        println!("{name}, near clip {near}{}:", if with_card { ", a card just beyond it" } else { "" });
        let clip = format!(r#"<float name="fov" value="40"/><float name="near_clip" value="{near}"/>"#);
        let edit = |t: String| {
            let t = t.replace(r#"<float name="fov" value="40"/>"#, &clip);
            if with_card {
                t.replace("</scene>", card)
            } else {
                t
            }
        };
        let scene = edited_conformance_scene(name, edit, 48, 48);
        estimators_agree(&scene, &every_estimator_at_full_count());
    }
}

/// Mean over `seeds` independent renders of the mean of each pixel class (interior, edges
/// without corners, corners), summed over channels, and its standard error across seeds.
fn class_means(scene: &Scene, name: &str, spp: u32, seeds: u64) -> [(f64, f64); 3] {
    let mut integrator = by_name(name).unwrap();
    let (w, h) = (scene.settings.width, scene.settings.height);
    let class = |x: usize, y: usize| {
        let on_x = x == 0 || x == w - 1;
        let on_y = y == 0 || y == h - 1;
        (on_x as usize) + (on_y as usize)
    };
    let mut per_seed = vec![[0.0f64; 3]; seeds as usize];
    for (seed, out) in per_seed.iter_mut().enumerate() {
        let img = render_spp(scene, integrator.as_mut(), spp, 100 + seed as u64).image();
        let (mut sum, mut count) = ([0.0; 3], [0.0; 3]);
        for y in 0..h {
            for x in 0..w {
                let p = img.get(x, y);
                sum[class(x, y)] += (p.r + p.g + p.b) as f64;
                count[class(x, y)] += 1.0;
            }
        }
        *out = [0, 1, 2].map(|c| sum[c] / count[c]);
    }
    [0, 1, 2].map(|c| {
        let n = seeds as f64;
        let m = per_seed.iter().map(|s| s[c]).sum::<f64>() / n;
        let var = per_seed.iter().map(|s| (s[c] - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, (var / n).sqrt())
    })
}

/// c15 (tent filter) with the field of view narrowed to 15° so that the film's border is
/// lit: light tracing and path tracing agree on the interior, the edges and the corners.
/// Splats divided by the filter's whole footprint came out 0.87 on the edges and 0.73 in
/// the corners. Eight renders each; Welch's t between the class means (14 degrees of
/// freedom: |t| > 5.4 has p < 1e-4).
#[test]
fn light_tracing_matches_path_tracing_on_the_border_of_a_tent_filtered_film() {
    let scene = edited_conformance_scene(
        "c15_tent_filter",
        |t| t.replace(r#"<float name="fov" value="40"/>"#, r#"<float name="fov" value="15"/>"#),
        24,
        24,
    );
    let lt = class_means(&scene, "lt", 512, 8);
    let pt = class_means(&scene, "pt", 256, 8);
    for (c, label) in ["interior", "edges", "corners"].iter().enumerate() {
        let ((ml, sl), (mp, sp)) = (lt[c], pt[c]);
        let t = (ml - mp) / (sl * sl + sp * sp).sqrt();
        println!("{label:9}: lt {ml:.4} ± {sl:.4}, pt {mp:.4} ± {sp:.4}, ratio {:.4}, t {t:.2}", ml / mp);
        assert!(t.abs() < 5.4, "{label}: lt {ml} ± {sl} vs pt {mp} ± {sp} (t = {t:.2})");
    }
}
