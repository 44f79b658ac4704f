//! Exact multiple-importance-sampling weights for bidirectional strategies (thesis §4.1.3,
//! eq. 102–125), by direct evaluation of density ratios along the whole path, as pbrt does.
//!
//! A path x_0 … x_k (x_0 on a light, x_k on the camera) made by strategy s takes x_0 … x_{s−1}
//! from the light sub-path and x_s … x_k from the camera sub-path (t = k + 1 − s). With L_i
//! and C_i the densities of x_i under light-side and camera-side sampling,
//! p_{s'} / p_s = Π_{i=s'}^{s−1} C_i / L_i for s' < s, and Π_{i=s}^{s'−1} L_i / C_i for s' > s.
//! Densities through a specular vertex are recorded as 0 and count as 1 here: they appear in
//! every strategy that can make the path, so they cancel.

use super::vertex::{EndDensities, Vertex};
use crate::scene::Scene;

/// How strategies' densities combine into weights (Veach's heuristics).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Heuristic {
    #[default]
    Balance,
    Power,
}

impl Heuristic {
    /// The heuristic's term for a strategy whose density is `ratio` times this one's.
    #[inline]
    pub fn apply(self, ratio: f32) -> f32 {
        match self {
            Heuristic::Balance => ratio,
            Heuristic::Power => ratio * ratio,
        }
    }
    pub fn parse(name: &str) -> Option<Heuristic> {
        match name {
            "balance" => Some(Heuristic::Balance),
            "power" => Some(Heuristic::Power),
            _ => None,
        }
    }
}

/// One side of a path: stored vertices followed by an optional vertex made for this
/// connection (a light point sampled from the camera side, a sampled lens point, the
/// emitter the camera path hit, the lens the light path hit).
#[derive(Clone, Copy)]
pub struct SubPath<'a> {
    pub stored: &'a [Vertex],
    pub last: Option<&'a Vertex>,
}

impl<'a> SubPath<'a> {
    pub fn new(stored: &'a [Vertex], last: Option<&'a Vertex>) -> SubPath<'a> {
        SubPath { stored, last }
    }
    pub const EMPTY: SubPath<'static> = SubPath { stored: &[], last: None };
    pub fn len(&self) -> usize {
        self.stored.len() + self.last.is_some() as usize
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The vertices from the sub-path's origin on.
    pub fn iter(&self) -> impl DoubleEndedIterator<Item = &'a Vertex> {
        self.stored.iter().chain(self.last)
    }
    #[inline]
    pub fn get(&self, i: usize) -> &'a Vertex {
        if i < self.stored.len() {
            &self.stored[i]
        } else {
            self.last.expect("vertex index within the sub-path")
        }
    }
}

/// Which strategies an estimator has: `(s, t)` → whether it samples paths that way.
pub type StrategySet<'a> = &'a dyn Fn(usize, usize) -> bool;

/// All (s, t) strategies: bidirectional path tracing.
pub fn all_strategies(_s: usize, _t: usize) -> bool {
    true
}

/// Densities a connection's ends computed along with their BSDF values ([`Vertex::join`]),
/// handed to the weight so that it does not evaluate the BSDFs again: at the light end y,
/// `next` is the camera end z and `prev` y's predecessor; at the camera end z, `next` is y
/// and `prev` z's predecessor. `None` where not known (an end that is not a surface).
#[derive(Clone, Copy, Debug, Default)]
pub struct Junction {
    pub light_end: Option<EndDensities>,
    pub camera_end: Option<EndDensities>,
}

impl Junction {
    pub const NONE: Junction = Junction { light_end: None, camera_end: None };
}

/// How an estimator weighs the path made by joining a light and a camera sub-path.
pub trait PathWeight {
    /// The weight, given densities the connection computed already.
    fn weight_joined(&self, scene: &Scene, light: SubPath, camera: SubPath, junction: &Junction) -> f32;
    /// The weight, every density evaluated as needed.
    fn weight(&self, scene: &Scene, light: SubPath, camera: SubPath) -> f32 {
        self.weight_joined(scene, light, camera, &Junction::NONE)
    }
}

/// Densities through a specular lobe are recorded as 0; they cancel between strategies.
#[inline]
pub fn remap_delta(pdf: f32) -> f32 {
    if pdf != 0.0 {
        pdf
    } else {
        1.0
    }
}

