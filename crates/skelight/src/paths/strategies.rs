//! The (s, t) sampling strategies of bidirectional path tracing, each returning its
//! MIS-weighted contribution. `bpt` uses them all, `lt` those with t ≤ 1; skeleton-guided
//! estimators reuse them with light vertices they resample.

use super::mis::{self, Heuristic, Junction, PathWeight, StrategySet, SubPath};
use super::mutation::{factor, Strategy};
use super::vertex::{Joined, LensHit, Vertex, VertexKind};
use super::visibility::{light_visible, visible, visible_from_near_plane, ShadowEnd};
use crate::color::Rgb;
use crate::material::TransportMode;
use crate::math::{Vec2, Vec3};
use crate::sampling::Rng;
use crate::scene::Scene;

/// Exact MIS over a set of strategies, from whole stored sub-paths (`bpt`, `lt`).
#[derive(Clone, Copy)]
pub struct Weighting<'a> {
    pub heuristic: Heuristic,
    pub strategies: StrategySet<'a>,
}

/// Light tracing's strategies: those that end on the camera (t ≤ 1).
pub fn camera_end_strategies(_s: usize, t: usize) -> bool {
    t <= 1
}

impl PathWeight for Weighting<'_> {
    fn weight_joined(&self, scene: &Scene, light: SubPath, camera: SubPath, junction: &Junction) -> f32 {
        mis::weight(scene, light, camera, junction, self.heuristic, self.strategies)
    }
}

/// s = 0: the camera sub-path's last vertex `camera[t − 1]` is on an emitter, or the path
/// escaped to the infinite lights.
pub fn camera_hits_light(scene: &Scene, camera: &[Vertex], t: usize, w: &impl PathWeight) -> Rgb {
    let z = &camera[t - 1];
    let prefix = SubPath::new(&camera[..t - 1], None);
    match z.kind {
        VertexKind::Surface => {
            let le = scene.emitted(&z.si);
            if le.is_black() {
                return Rgb::BLACK;
            }
            let li = scene.mesh_light[z.si.mesh as usize].expect("emissive mesh has a light");
            let lv = z.as_light(li);
            z.beta * le * w.weight(scene, SubPath::EMPTY, SubPath { last: Some(&lv), ..prefix }) * factor(Strategy::Hit)
        }
        VertexKind::Escaped => {
            let mut sum = Rgb::BLACK;
            for &li in &scene.infinite_lights {
                let le = scene.lights[li as usize].eval_infinite(-z.n());
                if le.is_black() {
                    continue;
                }
                let lv = z.as_infinite_light(li);
                sum += z.beta * le * w.weight(scene, SubPath::EMPTY, SubPath { last: Some(&lv), ..prefix });
            }
            sum * factor(Strategy::Hit)
        }
        _ => Rgb::BLACK,
    }
}

/// s = 1: next-event estimation from `camera[t − 1]` to a light point sampled there.
pub fn connect_to_light(scene: &Scene, camera: &[Vertex], t: usize, rng: &mut Rng, w: &impl PathWeight) -> Rgb {
    let z = &camera[t - 1];
    if z.kind != VertexKind::Surface || !z.can_connect(scene) || scene.lights.is_empty() {
        return Rgb::BLACK;
    }
    let (li, pmf, _) = scene.light_distribution.sample_discrete(rng.next_f32());
    let light = &scene.lights[li];
    let Some(ls) = light.sample_li(z.p(), rng.next_2d()) else { return Rgb::BLACK };
    if ls.radiance.is_black() || !(ls.pdf > 0.0) {
        return Rgb::BLACK;
    }
    let infinite = light.is_infinite();
    let n = if infinite {
        -ls.wi
    } else if light.is_delta() {
        Vec3::ZERO
    } else if ls.n.dot(ls.wi) > 0.0 {
        -ls.n
    } else {
        ls.n
    };
    let mut lv = Vertex::light(li as u32, infinite, ls.p, n, Rgb::WHITE, 0.0);
    lv.pdf_fwd = lv.pdf_light_origin(scene);
    let jz = z.join(scene, &camera[t - 2], &lv, TransportMode::Radiance);
    if jz.f.is_black() {
        return Rgb::BLACK;
    }
    if !light_visible(scene, &z.si, ShadowEnd::of_light(ls.p, ls.wi, infinite)) {
        return Rgb::BLACK;
    }
    let camera_end = z.end_densities(scene, &jz, &camera[t - 2], &lv);
    let junction = Junction { light_end: None, camera_end: Some(camera_end) };
    let weight = w.weight_joined(scene, SubPath::new(&[], Some(&lv)), SubPath::new(&camera[..t], None), &junction);
    z.beta * jz.f * ls.radiance * (weight / (pmf * ls.pdf) * factor(Strategy::Nee))
}

