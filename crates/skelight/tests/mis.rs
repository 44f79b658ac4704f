//! Multiple importance sampling of the bidirectional estimators: for random complete paths
//! in scenes with every kind of light, camera and BSDF, the weights of all the strategies
//! that can make a path sum to one, and the weight an estimator computes from the densities
//! its random walks recorded equals the one computed from densities evaluated afresh.

mod common;

use common::shared_dir;
use skelight::integrator::ibpt::{ibpt_strategies, ChainWeight, MisChain, Side};
use skelight::integrator::lt::camera_end_strategies;
use skelight::integrator::mis::{
    all_strategies, running_sums, weight, AllStrategies, Heuristic, Junction, PathWeight, StrategySet, SubPath,
};
use skelight::integrator::subpath::{camera_subpath, light_subpath};
use skelight::integrator::vertex::{Vertex, VertexKind};
use skelight::material::TransportMode;
use skelight::math::vec2;
use skelight::sampling::Rng;
use skelight::scene::load::load;
use skelight::scene::Scene;

/// A complete path x_0 (on a light) … x_k (on the lens), with which vertices were passed
/// through a specular lobe.
struct FullPath {
    x: Vec<Vertex>,
}

impl FullPath {
    /// Light-side (L_i) and camera-side (C_i) densities of every vertex, evaluated from
    /// scratch: per unit area (solid angle for distant lights), zero through specular lobes.
    fn densities(&self, scene: &Scene) -> (Vec<f32>, Vec<f32>) {
        let x = &self.x;
        let k = x.len() - 1;
        let mut l = vec![0.0; k + 1];
        let mut c = vec![0.0; k + 1];
        l[0] = x[0].pdf_light_origin(scene);
        l[1] = x[0].pdf_light(scene, &x[1]);
        for i in 2..=k {
            l[i] = if x[i - 1].delta { 0.0 } else { x[i - 1].pdf(scene, Some(&x[i - 2]), &x[i]) };
        }
        c[k] = scene.camera.pdf_we(scene.camera.forward).0;
        c[k - 1] = x[k].pdf(scene, None, &x[k - 1]);
        for i in (0..k - 1).rev() {
            c[i] = if x[i + 1].delta { 0.0 } else { x[i + 1].pdf(scene, Some(&x[i + 2]), &x[i]) };
        }
        (l, c)
    }

    /// Whether strategy s (s light vertices) can make this path.
    fn feasible(&self, scene: &Scene, s: usize) -> bool {
        let x = &self.x;
        let n = x.len();
        if n == 2 && (x[0].is_infinite() || !x[0].hittable(scene)) {
            // Lights without area are seen directly by the camera strategy only.
            return s == 0;
        }
        let splittable = |v: &Vertex| match v.kind {
            VertexKind::Surface => !v.delta,
            _ => true,
        };
        match s {
            0 => x[0].hittable(scene),
            _ if s == n => x[n - 1].hittable(scene),
            _ => splittable(&x[s - 1]) && splittable(&x[s]),
        }
    }

    /// The weight of strategy s, from densities evaluated afresh.
    fn weight(&self, scene: &Scene, s: usize, strategies: StrategySet) -> f32 {
        self.weight_with(scene, s, strategies, Heuristic::Balance)
    }

    fn weight_with(&self, scene: &Scene, s: usize, strategies: StrategySet, heuristic: Heuristic) -> f32 {
        let (l, c) = self.densities(scene);
        let light: Vec<Vertex> = (0..s).map(|i| Vertex { pdf_fwd: l[i], pdf_rev: c[i], ..self.x[i] }).collect();
        let camera: Vec<Vertex> =
            (s..self.x.len()).rev().map(|i| Vertex { pdf_fwd: c[i], pdf_rev: l[i], ..self.x[i] }).collect();
        weight(scene, SubPath::new(&light, None), SubPath::new(&camera, None), &Junction::NONE, heuristic, strategies)
    }

    /// Whether the path carries light (no zero factor a density of zero could hide behind).
    fn carries_light(&self, scene: &Scene) -> bool {
        let x = &self.x;
        let k = x.len() - 1;
        let emits = x[0].is_infinite() || !x[0].emission(scene, x[0].dir_to(&x[1])).is_black();
        let scatters =
            (1..k).all(|i| x[i].delta || !x[i].f(scene, &x[i - 1], &x[i + 1], TransportMode::Radiance).is_black());
        let we = scene.camera.pdf_we(x[k].dir_to(&x[k - 1])).1 > 0.0;
        emits && scatters && we
    }
}