/// MIS weight of the path made by joining `light` (s vertices) and `camera` (t vertices),
/// among the strategies in `strategies` that can make it; `junction` holds densities at the
/// connection already known.
pub fn weight(
    scene: &Scene,
    light: SubPath,
    camera: SubPath,
    junction: &Junction,
    heuristic: Heuristic,
    strategies: StrategySet,
) -> f32 {
    let (s, t) = (light.len(), camera.len());
    let n = s + t;
    if n < 2 {
        return 0.0;
    }
    let v = |i: usize| if i < s { light.get(i) } else { camera.get(n - 1 - i) };
    // A light seen directly: only the camera can see lights without area (for every
    // estimator alike, so pinhole and point light images agree), and distant lights.
    if n == 2 && !v(0).seen_by_other_strategies(scene) {
        return if s == 0 { 1.0 } else { 0.0 };
    }
    // Each vertex's light-side and camera-side densities and whether the path can be split
    // there, gathered once (on the stack for paths of up to `INLINE` vertices).
    const INLINE: usize = 16;
    let mut inline = [PathPoint::default(); INLINE];
    let mut heap = Vec::new();
    let points: &mut [PathPoint] = if n <= INLINE {
        &mut inline[..n]
    } else {
        heap.resize(n, PathPoint::default());
        &mut heap
    };
    let (light_side, camera_side) = points.split_at_mut(s);
    for (p, x) in light_side.iter_mut().zip(light.iter()) {
        *p = PathPoint { l: x.pdf_fwd, c: x.pdf_rev, splittable: x.connectible() };
    }
    for (p, x) in camera_side.iter_mut().zip(camera.iter().rev()) {
        *p = PathPoint { l: x.pdf_rev, c: x.pdf_fwd, splittable: x.connectible() };
    }
    // Densities of the four vertices around the connection change with it.
    let mut set = |i: usize, l: Option<f32>, c: Option<f32>| {
        if let Some(l) = l {
            points[i].l = l;
        }
        if let Some(c) = c {
            points[i].c = c;
        }
    };
    if s > 0 && t > 0 {
        let r = Rejoined::new(scene, light, camera, junction);
        set(s - 1, None, Some(r.light_end));
        if let Some(c) = r.light_before_end {
            set(s - 2, None, Some(c));
        }
        set(s, Some(r.camera_end), None);
        if let Some(l) = r.camera_before_end {
            set(s + 1, Some(l), None);
        }
    } else if s == 0 {
        let x0 = v(0);
        set(0, Some(x0.pdf_light_origin(scene)), None);
        set(1, Some(x0.pdf_light(scene, v(1))), None);
    } else {
        let lens = v(n - 1);
        set(n - 1, None, Some(scene.camera.pdf_we(scene.camera.forward).0));
        set(n - 2, None, Some(lens.pdf(scene, None, v(n - 2))));
    }
    // The two ends of this connection were joined through their non-specular parts,
    // whichever lobe their own sub-paths went on with.
    if s > 0 && t > 0 {
        points[s - 1].splittable = true;
        points[s].splittable = true;
    }
    let points = &*points;
    // Whether strategy sp (sp light vertices) can make the path too; the two ends are
    // asked once, not per strategy.
    let (first_hittable, last_hittable) = (v(0).hittable(scene), v(n - 1).hittable(scene));
    let valid = |sp: usize| {
        let possible = match sp {
            0 => first_hittable,
            _ if sp == n => last_hittable,
            _ => points[sp - 1].splittable && points[sp].splittable,
        };
        possible && strategies(sp, n - sp)
    };
    let remap = remap_delta;
    let mut sum = 1.0f32;
    let mut r = 1.0f32;
    for i in (0..s).rev() {
        let PathPoint { l, c, .. } = points[i];
        r *= remap(c) / remap(l);
        if valid(i) {
            sum += heuristic.apply(r);
        }
    }
    r = 1.0;
    for (i, &PathPoint { l, c, .. }) in points.iter().enumerate().skip(s) {
        r *= remap(l) / remap(c);
        if valid(i + 1) {
            sum += heuristic.apply(r);
        }
    }
    1.0 / sum
}

/// The densities that joining a light sub-path (ending y) and a camera sub-path (ending z)
/// changes: the other side's densities of the two ends and of their predecessors (`None`
/// where there is none), each from `junction` where it has it.
struct Rejoined {
    /// Camera-side density of y (z sampling y) and of y's predecessor (y sampling it, come
    /// from z).
    light_end: f32,
    light_before_end: Option<f32>,
    /// Light-side density of z (y sampling z) and of z's predecessor.
    camera_end: f32,
    camera_before_end: Option<f32>,
}

