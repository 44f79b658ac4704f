//! Pictures of the empty-space analysis that a person can judge (thesis Fig. 41–46 and 85):
//! the scene with the skeleton drawn over it (visible parts yellow, parts behind surfaces
//! blue, junctions and ends as dots), the node mapping as false colours on the visible
//! surfaces (every two points of one colour map to the same node), and the opening-forest
//! labelling the same way. The scene is shown with headlight shading (grey, brighter where
//! a surface faces the camera): the interiors these methods are for are too noisy to read
//! in a quick render.

use rayon::prelude::*;
use skelight_shape::mapping::{surface_voxel, NodeMapping};
use skelight_shape::pipeline::Analysis;
use skelight_shape::skeleton::SkeletonGraph;

use super::analysis::to_f64;
use super::directions::Directions;
use super::SkeletonGuide;
use crate::color::{rgb, Rgb};
use crate::geometry::Ray;
use crate::imageio::Image;
use crate::math::{vec3, Vec3};
use crate::scene::{Scene, SurfaceInteraction};

/// The pictures of the analysis `a` of `scene`, seen through its camera at its current
/// resolution, with their file names.
pub fn analysis_pictures(scene: &Scene, a: &Analysis) -> Vec<(&'static str, Image)> {
    let (w, h) = (scene.settings.width, scene.settings.height);
    let hits = primary_hits(scene);
    let backdrop = false_colours(w, h, &hits, |_| None);
    let mut written = Vec::new();
    let mut save = |name: &'static str, img: Image| written.push((name, img));
    save("skeleton_view.png", with_skeleton(scene, &backdrop, &a.skeleton));
    save("skeleton_filtered_view.png", with_skeleton(scene, &backdrop, &a.filtered));
    let full_mapping = NodeMapping::new(&a.skeleton, &a.empty);
    for (name, mapping) in [("mapping.png", &full_mapping), ("mapping_filtered.png", &a.mapping)] {
        let img = false_colours(w, h, &hits, |si| mapping.node_at(to_f64(si.p), to_f64(si.ng), to_f64(si.wi)));
        save(name, img);
    }
    let labels = &a.labelling.labels;
    let img = false_colours(w, h, &hits, |si| {
        let labelled = |v: usize| labels.data[v] != 0;
        surface_voxel(&labels.spec, labelled, to_f64(si.p), to_f64(si.ng), to_f64(si.wi)).map(|v| labels.data[v])
    });
    save("labels.png", img);
    written
}

/// Pictures of what guides `skelpt` (prepared for `scene`), seen through the camera at its
/// current resolution: `importance_view.png` (seed 001 Fig. 2: the filtered
/// skeleton, every importance node as a red dot sized by its share of the importance, and
/// at every node a segment towards its most likely importance point, red at the node, blue
/// at the far end, ending in a green dot) and `node_per_pixel.png` (the node each pixel's
/// first hit maps to, as the sampler sees it), and the importance nodes for
/// `importance.json`.
pub fn guidance_pictures(
    scene: &Scene,
    guide: &SkeletonGuide,
    directions: &Directions,
    importance: &[(u32, f64)],
) -> (Vec<(&'static str, Image)>, Vec<ImportanceNode>) {
    let (w, h) = (scene.settings.width, scene.settings.height);
    let hits = primary_hits(scene);
    let backdrop = false_colours(w, h, &hits, |_| None);
    let mut img = with_skeleton(scene, &backdrop, &guide.graph);
    let cam = scene.camera.position;
    let project = |q: Vec3| scene.camera.raster_of(cam, (q - cam).normalize());
    for (k, _) in guide.graph.nodes.iter().enumerate() {
        let Some(best) = directions.at(k as u32).iter().max_by(|a, b| a.probability.total_cmp(&b.probability)) else {
            continue;
        };
        let from = guide.position(k as u32);
        // A segment a quarter of the way to the importance point, at most two node radii.
        let reach = (guide.graph.nodes[k].radius as f32 * 2.0).max(1e-3);
        let d = best.point - from;
        let to = from + d * (reach / d.length().max(1e-6)).min(1.0);
        for step in 0..=64 {
            let f = step as f32 / 64.0;
            if let Some(r) = project(from + (to - from) * f) {
                dot(&mut img, r.x, r.y, 1.0, rgb(1.0 - f, 0.1, f));
            }
        }
        if let Some(r) = project(to) {
            dot(&mut img, r.x, r.y, 1.8, rgb(0.1, 1.0, 0.1));
        }
    }
    let total: f64 = importance.iter().map(|i| i.1).sum();
    let mut listed = Vec::new();
    for &(node, value) in importance {
        let p = guide.position(node);
        if let Some(r) = project(p) {
            dot(&mut img, r.x, r.y, 2.0 + 6.0 * (value / total.max(1e-30)).sqrt() as f32, rgb(1.0, 0.05, 0.05));
        }
        listed.push(ImportanceNode { node, position: [p.x, p.y, p.z], value });
    }
    let nodes = false_colours(w, h, &hits, |si| guide.node_at(si.p, si.ng, si.wi));
    (vec![("importance_view.png", img), ("node_per_pixel.png", nodes)], listed)
}

/// One importance node as `importance.json` lists it.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ImportanceNode {
    pub node: u32,
    pub position: [f32; 3],
    pub value: f64,
}

