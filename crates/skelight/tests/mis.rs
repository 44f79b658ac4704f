//! Multiple importance sampling of the bidirectional estimators.
//!
//! MIS weights are ratios of the densities with which each strategy makes a path. The
//! densities here are written out plainly from the sampling routines (a BSDF's, a light's
//! and the camera's own density per solid angle, turned into a density per unit area by
//! |cos| / distance² at the receiving vertex), independently of the `Vertex` code the
//! estimators use, and checked three ways:
//! - every density the random walks record equals this evaluation along the directions the
//!   walks actually took (rays leave from origins offset off the surface), within a
//!   tolerance worked out from how much the density changes when the direction moves by the
//!   rounding error of a hit point;
//! - the weights of all the strategies that can make a path, from these densities, sum to
//!   one, for bpt, lt's subset and ibpt's four strategies;
//! - bpt's running sums and ibpt's running product weigh paths as exact MIS does.

mod common;

use common::{edited_conformance_scene, shared_dir};
use skelight::geometry::offset_origin;
use skelight::material::TransportMode;
use skelight::material::{BsdfCtx, BsdfModel};
use skelight::math::{vec2, Frame, Vec3};
use skelight::paths::mis::{
    all_strategies, running_sums, weight, AllStrategies, Heuristic, Junction, PathWeight, StrategySet, SubPath,
};
use skelight::paths::mis_chain::{ibpt_strategies, ChainWeight, MisChain, Side};
use skelight::paths::strategies::camera_end_strategies;
use skelight::paths::subpath::{camera_subpath, light_subpath};
use skelight::paths::vertex::{LensHit, Vertex, VertexKind};
use skelight::sampling::Rng;
use skelight::scene::load::load;
use skelight::scene::Scene;

/// Density per solid angle with which vertex `v`, reached from direction `wi` (pointing away
/// from `v`; unused at sub-path origins), samples direction `wo`: the camera's (a uniform
/// point on the film at unit depth: 1 / (A_film cos³θ)), an emitter's (its own routine), or
/// the BSDF's in the transport mode of the walk that samples it. Zero through specular lobes.
fn solid_angle_density(scene: &Scene, v: &Vertex, wi: Vec3, wo: Vec3, mode: TransportMode) -> f32 {
    match v.kind {
        VertexKind::Camera => {
            let cam = &scene.camera;
            let cos = wo.dot(cam.forward);
            if cos <= 0.0 {
                return 0.0;
            }
            1.0 / (4.0 * cam.tan_half.x * cam.tan_half.y * cos * cos * cos)
        }
        VertexKind::Light { light, infinite: false } => scene.lights[light as usize].pdf_le_direction(v.n(), wo),
        VertexKind::Surface if !v.delta => {
            let bsdf = &scene.materials[v.si.material as usize].bsdf;
            let f = &v.si.frame;
            bsdf.pdf(&BsdfCtx { uv: v.si.uv, mode }, f.to_local(wi), f.to_local(wo))
        }
        _ => 0.0,
    }
}

/// Where a vertex is as far as densities go: the lens point for the camera (the centre of
/// a pinhole; on a thin lens, where the line to the next vertex `towards` crosses the lens
/// plane, whatever point of that line the vertex was stored at), its position otherwise.
fn position(scene: &Scene, v: &Vertex, towards: Option<&Vertex>) -> Vec3 {
    let cam = &scene.camera;
    match (v.kind, towards) {
        (VertexKind::Camera, _) if cam.aperture_radius <= 0.0 => cam.position,
        (VertexKind::Camera, Some(q)) if !q.is_infinite() => {
            let d = (q.p() - v.p()).normalize();
            q.p() - d * ((q.p() - cam.position).dot(cam.forward) / d.dot(cam.forward))
        }
        _ => v.p(),
    }
}

/// Turns a density per solid angle at `from` into one per unit area at `to`: |cos| at `to`
/// over the squared distance (1 / distance² where `to` has no normal), and nothing for
/// vertices at infinity, whose densities stay per solid angle.
fn per_area(from: Vec3, to: &Vertex, to_position: Vec3) -> f32 {
    if to.is_infinite() {
        return 1.0;
    }
    let d = to_position - from;
    let dist2 = d.length_squared();
    let n = to.n();
    if n.length_squared() > 0.0 {
        n.normalize().dot(d / dist2.sqrt()).abs() / dist2
    } else {
        1.0 / dist2
    }
}