impl Rejoined {
    fn new(scene: &Scene, light: SubPath, camera: SubPath, junction: &Junction) -> Rejoined {
        let (s, t) = (light.len(), camera.len());
        let (y, z) = (light.get(s - 1), camera.get(t - 1));
        let y_prev = (s >= 2).then(|| light.get(s - 2));
        let z_prev = (t >= 2).then(|| camera.get(t - 2));
        let (cam, lig) = (junction.camera_end, junction.light_end);
        let camera_end = match y_prev {
            None => y.pdf_light(scene, z),
            Some(yp) => lig.map_or_else(|| y.pdf(scene, Some(yp), z), |d| d.next),
        };
        Rejoined {
            light_end: cam.map_or_else(|| z.pdf(scene, z_prev, y), |d| d.next),
            light_before_end: y_prev.map(|yp| lig.map_or_else(|| y.pdf(scene, Some(z), yp), |d| d.prev)),
            camera_end,
            camera_before_end: z_prev.map(|zp| cam.map_or_else(|| z.pdf(scene, Some(y), zp), |d| d.prev)),
        }
    }
}

/// Running sums of a stored sub-path's terms in the weights of the paths it is joined into
/// (SmallVCM's recursive quantities, per vertex): entry k is Σ_{i ≤ k} [strategy i can
/// make the path] Π_{j = i..=k} h(rev_j / fwd_j), counting vertices from the sub-path's
/// origin, fwd its own density and rev the other side's. A join at vertex m − 1 changes
/// only the densities of vertices m − 1 and m − 2, so entry m − 3 stands for all the rest
/// of that side ([`AllStrategies`]). For every strategy only: a subset's terms would depend
/// on the whole path's length.
pub fn running_sums(scene: &Scene, path: &[Vertex], heuristic: Heuristic, out: &mut Vec<f32>) {
    out.clear();
    let mut sum = 0.0f32;
    let side = SubPath::new(path, None);
    for (k, x) in path.iter().enumerate() {
        let feasible = ends_at(scene, side, k, x.connectible());
        sum = heuristic.apply(remap_delta(x.pdf_rev) / remap_delta(x.pdf_fwd)) * (sum + feasible);
        out.push(sum);
    }
}

/// 1 if the strategy that takes `side`'s vertices up to `k` from the other side can make
/// the path (the origin is hittable for k = 0; otherwise vertices k − 1 and k, this one
/// `splittable`, both allow a connection), else 0: the rule of [`weight`]'s `valid`, in one
/// sub-path's own numbering.
#[inline]
fn ends_at(scene: &Scene, side: SubPath, k: usize, splittable: bool) -> f32 {
    let ok = if k == 0 { side.get(0).hittable(scene) } else { side.get(k - 1).connectible() && splittable };
    f32::from(u8::from(ok))
}

/// Exact MIS over all (s, t) strategies (`bpt`) from the [`running_sums`] of the two stored
/// sub-paths being joined: a weight costs the densities at the join, not a pass over the
/// path. Joins with no vertex on one side (s = 0, t = 0) are weighed by [`weight`].
#[derive(Clone, Copy)]
pub struct AllStrategies<'a> {
    pub heuristic: Heuristic,
    pub light_sums: &'a [f32],
    pub camera_sums: &'a [f32],
}

impl PathWeight for AllStrategies<'_> {
    fn weight_joined(&self, scene: &Scene, light: SubPath, camera: SubPath, junction: &Junction) -> f32 {
        let (s, t) = (light.len(), camera.len());
        if s == 0 || t == 0 {
            return weight(scene, light, camera, junction, self.heuristic, &all_strategies);
        }
        if s + t == 2 && !light.get(0).seen_by_other_strategies(scene) {
            return 0.0;
        }
        let r = Rejoined::new(scene, light, camera, junction);
        let light_side = self.side(scene, light, r.light_end, r.light_before_end, self.light_sums);
        let camera_side = self.side(scene, camera, r.camera_end, r.camera_before_end, self.camera_sums);
        1.0 / (1.0 + light_side + camera_side)
    }
}

impl AllStrategies<'_> {
    /// The terms of the strategies that take more vertices from the other side than this
    /// join does: `side`'s vertex m − 1 (joined, so splittable) and m − 2 with their new
    /// other-side densities, then the running sum of the rest.
    fn side(&self, scene: &Scene, side: SubPath, rev_end: f32, rev_before_end: Option<f32>, sums: &[f32]) -> f32 {
        let m = side.len();
        let h = |k: usize, rev: f32| self.heuristic.apply(remap_delta(rev) / remap_delta(side.get(k).pdf_fwd));
        let before = match rev_before_end {
            Some(rev) => {
                let rest = if m >= 3 { sums[m - 3] } else { 0.0 };
                h(m - 2, rev) * (rest + ends_at(scene, side, m - 2, side.get(m - 2).connectible()))
            }
            None => 0.0,
        };
        h(m - 1, rev_end) * (before + ends_at(scene, side, m - 1, true))
    }
}

/// A vertex of the path being weighed: its densities under light-side (`l`) and
/// camera-side (`c`) sampling, and whether a connection may end there.
#[derive(Clone, Copy, Default)]
struct PathPoint {
    l: f32,
    c: f32,
    splittable: bool,
}