/// The weight `ibpt` gives strategy s (0: the camera path hits the light, 1: next-event
/// estimation, k: the light path connects to the lens, k + 1: it passes through the lens),
/// computed as its walks do: earlier vertices folded into one running state, the last
/// three kept.
fn ibpt_weight(scene: &Scene, path: &FullPath, s: usize) -> f32 {
    let (l, c) = path.densities(scene);
    let k = path.x.len() - 1;
    let side = if s <= 1 { Side::Camera } else { Side::Light };
    // The walk's vertices a_0, a_1, … with own (F) and other-side (O) densities.
    let walk: Vec<Vertex> = match side {
        Side::Camera => (0..=k).map(|m| Vertex { pdf_fwd: c[k - m], pdf_rev: l[k - m], ..path.x[k - m] }).collect(),
        Side::Light => (0..=k).map(|m| Vertex { pdf_fwd: l[m], pdf_rev: c[m], ..path.x[m] }).collect(),
    };
    // Explicit strategies end the walk at a_{k−1}; the camera walk pushes the emitter it
    // hits, the light walk never pushes the lens.
    let last_pushed = if s == 0 { k } else { k - 1 };
    let mut chain = MisChain::new(walk[0].hittable(scene));
    for m in 0..(last_pushed + 1).saturating_sub(2) {
        chain.fold(m, walk[m].pdf_rev, walk[m].pdf_fwd, !walk[1].delta);
    }
    let window_start = last_pushed.saturating_sub(2);
    let w = ChainWeight { side, chain, window_start };
    let stored_to = |end: usize| SubPath::new(&walk[window_start..end], None);
    let implicit = || SubPath::new(&walk[window_start..k], Some(&walk[k]));
    // The other side's origin, with that side's densities.
    let b = Vertex { pdf_fwd: walk[k].pdf_rev, pdf_rev: walk[k].pdf_fwd, ..walk[k] };
    let other_origin = SubPath::new(&[], Some(&b));
    // Explicit strategies: the connection's own densities at a_{k−1}, as the estimator hands
    // them over, must weigh the path as densities evaluated afresh do.
    let joined = |light: SubPath, camera: SubPath| {
        let fresh = w.weight(scene, light, camera);
        let (aj, prev) = (&walk[k - 1], &walk[k.saturating_sub(2)]);
        if k < 2 || aj.kind != VertexKind::Surface {
            return fresh;
        }
        let mode = if side == Side::Camera { TransportMode::Radiance } else { TransportMode::Importance };
        let j = aj.join(scene, prev, &b, mode);
        let densities = Some(aj.end_densities(scene, &j, prev, &b));
        let junction = match side {
            Side::Camera => Junction { camera_end: densities, light_end: None },
            Side::Light => Junction { light_end: densities, camera_end: None },
        };
        let known = w.weight_joined(scene, light, camera, &junction);
        // The same floating-point operations either way: equal to the bit.
        assert_eq!(known.to_bits(), fresh.to_bits(), "ibpt s = {s}: joined {known}, fresh {fresh}");
        known
    };
    match s {
        0 => w.weight(scene, SubPath::EMPTY, implicit()),
        1 => joined(other_origin, stored_to(k)),
        _ if s == k => joined(stored_to(k), other_origin),
        _ => w.weight(scene, implicit(), SubPath::EMPTY),
    }
}