/// Density (per unit area at `next`, per solid angle at infinity) with which `v`, reached
/// from `prev`, samples `next` along the unit direction `wo` (`wi` towards `prev`).
#[allow(clippy::too_many_arguments)]
fn plain_density(
    scene: &Scene,
    v: &Vertex,
    v_at: Vec3,
    wi: Vec3,
    wo: Vec3,
    next: &Vertex,
    next_at: Vec3,
    mode: TransportMode,
) -> f32 {
    if let VertexKind::Light { infinite: true, .. } = v.kind {
        // Rays start uniformly on a disk across the emission sphere, along the travel
        // direction: per unit area at `next`, the disk's density times |cos| there.
        let (_, radius) = scene.emission_sphere();
        let n = next.n();
        let cos = if n.length_squared() > 0.0 { n.normalize().dot(v.n()).abs() } else { 1.0 };
        return cos / (std::f32::consts::PI * radius * radius);
    }
    solid_angle_density(scene, v, wi, wo, mode) * per_area(v_at, next, next_at)
}

/// A complete path x_0 (on a light) … x_k (on the lens), with which vertices were passed
/// through a specular lobe.
struct FullPath {
    x: Vec<Vertex>,
}

impl FullPath {
    /// Light-side (L_i) and camera-side (C_i) densities of every vertex, evaluated plainly
    /// along the straight lines between the vertices (as connections see them); each side's
    /// BSDFs sampled in that side's transport mode.
    fn densities(&self, scene: &Scene) -> (Vec<f32>, Vec<f32>) {
        let x = &self.x;
        let k = x.len() - 1;
        let at: Vec<Vec3> = (0..=k).map(|i| position(scene, &x[i], (i == k).then(|| &x[k - 1]))).collect();
        let dir = |i: usize, j: usize| {
            if x[j].is_infinite() {
                -x[j].n()
            } else if x[i].is_infinite() {
                x[i].n()
            } else {
                (at[j] - at[i]).normalize()
            }
        };
        let mut l = vec![0.0; k + 1];
        let mut c = vec![0.0; k + 1];
        l[0] = origin_density(scene, &x[0]);
        for i in 1..=k {
            let wi = if i >= 2 { dir(i - 1, i - 2) } else { Vec3::ZERO };
            l[i] =
                plain_density(scene, &x[i - 1], at[i - 1], wi, dir(i - 1, i), &x[i], at[i], TransportMode::Importance);
        }
        c[k] = origin_density(scene, &x[k]);
        for i in (0..k).rev() {
            let wi = if i + 2 <= k { dir(i + 1, i + 2) } else { Vec3::ZERO };
            c[i] = plain_density(scene, &x[i + 1], at[i + 1], wi, dir(i + 1, i), &x[i], at[i], TransportMode::Radiance);
        }
        (l, c)
    }