/// t = 1: connects light vertex `light[s − 1]` to a sampled lens point. Returns the film
/// position and the contribution to splat.
pub fn connect_to_camera(
    scene: &Scene,
    light: &[Vertex],
    s: usize,
    rng: &mut Rng,
    w: &impl PathWeight,
) -> Option<(Vec2, Rgb)> {
    let y = &light[s - 1];
    if !y.can_connect(scene) || y.is_infinite() || (s == 1 && !y.hittable(scene)) {
        return None;
    }
    let cam = &scene.camera;
    let cs = cam.sample_wi(y.p(), rng.next_2d())?;
    if !(cs.pdf > 0.0) {
        return None;
    }
    let lens = Vertex::camera(cs.lens_point, cam.forward, Rgb::WHITE, cam.pdf_we(cam.forward).0);
    let (throughput, joined) = if s == 1 {
        (y.beta * y.emission(scene, cs.wi) * y.n().dot(cs.wi).abs(), None)
    } else {
        let jy = y.join(scene, &light[s - 2], &lens, TransportMode::Importance);
        (y.beta * jy.f, Some(jy))
    };
    // Occluders between the lens and the near plane are clipped away.
    if throughput.is_black() || !visible_from_near_plane(scene, cs.near_point, y) {
        return None;
    }
    let junction = match joined {
        Some(jy) => Junction { light_end: Some(y.end_densities(scene, &jy, &light[s - 2], &lens)), camera_end: None },
        None => Junction::NONE,
    };
    let pixels = (scene.settings.width * scene.settings.height) as f32;
    let weight = w.weight_joined(scene, SubPath::new(&light[..s], None), SubPath::new(&[], Some(&lens)), &junction);
    Some((cs.raster, throughput * (cs.importance * pixels / cs.pdf * weight * factor(Strategy::LightTrace))))
}

/// t = 0: a light sub-path that passed through the aperture.
pub fn light_hits_lens(scene: &Scene, light: &[Vertex], hit: &LensHit, w: &impl PathWeight) -> Rgb {
    let stored = &light[..hit.light_vertices as usize];
    hit.vertex.beta
        * (w.weight(scene, SubPath::new(stored, Some(&hit.vertex)), SubPath::EMPTY) * factor(Strategy::LightTrace))
}

/// The edge joining two surface vertices, light-side `y` (reached from `y_prev`) and
/// camera-side `z` (reached from `z_prev`): each end's BSDF·|cos| towards the other and the
/// squared distance (the unweighted, unoccluded throughput it adds is
/// `light_end.f · camera_end.f / d2`), and each end's view of it for MIS. `None` where
/// either end cannot be joined.
pub struct Edge {
    pub light_end: Joined,
    pub camera_end: Joined,
    pub d2: f32,
}

pub fn edge(scene: &Scene, y: &Vertex, y_prev: &Vertex, z: &Vertex, z_prev: &Vertex) -> Option<Edge> {
    if !y.can_connect(scene) || !z.can_connect(scene) || z.kind != VertexKind::Surface {
        return None;
    }
    let d = z.p() - y.p();
    let d2 = d.length_squared();
    if !(d2 > 0.0) || y.kind != VertexKind::Surface {
        return None;
    }
    // Both ends are surfaces: one direction, each end's view of it.
    let towards_z = d / d2.sqrt();
    let light_end = y.join_towards(scene, y_prev, towards_z, TransportMode::Importance);
    let camera_end = z.join_towards(scene, z_prev, -towards_z, TransportMode::Radiance);
    Some(Edge { light_end, camera_end, d2 })
}

/// s, t ≥ 2: joins light vertex `light[s − 1]` and camera vertex `camera[t − 1]`.
pub fn connect_vertices(
    scene: &Scene,
    light: &[Vertex],
    s: usize,
    camera: &[Vertex],
    t: usize,
    w: &impl PathWeight,
) -> Rgb {
    let (y, z) = (&light[s - 1], &camera[t - 1]);
    let Some(e) = edge(scene, y, &light[s - 2], z, &camera[t - 2]) else { return Rgb::BLACK };
    let c = y.beta * e.light_end.f * e.camera_end.f * z.beta / e.d2;
    if c.is_black() || !visible(scene, z, y) {
        return Rgb::BLACK;
    }
    let junction = Junction {
        light_end: Some(y.end_densities(scene, &e.light_end, &light[s - 2], z)),
        camera_end: Some(z.end_densities(scene, &e.camera_end, &camera[t - 2], y)),
    };
    c * (w.weight_joined(scene, SubPath::new(&light[..s], None), SubPath::new(&camera[..t], None), &junction)
        * factor(Strategy::Connection))
}