/// Complete paths made from random sub-paths: camera paths that hit an emitter, and every
/// join of a light and a camera sub-path at two vertices that can connect.
fn random_paths(scene: &Scene, count: usize) -> Vec<(FullPath, usize, f32)> {
    let mut out = Vec::new();
    let max_depth = 6;
    let (mut camera, mut light, mut hits) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..count as u64 {
        let mut rng = Rng::new(0xA11CE, i, 0);
        let (w, h) = (scene.settings.width as f32, scene.settings.height as f32);
        let raster = vec2(rng.next_f32() * w, rng.next_f32() * h);
        camera_subpath(scene, raster, &mut rng, max_depth, &mut camera);
        light_subpath(scene, &mut rng, max_depth, &mut light, &mut hits);
        // s = 0: the camera path's last vertex emits.
        if let Some(z) = camera.last().filter(|_| camera.len() >= 2) {
            let light_vertex = match z.kind {
                VertexKind::Surface if !scene.emitted(&z.si).is_black() => {
                    scene.mesh_light[z.si.mesh as usize].map(|li| z.as_light(li))
                }
                VertexKind::Escaped => scene
                    .infinite_lights
                    .iter()
                    .find(|&&li| scene.lights[li as usize].can_be_hit())
                    .map(|&li| z.as_infinite_light(li)),
                _ => None,
            };
            if let Some(lv) = light_vertex {
                let w = weight(
                    scene,
                    SubPath::EMPTY,
                    SubPath::new(&camera[..camera.len() - 1], Some(&lv)),
                    &Junction::NONE,
                    Heuristic::Balance,
                    &all_strategies,
                );
                let mut x: Vec<Vertex> = camera[..camera.len() - 1].iter().rev().copied().collect();
                x.insert(0, lv);
                out.push((FullPath { x }, 0, w));
            }
        }
        // s, t ≥ 2: every join of stored vertices.
        for s in 2..=light.len() {
            for t in 2..=camera.len() {
                if s + t > max_depth as usize + 1 {
                    continue;
                }
                let (y, z) = (&light[s - 1], &camera[t - 1]);
                if !y.can_connect(scene) || !z.can_connect(scene) || z.kind != VertexKind::Surface {
                    continue;
                }
                // With the densities the join computes along with the BSDFs, as `bpt` does
                // (compared below with densities evaluated afresh).
                let jy = y.join(scene, &light[s - 2], z, TransportMode::Importance);
                let jz = z.join(scene, &camera[t - 2], y, TransportMode::Radiance);
                let junction = Junction {
                    light_end: Some(y.end_densities(scene, &jy, &light[s - 2], z)),
                    camera_end: Some(z.end_densities(scene, &jz, &camera[t - 2], y)),
                };
                let w = weight(
                    scene,
                    SubPath::new(&light[..s], None),
                    SubPath::new(&camera[..t], None),
                    &junction,
                    Heuristic::Balance,
                    &all_strategies,
                );
                let mut x: Vec<Vertex> = light[..s].to_vec();
                x.extend(camera[..t].iter().rev().copied());
                // The ends of the join were connected through their non-specular parts.
                x[s - 1].delta = false;
                x[s].delta = false;
                out.push((FullPath { x }, s, w));
            }
        }
    }
    out
}

/// `bpt`'s weights from running sums of the stored sub-paths equal the weights evaluated
/// over the whole path, for every join of two stored sub-paths (s, t ≥ 1, the lens and the
/// light origin included) and both heuristics. Returns how many joins were compared.
fn check_running_sums(scene: &Scene, name: &str) -> usize {
    let max_depth = 6;
    let (mut camera, mut light, mut hits) = (Vec::new(), Vec::new(), Vec::new());
    let (mut camera_sums, mut light_sums) = (Vec::new(), Vec::new());
    let (mut compared, mut worst) = (0, 0.0f32);
    for i in 0..200u64 {
        let mut rng = Rng::new(0xB0B, i, 0);
        let (w, h) = (scene.settings.width as f32, scene.settings.height as f32);
        camera_subpath(scene, vec2(rng.next_f32() * w, rng.next_f32() * h), &mut rng, max_depth, &mut camera);
        light_subpath(scene, &mut rng, max_depth, &mut light, &mut hits);
        for heuristic in [Heuristic::Balance, Heuristic::Power] {
            running_sums(scene, &camera, heuristic, &mut camera_sums);
            running_sums(scene, &light, heuristic, &mut light_sums);
            let fast = AllStrategies { heuristic, light_sums: &light_sums, camera_sums: &camera_sums };
            for s in 1..=light.len() {
                for t in 1..=camera.len() {
                    let (l, c) = (SubPath::new(&light[..s], None), SubPath::new(&camera[..t], None));
                    let exact = weight(scene, l, c, &Junction::NONE, heuristic, &all_strategies);
                    let summed = fast.weight(scene, l, c);
                    // Both sum the same positive terms in another order: each term a product
                    // of up to n ratios (a division, squared for the power heuristic, and a
                    // product each), n additions and a reciprocal — within (4n + 2) ε of each
                    // other relatively, with no cancellation to amplify it.
                    let n = (s + t) as f32;
                    let bound = (4.0 * n + 2.0) * f32::EPSILON * exact + f32::MIN_POSITIVE;
                    worst = worst.max((summed - exact).abs() / (exact * f32::EPSILON));
                    assert!(
                        (summed - exact).abs() <= bound,
                        "{name}: {heuristic:?} weight of (s, t) = ({s}, {t}): running sums {summed}, exact {exact}"
                    );
                    compared += 1;
                }
            }
        }
    }
    println!("{name}: {compared} joins weighed by running sums, worst relative difference {worst} ε");
    compared
}