    /// Σ over the path's segments of the relative rounding of the cosines at both ends
    /// (8 ε / |cos|): a segment nearly in the plane of a surface it joins (a walk that
    /// grazed a leaf and hit it again) makes densities of 1e-15 whose ratios no evaluation
    /// gets to f32 precision, and the weights of strategies evaluated apart disagree by as
    /// much.
    fn cosine_uncertainty(&self, scene: &Scene) -> f32 {
        let x = &self.x;
        let mut sum = 0.0;
        for i in 0..x.len() - 1 {
            let (a, b) = (&x[i], &x[i + 1]);
            if a.is_infinite() || b.is_infinite() {
                continue;
            }
            let (pa, pb) = (position(scene, a, Some(b)), position(scene, b, Some(a)));
            let d = (pb - pa).normalize();
            for n in [a.n(), b.n()] {
                if n.length_squared() > 0.0 {
                    sum += 8.0 * f32::EPSILON / n.normalize().dot(d).abs().max(1e-30);
                }
            }
        }
        sum
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

/// Density with which a sub-path starts at `v`: a point on the lens (uniform over the
/// aperture; 1 for a pinhole), or a light chosen by power and a point on it (a direction,
/// for lights at infinity).
fn origin_density(scene: &Scene, v: &Vertex) -> f32 {
    match v.kind {
        VertexKind::Camera => {
            let r = scene.camera.aperture_radius;
            if r > 0.0 {
                1.0 / (std::f32::consts::PI * r * r)
            } else {
                1.0
            }
        }
        VertexKind::Light { light, .. } => {
            scene.light_distribution.pmf(light as usize) * scene.lights[light as usize].pdf_le_origin(v.n())
        }
        _ => 0.0,
    }
}

/// The unit direction in which the walk that made a sub-path went from `a` to the vertex
/// after it, `b`: rays leave surfaces and area lights from a point offset along the normal
/// (`offset_origin`), the camera's along the line from the lens, lights at infinity along
/// their direction of travel, and an escaped path along the direction it stored.
fn walked(scene: &Scene, a: &Vertex, b: &Vertex) -> Vec3 {
    if b.kind == VertexKind::Escaped {
        return -b.n();
    }
    if a.is_infinite() {
        return a.n();
    }
    let offset = a.kind == VertexKind::Surface || (a.is_light() && a.hittable(scene));
    let o = if offset { offset_origin(a.p(), a.n(), b.p() - a.p()) } else { a.p() };
    (b.p() - o).normalize()
}

/// The largest relative error one density evaluation may carry: a few dozen floating-point
/// operations, some transcendental (64 ε).
const EVALUATION_ERROR: f32 = 64.0 * f32::EPSILON;

/// A density the walk recorded against the plain evaluation along the walked directions
/// `wi`, `wo` at `v`. The tolerance: the evaluation's own rounding, plus how much the
/// density changes when the directions turn by the error of the hit points that define
/// them (64 ε (1 + |p|) / d: ulps of the coordinates over the distance, with a margin —
/// 16 ε left 2 of ~3 900 densities on rough glass, 1e-4 and 3e-4 off, outside), each
/// direction turned four ways and both together, and
/// the rounding of the cosine at the receiving end (8 ε over the cosine).
/// Returns the error over the tolerance (≤ 1 passes).
#[allow(clippy::too_many_arguments)]
fn recorded_vs_plain(
    scene: &Scene,
    v: &Vertex,
    v_at: Vec3,
    wi: Vec3,
    wo: Vec3,
    next: &Vertex,
    next_at: Vec3,
    mode: TransportMode,
    recorded: f32,
) -> (f32, f32) {
    let expected = plain_density(scene, v, v_at, wi, wo, next, next_at, mode);
    let scale = 1.0 + v_at.abs().max_component().max(next_at.abs().max_component());
    let dist = if next.is_infinite() { 1.0 } else { (next_at - v_at).length() };
    let turn = 64.0 * f32::EPSILON * scale / dist;
    let turns = |w: Vec3| -> Vec<Vec3> {
        if w == Vec3::ZERO {
            return vec![w];
        }
        let f = Frame::from_normal(w);
        let mut out = vec![w];
        out.extend([f.s, f.t, -f.s, -f.t].iter().map(|&side| (w + side * turn).normalize()));
        out
    };
    let mut spread = 0.0f32;
    for wi2 in turns(wi) {
        for wo2 in turns(wo) {
            spread = spread.max((plain_density(scene, v, v_at, wi2, wo2, next, next_at, mode) - expected).abs());
        }
    }
    // The cosine at the receiving end is a dot product of unit vectors, off by a few ε
    // absolutely: relatively large at grazing angles.
    let n = next.n();
    let cos_error = if next.is_infinite() || n.length_squared() == 0.0 {
        0.0
    } else {
        8.0 * f32::EPSILON / n.normalize().dot((next_at - v_at).normalize()).abs().max(1e-30)
    };
    let tolerance = spread + (EVALUATION_ERROR + cos_error) * expected + f32::MIN_POSITIVE;
    ((recorded - expected).abs() / tolerance, expected)
}

/// Checks every density a random walk recorded in `path` (walk order; `mode` its transport)
/// and in its lens passages against the plain evaluation. Returns (densities checked, the
/// worst error over its tolerance).
fn check_walk(scene: &Scene, name: &str, path: &[Vertex], hits: &[LensHit], mode: TransportMode) -> (usize, f32) {
    let n = path.len();
    let at: Vec<Vec3> = (0..n).map(|i| position(scene, &path[i], path.get(1).filter(|_| i == 0))).collect();
    // wi at vertex i: back along the direction the walk arrived by.
    let wi = |i: usize| if i == 0 { Vec3::ZERO } else { -walked(scene, &path[i - 1], &path[i]) };
    let (mut checked, mut worst) = (0, 0.0f32);
    let mut check = |what: &str, i: usize, ratio: (f32, f32), recorded: f32| {
        assert!(
            ratio.0 <= 1.0,
            "{name}: {mode:?} walk of {n} vertices, {what} of vertex {i}: recorded {recorded}, plain {}",
            ratio.1
        );
        worst = worst.max(ratio.0);
        checked += 1;
    };
    if n > 0 {
        let (r, e) = (path[0].pdf_fwd, origin_density(scene, &path[0]));
        check("origin density", 0, ((r - e).abs() / (EVALUATION_ERROR * e + f32::MIN_POSITIVE), e), r);
    }
    for i in 1..n {
        let (v, next) = (&path[i - 1], &path[i]);
        let wo = walked(scene, v, next);
        let ratio = recorded_vs_plain(scene, v, at[i - 1], wi(i - 1), wo, next, at[i], mode, next.pdf_fwd);
        check("forward density", i, ratio, next.pdf_fwd);
        // The walk left path[i] towards path[i + 1] and recorded the reverse density of
        // path[i − 1] (with wi and wo swapped at path[i]).
        if i + 1 < n && path[i].kind == VertexKind::Surface {
            let wo = walked(scene, &path[i], &path[i + 1]);
            let ratio = recorded_vs_plain(scene, &path[i], at[i], wo, wi(i), v, at[i - 1], mode, v.pdf_rev);
            check("reverse density", i - 1, ratio, v.pdf_rev);
        }
    }
    for hit in hits {
        let m = hit.light_vertices as usize;
        let (v, lens) = (&path[m - 1], &hit.vertex);
        let wo = walked(scene, v, lens);
        let ratio = recorded_vs_plain(scene, v, at[m - 1], wi(m - 1), wo, lens, lens.p(), mode, lens.pdf_fwd);
        check("lens passage density", m, ratio, lens.pdf_fwd);
    }
    (checked, worst)
}

/// Every density recorded by the camera and light walks of 300 samples of `scene`.
fn check_recorded_densities(scene: &Scene, name: &str) {
    let (mut camera, mut light, mut hits) = (Vec::new(), Vec::new(), Vec::new());
    let (mut checked, mut worst) = (0, 0.0f32);
    for i in 0..300u64 {
        let mut rng = Rng::new(0xDE75, i, 0);
        let (w, h) = (scene.settings.width as f32, scene.settings.height as f32);
        camera_subpath(scene, vec2(rng.next_f32() * w, rng.next_f32() * h), &mut rng, 6, &mut camera);
        light_subpath(scene, &mut rng, 6, &mut light, &mut hits);
        for (c, wst) in [
            check_walk(scene, name, &camera, &[], TransportMode::Radiance),
            check_walk(scene, name, &light, &hits, TransportMode::Importance),
        ] {
            checked += c;
            worst = worst.max(wst);
        }
    }
    println!(
        "{name}: {checked} recorded densities equal the plain evaluation; worst error {worst:.3} of its tolerance"
    );
    assert!(checked >= 600, "{name}: only {checked} densities checked");
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
/// join of a light and a camera sub-path at two vertices that can connect. The densities
/// each join works out at its two ends (as `bpt` hands them to MIS) are checked against
/// the plain evaluation along the connecting segment; returns the paths, how many
/// densities were checked and the worst error over its tolerance.
fn random_paths(scene: &Scene, name: &str, count: usize) -> (Vec<FullPath>, usize, f32) {
    let mut out = Vec::new();
    let max_depth = 6;
    let (mut camera, mut light, mut hits) = (Vec::new(), Vec::new(), Vec::new());
    let (mut checked, mut worst) = (0, 0.0f32);
    let line = |a: &Vertex, b: &Vertex| (b.p() - a.p()).normalize();
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
                let mut x: Vec<Vertex> = camera[..camera.len() - 1].iter().rev().copied().collect();
                x.insert(0, lv);
                out.push(FullPath { x });
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
                let (y_prev, z_prev) = (&light[s - 2], &camera[t - 2]);
                // Joins go through the ends' non-specular parts, whichever lobe their walks
                // left them by.
                let (y, z) = (&Vertex { delta: false, ..*y }, &Vertex { delta: false, ..*z });
                let jy = y.join(scene, y_prev, z, TransportMode::Importance);
                let jz = z.join(scene, z_prev, y, TransportMode::Radiance);
                let (ey, ez) = (y.end_densities(scene, &jy, y_prev, z), z.end_densities(scene, &jz, z_prev, y));
                // At y: z sampled light-side (importance), y's predecessor camera-side
                // (radiance); at z the other way round. Along straight lines.
                let (y_prev_at, z_prev_at) = (position(scene, y_prev, None), position(scene, z_prev, Some(z)));
                let y_in = if y_prev.is_infinite() { -y_prev.n() } else { line(y, y_prev) };
                let z_in = line(z, z_prev);
                let (y_z, z_y) = (line(y, z), line(z, y));
                use TransportMode::{Importance, Radiance};
                for (what, ratio, recorded) in [
                    ("y → z", recorded_vs_plain(scene, y, y.p(), y_in, y_z, z, z.p(), Importance, ey.next), ey.next),
                    (
                        "y → its predecessor",
                        recorded_vs_plain(scene, y, y.p(), y_z, y_in, y_prev, y_prev_at, Radiance, ey.prev),
                        ey.prev,
                    ),
                    ("z → y", recorded_vs_plain(scene, z, z.p(), z_in, z_y, y, y.p(), Radiance, ez.next), ez.next),
                    (
                        "z → its predecessor",
                        recorded_vs_plain(scene, z, z.p(), z_y, z_in, z_prev, z_prev_at, Importance, ez.prev),
                        ez.prev,
                    ),
                ] {
                    assert!(
                        ratio.0 <= 1.0,
                        "{name}: join (s, t) = ({s}, {t}), density {what}: the join's {recorded}, plain {}",
                        ratio.1
                    );
                    worst = worst.max(ratio.0);
                    checked += 1;
                }
                let mut x: Vec<Vertex> = light[..s].to_vec();
                x.extend(camera[..t].iter().rev().copied());
                // The ends of the join were connected through their non-specular parts.
                x[s - 1].delta = false;
                x[s].delta = false;
                out.push(FullPath { x });
            }
        }
    }
    (out, checked, worst)
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

/// The weights of a path's strategies sum to one up to rounding: each weight is a product
/// of up to n density ratios (a division each, squared for the power heuristic), summed over
/// up to n + 1 terms and inverted — within (4n + 2) ε relatively — and there are n + 1 of
/// them. Densities themselves carry the rounding of their cosines ([`FullPath::cosine_uncertainty`]),
/// which the weights of different strategies take from different evaluations.
fn sum_tolerance(n: usize) -> f32 {
    (n as f32 + 1.0) * (4.0 * n as f32 + 2.0) * f32::EPSILON
}

fn check_scene(scene: &Scene, name: &str) -> usize {
    check_recorded_densities(scene, name);
    let compared = check_running_sums(scene, name);
    assert!(compared >= 500, "{name}: only {compared} joins compared with running sums");
    let (paths, joins, worst) = random_paths(scene, name, 400);
    println!(
        "{name}: {joins} densities at the ends of joins equal the plain evaluation; worst {worst:.3} of its tolerance"
    );
    let mut checked = 0;
    for path in paths {
        if !path.carries_light(scene) {
            continue;
        }
        let n = path.x.len();
        let tolerance = sum_tolerance(n) + 2.0 * path.cosine_uncertainty(scene);
        let sum: f32 =
            (0..=n).filter(|&sp| path.feasible(scene, sp)).map(|sp| path.weight(scene, sp, &all_strategies)).sum();
        assert!((sum - 1.0).abs() <= tolerance, "{name}: weights of a {n}-vertex path sum to {sum}");
        // Light tracing's subset (t ≤ 1) weighs the strategies it has the same way.
        let lt: Vec<usize> = (n.saturating_sub(1)..=n).filter(|&sp| path.feasible(scene, sp)).collect();
        if !lt.is_empty() {
            let sum: f32 = lt.iter().map(|&sp| path.weight(scene, sp, &camera_end_strategies)).sum();
            assert!((sum - 1.0).abs() <= tolerance, "{name}: lt weights of a {n}-vertex path sum to {sum}");
        }
        // ibpt's four strategies, weighted by its running state, against exact MIS.
        let ibpt: Vec<usize> = [0, 1, n - 1, n]
            .into_iter()
            .filter(|&sp| path.feasible(scene, sp) && ibpt_strategies(sp, n - sp))
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        let mut sum = 0.0;
        for &sp in &ibpt {
            let (chained, exact) =
                (ibpt_weight(scene, &path, sp), path.weight_with(scene, sp, &ibpt_strategies, Heuristic::Power));
            assert!(
                (chained - exact).abs() <= 2.0 * sum_tolerance(n) * exact + f32::MIN_POSITIVE,
                "{name}: ibpt strategy s = {sp} of a {n}-vertex path: running weight {chained}, exact {exact}"
            );
            sum += chained;
        }
        if !ibpt.is_empty() {
            assert!((sum - 1.0).abs() <= tolerance, "{name}: ibpt weights of a {n}-vertex path sum to {sum}");
        }
        checked += 1;
    }
    println!("{name}: the strategies' weights of {checked} complete paths sum to one");
    checked
}

#[test]
fn bidirectional_mis_weights_sum_to_one() {
    // Area, point, spot, directional, constant and environment lights; diffuse, mirror,
    // glass, rough glass, plastic (specular over diffuse), rough conductors and an alpha
    // mask; pinhole and thin lens.
    let scenes = [
        "c01_cbox_area",
        "c02_point",
        "c03_spot",
        "c04_directional",
        "c05_constant_env",
        "c06_envmap",
        "c07_roughconductor",
        "c08_mirror",
        "c09_glass",
        "c10_roughglass",
        "c11_plastic",
        "c13_mask_twosided",
        "c14_thinlens",
        "c18_sphere_light",
    ];
    for name in scenes {
        let path = shared_dir().join("conformance/scenes").join(format!("{name}.xml"));
        let scene = load(&path, &[]).unwrap_or_else(|e| panic!("{name}: {e}"));
        let checked = check_scene(&scene, name);
        assert!(checked >= 100, "{name}: only {checked} complete paths were checked");
    }
}

/// The same with a near clip (the camera vertex is the lens point, not the ray's origin on
/// the near plane), with a pinhole and a thin lens, and under Mitsuba's `sunsky`.
#[test]
fn bidirectional_mis_weights_sum_to_one_with_near_clip_and_sunsky() {
    let clip = |t: String| {
        t.replace(
            r#"<float name="fov" value="40"/>"#,
            r#"<float name="fov" value="40"/><float name="near_clip" value="2.5"/>"#,
        )
    };
    let sunsky = |t: String| {
        t.replace(
            r#"<emitter type="constant"><rgb name="radiance" value="1.0"/></emitter>"#,
            r#"<emitter type="sunsky"><vector name="sun_direction" value="0.4, 0.8, 0.45"/></emitter>"#,
        )
    };
    for (label, scene) in [
        ("c01 near clip 2.5", edited_conformance_scene("c01_cbox_area", clip, 128, 128)),
        ("c14 near clip 2.5", edited_conformance_scene("c14_thinlens", clip, 128, 128)),
        ("c05 under sunsky", edited_conformance_scene("c05_constant_env", sunsky, 128, 128)),
    ] {
        let checked = check_scene(&scene, label);
        assert!(checked >= 100, "{label}: only {checked} complete paths were checked");
    }
}
