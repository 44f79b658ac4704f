//! Sub-path sampling for the bidirectional estimators: camera sub-paths, light sub-paths
//! (with their passages through the thin-lens aperture) and the light-vertex buffer that
//! holds one light sub-path per pixel for a whole iteration (thesis eq. 185), which `bpt`
//! connects to and skeleton-guided estimators resample from.

use super::vertex::{shading_normal_correction, LensHit, Vertex};
use crate::color::Rgb;
use crate::geometry::{offset_origin, Ray};
use crate::material::{BsdfCtx, BsdfModel, TransportMode};
use crate::math::Vec2;
use crate::sampling::Rng;
use crate::scene::Scene;

/// Longest sub-path (in vertices) a walk may build under Mitsuba's `max_depth` (segments;
/// negative = unlimited): a path of k segments has k + 1 vertices.
pub fn max_vertices(max_depth: i32) -> usize {
    if max_depth < 0 {
        usize::MAX
    } else {
        max_depth as usize + 1
    }
}

/// Where a random walk puts its vertices. `bpt` stores whole sub-paths; `ibpt` keeps only
/// the last few vertices and folds the rest into its MIS state as the walk goes.
pub trait VertexSink {
    fn push(&mut self, v: Vertex);
    /// Vertices pushed so far.
    fn count(&self) -> usize;
    /// The vertex `i` places before the last (0 = the last).
    fn back(&self, i: usize) -> &Vertex;
    fn back_mut(&mut self, i: usize) -> &mut Vertex;
    /// Called after each vertex is pushed, before the walk samples its continuation.
    fn visit(&mut self, _scene: &Scene, _rng: &mut Rng) {}
    /// Whether this sink wants passages through the thin-lens aperture.
    fn wants_lens_hits(&self) -> bool {
        false
    }
    /// A passage through the aperture (see [`LensHit`]).
    fn lens_hit(&mut self, _scene: &Scene, _hit: LensHit) {}
}

/// A whole sub-path, and its lens passages when `hits` is given.
pub struct StoredPath<'a> {
    pub path: &'a mut Vec<Vertex>,
    pub hits: Option<&'a mut Vec<LensHit>>,
}

impl VertexSink for StoredPath<'_> {
    fn push(&mut self, v: Vertex) {
        self.path.push(v);
    }
    fn count(&self) -> usize {
        self.path.len()
    }
    fn back(&self, i: usize) -> &Vertex {
        &self.path[self.path.len() - 1 - i]
    }
    fn back_mut(&mut self, i: usize) -> &mut Vertex {
        let n = self.path.len();
        &mut self.path[n - 1 - i]
    }
    fn wants_lens_hits(&self) -> bool {
        self.hits.is_some()
    }
    fn lens_hit(&mut self, _scene: &Scene, hit: LensHit) {
        if let Some(h) = self.hits.as_deref_mut() {
            h.push(hit);
        }
    }
}

/// Extends the sub-path in `sink` (holding its first vertex) by sampling BSDFs, recording
/// both densities of every vertex, and passages through the lens if the sink wants them.
#[allow(clippy::too_many_arguments)]
pub fn random_walk(
    scene: &Scene,
    mut ray: Ray,
    mut beta: Rgb,
    mut pdf_dir: f32,
    rng: &mut Rng,
    max_vertices: usize,
    mode: TransportMode,
    sink: &mut impl VertexSink,
) {
    let pixels = (scene.settings.width * scene.settings.height) as f32;
    let rr_depth = scene.settings.rr_depth as usize;
    let lens_hits = sink.wants_lens_hits();
    while sink.count() < max_vertices {
        let hit = scene.intersect(&ray);
        let prev = *sink.back(0);
        if lens_hits {
            // Light seen directly by the lens only counts for area lights (see `mis`).
            let direct_non_area = sink.count() == 1 && (prev.is_infinite() || !prev.hittable(scene));
            let limit = Ray { tmax: hit.as_ref().map_or(f32::INFINITY, |h| h.t), ..ray };
            if !direct_non_area {
                if let Some((_, lens_point, raster)) = scene.camera.intersect_lens(&limit) {
                    let mut lens = Vertex::camera(lens_point, scene.camera.forward, Rgb::BLACK, 0.0);
                    lens.pdf_fwd = if prev.is_infinite() {
                        prev.pdf_light(scene, &lens)
                    } else {
                        prev.convert_density(pdf_dir, &lens)
                    };
                    lens.beta = beta * (scene.camera.importance(-ray.d) * pixels);
                    let light_vertices = sink.count() as u32;
                    sink.lens_hit(scene, LensHit { light_vertices, vertex: lens, raster });
                }
            }
        }
        let Some(si) = hit else {
            if mode == TransportMode::Radiance && !scene.infinite_lights.is_empty() {
                sink.push(Vertex::escaped(prev.p(), ray.d, beta, pdf_dir));
                sink.visit(scene, rng);
            }
            break;
        };
        let mut v = Vertex::surface(si, beta, 0.0);
        v.pdf_fwd = if prev.is_infinite() { prev.pdf_light(scene, &v) } else { prev.convert_density(pdf_dir, &v) };
        sink.push(v);
        sink.visit(scene, rng);
        if sink.count() >= max_vertices {
            break;
        }
        let bsdf = &scene.materials[si.material as usize].bsdf;
        let ctx = BsdfCtx { uv: si.uv, mode };
        let wi = si.frame.to_local(si.wi);
        let Some(bs) = bsdf.sample(&ctx, wi, rng.next_f32(), rng.next_2d()) else { break };
        let wo = si.frame.to_world(bs.wo);
        beta *= bs.weight;
        if mode == TransportMode::Importance {
            beta *= shading_normal_correction(&si, si.wi, wo);
        }
        let (pdf_next, pdf_back) = if bs.delta {
            sink.back_mut(0).delta = true;
            (0.0, 0.0)
        } else {
            (bs.pdf, bsdf.pdf(&ctx, bs.wo, wi))
        };
        let back = sink.back(0).convert_density(pdf_back, sink.back(1));
        sink.back_mut(1).pdf_rev = back;
        if beta.is_black() || !beta.is_finite() {
            break;
        }
        if sink.count() > rr_depth {
            let q = beta.max_component().min(0.95);
            if rng.next_f32() >= q {
                break;
            }
            beta = beta / q;
        }
        pdf_dir = pdf_next;
        ray = si.spawn_ray(wo);
    }
}