fn check_scene(name: &str) -> usize {
    let path = shared_dir().join("conformance/scenes").join(format!("{name}.xml"));
    let scene = load(&path, &[]).unwrap_or_else(|e| panic!("{name}: {e}"));
    let compared = check_running_sums(&scene, name);
    assert!(compared >= 500, "{name}: only {compared} joins compared with running sums");
    let (mut checked, mut differing, mut worst) = (0, 0, 0.0f32);
    for (path, s, recorded) in random_paths(&scene, 400) {
        if !path.carries_light(&scene) {
            continue;
        }
        let n = path.x.len();
        let sum: f32 =
            (0..=n).filter(|&sp| path.feasible(&scene, sp)).map(|sp| path.weight(&scene, sp, &all_strategies)).sum();
        assert!((sum - 1.0).abs() < 2e-3, "{name}: weights of a {n}-vertex path sum to {sum}");
        // Light tracing's subset (t ≤ 1) weighs the strategies it has the same way.
        let lt: Vec<usize> = (n.saturating_sub(1)..=n).filter(|&sp| path.feasible(&scene, sp)).collect();
        if !lt.is_empty() {
            let sum: f32 = lt.iter().map(|&sp| path.weight(&scene, sp, &camera_end_strategies)).sum();
            assert!((sum - 1.0).abs() < 2e-3, "{name}: lt weights of a {n}-vertex path sum to {sum}");
        }
        // ibpt's four strategies, weighted by its running state, against exact MIS.
        let ibpt: Vec<usize> = [0, 1, n - 1, n]
            .into_iter()
            .filter(|&sp| path.feasible(&scene, sp) && ibpt_strategies(sp, n - sp))
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        let mut sum = 0.0;
        for &sp in &ibpt {
            let (chained, exact) =
                (ibpt_weight(&scene, &path, sp), path.weight_with(&scene, sp, &ibpt_strategies, Heuristic::Power));
            assert!(
                (chained - exact).abs() < 1e-3 * exact.max(1e-2),
                "{name}: ibpt strategy s = {sp} of a {n}-vertex path: running weight {chained}, exact {exact}"
            );
            sum += chained;
        }
        if !ibpt.is_empty() {
            assert!((sum - 1.0).abs() < 2e-3, "{name}: ibpt weights of a {n}-vertex path sum to {sum}");
        }
        let fresh = path.weight(&scene, s, &all_strategies);
        let error = (fresh - recorded).abs() / fresh.max(1e-3);
        if error > 1e-3 {
            differing += 1;
            worst = worst.max(error);
        }
        checked += 1;
    }
    println!("{name}: {checked} paths, {differing} with recorded weights off by > 0.1 % (worst {worst})");
    // Walks offset each ray's origin from its surface, so where two vertices lie close
    // together (in a corner) the recorded direction differs slightly from the one between
    // the vertices; a wrong density would show on most paths, not a few.
    assert!(differing * 50 <= checked, "{name}: {differing} of {checked} paths have recorded weights off by > 0.1 %");
    assert!(worst < 0.1, "{name}: a recorded weight is off by {worst}");
    checked
}

#[test]
fn bidirectional_mis_weights_sum_to_one() {
    // Area, point, spot, directional, constant and environment lights; diffuse, mirror,
    // glass, plastic (specular over diffuse) and rough surfaces; pinhole and thin lens.
    let scenes = [
        "c01_cbox_area",
        "c02_point",
        "c03_spot",
        "c04_directional",
        "c06_envmap",
        "c07_roughconductor",
        "c08_mirror",
        "c09_glass",
        "c11_plastic",
        "c14_thinlens",
        "c18_sphere_light",
    ];
    for name in scenes {
        let checked = check_scene(name);
        assert!(checked >= 100, "{name}: only {checked} complete paths were checked");
    }
}