/// `importance.json`'s contents.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ImportanceFile {
    pub importance_nodes: Vec<ImportanceNode>,
}

/// The first hit of a ray through every pixel's centre.
/// Any labelling of the primary hits (regions, nodes) as false colours, through the
/// scene's camera at its current resolution.
pub fn label_picture(scene: &Scene, label_of: impl Fn(&SurfaceInteraction) -> Option<u32> + Sync) -> Image {
    false_colours(scene.settings.width, scene.settings.height, &primary_hits(scene), label_of)
}

/// A value in [0, 1] at each primary hit as a grey level (black where nothing is hit).
pub fn value_picture(scene: &Scene, value_of: impl Fn(&SurfaceInteraction) -> f32 + Sync) -> Image {
    let pixels = primary_hits(scene)
        .par_iter()
        .map(|hit| hit.as_ref().map_or(Rgb::BLACK, |si| Rgb::WHITE * value_of(si).clamp(0.0, 1.0)))
        .collect();
    Image { width: scene.settings.width, height: scene.settings.height, pixels }
}

fn primary_hits(scene: &Scene) -> Vec<Option<SurfaceInteraction>> {
    scene.camera.pixel_centre_rays().par_iter().map(|r| scene.intersect(r)).collect()
}

/// Surface points of the primary hits coloured by the label `label_of` gives them, shaded by
/// the angle they are seen at (headlight shading); grey where a point has no label, black
/// where nothing is hit.
fn false_colours(
    w: usize,
    h: usize,
    hits: &[Option<SurfaceInteraction>],
    label_of: impl Fn(&SurfaceInteraction) -> Option<u32> + Sync,
) -> Image {
    let pixels = hits
        .par_iter()
        .map(|hit| {
            let Some(si) = hit else { return Rgb::BLACK };
            let shade = 0.35 + 0.65 * si.ng.dot(si.wi).abs();
            label_of(si).map_or(rgb(0.25, 0.25, 0.25), distinct_colour) * shade
        })
        .collect();
    Image { width: w, height: h, pixels }
}

/// A colour per label, neighbouring labels far apart in hue (golden-ratio steps) and in
/// brightness (three levels).
fn distinct_colour(label: u32) -> Rgb {
    let hue = (label as f64 * 0.618_033_988_75).fract() * 6.0;
    let value = [1.0, 0.7, 0.45][(label % 3) as usize];
    let (sector, f) = (hue.floor() as u32, hue.fract() as f32);
    let (s, v) = (0.75f32, value as f32);
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let [r, g, b] = match sector {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    };
    // The PNG writer encodes sRGB: undo it roughly (gamma 2) so the picture shows these.
    rgb(r * r, g * g, b * b)
}

