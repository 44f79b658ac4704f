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
    if n == 2 {
        let x0 = v(0);
        let area = x0.is_light() && !x0.is_infinite() && x0.hittable(scene);
        if !area {
            return if s == 0 { 1.0 } else { 0.0 };
        }
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
        let (y, z) = (v(s - 1), v(s));
        let z_prev = (t >= 2).then(|| v(s + 1));
        let (cam, lig) = (junction.camera_end, junction.light_end);
        set(s - 1, None, Some(cam.map_or_else(|| z.pdf(scene, z_prev, y), |d| d.next)));
        if s >= 2 {
            set(s - 2, None, Some(lig.map_or_else(|| y.pdf(scene, Some(z), v(s - 2)), |d| d.prev)));
        }
        let l_z = if s == 1 {
            y.pdf_light(scene, z)
        } else {
            lig.map_or_else(|| y.pdf(scene, Some(v(s - 2)), z), |d| d.next)
        };
        set(s, Some(l_z), None);
        if let Some(zp) = z_prev {
            set(s + 1, Some(cam.map_or_else(|| z.pdf(scene, Some(y), zp), |d| d.prev)), None);
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

/// A vertex of the path being weighed: its densities under light-side (`l`) and
/// camera-side (`c`) sampling, and whether a connection may end there.
#[derive(Clone, Copy, Default)]
struct PathPoint {
    l: f32,
    c: f32,
    splittable: bool,
}