/// Samples a camera sub-path through film position `raster` (pixels): the lens vertex,
/// then surface vertices, ending in an `Escaped` vertex if the last ray left the scene
/// and the scene has infinite lights.
pub fn camera_subpath(scene: &Scene, raster: Vec2, rng: &mut Rng, max_depth: i32, path: &mut Vec<Vertex>) {
    path.clear();
    let Some((lens, ray, pdf_dir)) = camera_subpath_start(scene, raster, rng, max_depth) else { return };
    path.push(lens);
    let mut sink = StoredPath { path, hits: None };
    random_walk(scene, ray, Rgb::WHITE, pdf_dir, rng, max_vertices(max_depth), TransportMode::Radiance, &mut sink);
}

/// The lens vertex of a camera sub-path through `raster`, the ray leaving it and that
/// ray's directional density.
pub fn camera_subpath_start(scene: &Scene, raster: Vec2, rng: &mut Rng, max_depth: i32) -> Option<(Vertex, Ray, f32)> {
    if max_depth == 0 {
        return None;
    }
    let cam = &scene.camera;
    // The camera vertex is the lens point, not the ray's origin on the near plane: the
    // densities of the next vertex are per unit area from the lens (as light-side
    // connections see the camera), and the near plane only hides occluders.
    let (lens, ray) = cam.sample_ray(raster, rng.next_2d());
    let (pdf_pos, pdf_dir) = cam.pdf_we(ray.d);
    Some((Vertex::camera(lens, cam.forward, Rgb::WHITE, pdf_pos), ray, pdf_dir))
}

/// Samples a light sub-path: a light chosen by power, a point and direction on it, then
/// surface vertices. With a thin-lens camera, passages through the aperture are recorded
/// in `lens_hits` (a path of k segments ending on the lens needs k light vertices, so the
/// walk may go one vertex further than connections use).
pub fn light_subpath(
    scene: &Scene,
    rng: &mut Rng,
    max_depth: i32,
    path: &mut Vec<Vertex>,
    lens_hits: &mut Vec<LensHit>,
) {
    path.clear();
    lens_hits.clear();
    let thin_lens = scene.camera.aperture_radius > 0.0;
    let hits = thin_lens.then_some(lens_hits);
    let Some(start) = start_light_subpath(scene, rng, max_depth) else { return };
    path.push(start.vertex);
    let mut sink = StoredPath { path, hits };
    start.walk(scene, rng, max_depth, &mut sink);
}

/// The first vertex of a light sub-path and the ray leaving it.
pub struct LightStart {
    pub vertex: Vertex,
    /// The ray leaving the light.
    pub ray: Ray,
    /// Its throughput: emitted radiance × |cos| over the joint density of light, origin
    /// and direction (the power it carries, eq. 176's Le/p).
    pub beta: Rgb,
    /// The density of its direction, as [`random_walk`] takes it.
    pub pdf_dir: f32,
}