/// `backdrop` with the edges of `graph` drawn over it, yellow where the camera sees them and
/// blue where a surface hides them, and its junctions and ends as red (or blue) dots.
fn with_skeleton(scene: &Scene, backdrop: &Image, graph: &SkeletonGraph) -> Image {
    let mut img = backdrop.clone();
    let cam = scene.camera.position;
    let world = |p: [f64; 3]| vec3(p[0] as f32, p[1] as f32, p[2] as f32);
    let seen = |q: Vec3| !scene.occluded(&Ray { o: cam, d: q - cam, tmax: 1.0 - 1e-4 });
    let project = |q: Vec3| scene.camera.raster_of(cam, (q - cam).normalize());
    let (visible, hidden) = (rgb(1.0, 0.8, 0.05), rgb(0.1, 0.35, 1.0));
    for &[a, b] in &graph.edges {
        let (pa, pb) = (world(graph.nodes[a as usize].position), world(graph.nodes[b as usize].position));
        // About two samples per pixel of the edge's length on the film.
        let steps = match (project(pa), project(pb)) {
            (Some(ra), Some(rb)) => ((ra.x - rb.x).hypot(ra.y - rb.y) * 2.0).clamp(2.0, 8192.0) as usize,
            _ => 512,
        };
        for k in 0..=steps {
            let q = pa + (pb - pa) * (k as f32 / steps as f32);
            if let Some(r) = project(q) {
                let in_view = seen(q);
                dot(&mut img, r.x, r.y, if in_view { 1.2 } else { 0.6 }, if in_view { visible } else { hidden });
            }
        }
    }
    let degree = graph.adjacency();
    for (n, links) in graph.nodes.iter().zip(&degree) {
        if links.len() == 2 {
            continue;
        }
        let q = world(n.position);
        if let Some(r) = project(q) {
            let c = if seen(q) { rgb(1.0, 0.15, 0.05) } else { hidden };
            dot(&mut img, r.x, r.y, 2.5, c);
        }
    }
    img
}

/// Paints a disc of `radius` pixels centred at film position (x, y).
fn dot(img: &mut Image, x: f32, y: f32, radius: f32, c: Rgb) {
    let r = radius.ceil() as i64;
    for dy in -r..=r {
        for dx in -r..=r {
            let (px, py) = (x.floor() as i64 + dx, y.floor() as i64 + dy);
            let (cx, cy) = (px as f32 + 0.5 - x, py as f32 + 0.5 - y);
            if cx * cx + cy * cy > radius * radius || px < 0 || py < 0 {
                continue;
            }
            let (px, py) = (px as usize, py as usize);
            if px < img.width && py < img.height {
                img.pixels[py * img.width + px] = c;
            }
        }
    }
}

/// `nodes_view.png`: the filtered skeleton seen through the camera, with every node skelbpt
/// built resampling tables for in its last pass as a red dot sized by the share of eye
/// vertices mapped to it (thesis §11.4), and the nodes reached but not accepted as small
/// grey dots.
pub fn node_use_picture(scene: &Scene, guide: &SkeletonGuide, accepted: &[u32], mapped: &[u64]) -> Image {
    let (w, h) = (scene.settings.width, scene.settings.height);
    let backdrop = false_colours(w, h, &primary_hits(scene), |_| None);
    let mut img = with_skeleton(scene, &backdrop, &guide.graph);
    let cam = scene.camera.position;
    let total = mapped.iter().sum::<u64>().max(1) as f32;
    for (node, &count) in mapped.iter().enumerate() {
        let Some(r) = scene.camera.raster_of(cam, (guide.position(node as u32) - cam).normalize()) else { continue };
        if accepted.contains(&(node as u32)) {
            dot(&mut img, r.x, r.y, 2.0 + 10.0 * (count as f32 / total).sqrt(), rgb(1.0, 0.05, 0.05));
        } else if count > 0 {
            dot(&mut img, r.x, r.y, 1.5, rgb(0.6, 0.6, 0.6));
        }
    }
    img
}