/// Chooses a light by power and samples a point and direction on it.
pub fn start_light_subpath(scene: &Scene, rng: &mut Rng, max_depth: i32) -> Option<LightStart> {
    if scene.lights.is_empty() || max_depth == 0 {
        return None;
    }
    let (center, radius) = scene.emission_sphere();
    let (li, pmf, _) = scene.light_distribution.sample_discrete(rng.next_f32());
    let light = &scene.lights[li];
    let (u1, u2) = (rng.next_2d(), rng.next_2d());
    let e = light.sample_le(u1, u2, center, radius)?;
    let origin_pdf = if e.infinite { pmf * e.pdf_dir } else { pmf * e.pdf_pos };
    // For distant lights `e.n` is the direction of travel, as `Vertex::light` expects.
    let vertex = Vertex::light(li as u32, e.infinite, e.p, e.n, Rgb::WHITE / (pmf * e.pdf_pos), origin_pdf);
    let origin = if e.delta_pos || e.infinite { e.p } else { offset_origin(e.p, e.n, e.d) };
    Some(LightStart { vertex, ray: Ray::new(origin, e.d), beta: e.beta / pmf, pdf_dir: e.pdf_dir })
}

impl LightStart {
    /// Continues the sub-path (whose first vertex the sink holds). With a thin lens, a path
    /// of k segments ending on the lens needs k light vertices, so the walk may go one
    /// vertex further than connections use.
    pub fn walk(self, scene: &Scene, rng: &mut Rng, max_depth: i32, sink: &mut impl VertexSink) {
        let thin_lens = scene.camera.aperture_radius > 0.0;
        let limit = max_vertices(max_depth).saturating_add(thin_lens as usize).saturating_sub(1);
        random_walk(scene, self.ray, self.beta, self.pdf_dir, rng, limit, TransportMode::Importance, sink);
    }
}

/// One light sub-path per pixel for one iteration (eq. 185), in blocks of
/// [`LightPaths::BLOCK`] consecutive paths, each traced and stored by one task: no block
/// waits for another and nothing is copied into one big buffer afterwards.
#[derive(Default)]
pub struct LightPaths {
    blocks: Vec<PathBlock>,
    count: usize,
}

/// Consecutive light sub-paths stored contiguously.
#[derive(Default)]
struct PathBlock {
    vertices: Vec<Vertex>,
    /// Path i owns `vertices[starts[i]..starts[i + 1]]`.
    starts: Vec<u32>,
    lens_hits: Vec<LensHit>,
    hit_starts: Vec<u32>,
}

impl PathBlock {
    fn clear(&mut self) {
        self.vertices.clear();
        self.starts.clear();
        self.lens_hits.clear();
        self.hit_starts.clear();
    }

    fn push(&mut self, path: &[Vertex], hits: &[LensHit]) {
        if self.starts.is_empty() {
            self.starts.push(0);
            self.hit_starts.push(0);
        }
        self.vertices.extend_from_slice(path);
        self.lens_hits.extend_from_slice(hits);
        self.starts.push(self.vertices.len() as u32);
        self.hit_starts.push(self.lens_hits.len() as u32);
    }
}

impl LightPaths {
    /// Paths per block: enough to amortise a task, few enough to balance two to sixteen
    /// threads on small images.
    pub const BLOCK: usize = 512;

    /// Traces `count` light sub-paths in parallel, replacing those held (their memory is
    /// reused); path i draws its random numbers from (seed, i, iteration) on a stream of its
    /// own, so the buffer is reproducible.
    pub fn trace(&mut self, scene: &Scene, count: usize, seed: u64, iteration: u64, max_depth: i32) {
        use rayon::prelude::*;
        self.blocks.resize_with(count.div_ceil(Self::BLOCK), PathBlock::default);
        self.count = count;
        self.blocks.par_iter_mut().enumerate().for_each(|(b, block)| {
            block.clear();
            let (mut path, mut hits) = (Vec::new(), Vec::new());
            for i in b * Self::BLOCK..((b + 1) * Self::BLOCK).min(count) {
                let mut rng = Rng::new(seed ^ LIGHT_STREAM, i as u64, iteration);
                light_subpath(scene, &mut rng, max_depth, &mut path, &mut hits);
                block.push(&path, &hits);
            }
        });
    }

    pub fn len(&self) -> usize {
        self.count
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn block(&self, i: usize) -> (&PathBlock, usize) {
        (&self.blocks[i / Self::BLOCK], i % Self::BLOCK)
    }
    pub fn path(&self, i: usize) -> &[Vertex] {
        let (b, j) = self.block(i);
        &b.vertices[b.starts[j] as usize..b.starts[j + 1] as usize]
    }
    pub fn lens_hits(&self, i: usize) -> &[LensHit] {
        let (b, j) = self.block(i);
        &b.lens_hits[b.hit_starts[j] as usize..b.hit_starts[j + 1] as usize]
    }
}

/// Separates light sub-path random numbers from camera ones drawn for the same pixel.
const LIGHT_STREAM: u64 = 0x6C69_6768_745F_7061;
