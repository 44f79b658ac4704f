//! `skelpt`: path tracing guided by the curvilinear skeleton of the empty space (thesis
//! ch. 9, seed 001). Before rendering, the scene's empty space is analysed (ch. 6), the
//! importance of every skeleton node is estimated from light rays (eq. 171–176) and, for
//! every node, the importance point towards each importance node along the shortest
//! skeleton path (eq. 162) and its selection probability (eq. 164–165). At each eye vertex
//! whose point maps to a node (eq. 151–155), directions are drawn with probability c_skel
//! from the mixture of cos^s lobes towards those points (eq. 163, 167) and otherwise from
//! the BSDF, and weighted by the density of the whole mixture (eq. 168–170): unbiased
//! wherever the BSDF can sample every direction it reflects into. Next-event estimation
//! and MIS on emitter hits are `pt`'s, against that mixture density.
//!
//! Where skeleton sampling cannot help it is not used: at BSDFs with a delta lobe (mirrors,
//! glass, coatings) and near-specular ones, at points no node reaches, and everywhere in a
//! scene with no lit node (then the render is `pt`'s, and the preparation says so).

use std::sync::Arc;

use crate::guided::analysis::unguided_because;
use crate::guided::directions::{mixture_pdf, mixture_pdfs, sample_mixture, Directions, Target};
use crate::guided::learning::{Moments, TileMoments};
use crate::guided::pictures::{guidance_pictures, ImportanceFile};
use crate::guided::{Guidance, GuidanceSettings, SkeletonGuide};
use crate::integrator::diagnostics::DebugFile;
use crate::integrator::params::{ParamKind, ParamSpec, Params};
use crate::integrator::{Integrator, Preparation, PrepareError, SampleContext, Scratch};
use crate::material::Bsdf;
use crate::math::{vec2, Vec3};
use crate::paths::walk::{guidable, trace, DirectionGuide, GuidedStep, GuidedVertex};
use crate::sampling::Rng;
use crate::scene::{Scene, SurfaceInteraction};

/// skelpt's parameters, as the registry offers them.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "strength",
        kind: ParamKind::Float { min: 0.0, max: 10_000.0 },
        default: "8",
        doc: "skeleton strength s: exponent of the cos^s lobe around the importance direction (eq. 163)",
    },
    ParamSpec {
        name: "c_skel",
        kind: ParamKind::Float { min: 0.0, max: 0.99 },
        default: "0.5",
        doc: "probability of drawing a direction from the skeleton rather than the BSDF (eq. 168); 0 is pt; \
              below 1, or directions no lobe reaches and delta lobes would never be drawn (a bias)",
    },
    crate::integrator::params::SKELETON_RESOLUTION,
    crate::integrator::params::SKELETON_BOUNDS,
    ParamSpec {
        name: "importance_rays",
        kind: ParamKind::Int { min: 1, max: 1 << 28 },
        default: "262144",
        doc: "light rays traced once before rendering to estimate the nodes' importance (eq. 176)",
    },
    ParamSpec {
        name: "importance_bounces",
        kind: ParamKind::Int { min: 1, max: 16 },
        default: "1",
        doc: "hits of each light path credited to their nodes: 1 is eq. 176 (first hits); more follow the light \
              by BSDF sampling into rooms it reaches only after reflections",
    },
    ParamSpec {
        name: "importance_nodes",
        kind: ParamKind::Int { min: 1, max: 4096 },
        default: "64",
        doc: "at most this many importance nodes, the brightest",
    },
    ParamSpec {
        name: "adaptive",
        kind: ParamKind::Bool,
        default: "true",
        doc: "learn strength and c_skel per node from earlier passes (fixed within a pass, so unbiased)",
    },
];

/// The adaptive mode's candidate strengths and selection probabilities; every pairing is a
/// candidate. c = 0 (BSDF sampling alone) lets a node turn guidance off where it hurts.
const STRENGTHS: [f32; 4] = [1.0, 4.0, 16.0, 64.0];
const SELECTIONS: [f32; 4] = [0.0, 0.25, 0.5, 0.75];
const CANDIDATES: usize = STRENGTHS.len() * SELECTIONS.len();
/// Per node, the estimated second moment under every candidate (see [`Moments`]).
type NodeMoments = Moments<CANDIDATES>;

/// A tile's learning memory: its moments and one path's guided steps.
struct Learning {
    moments: TileMoments<CANDIDATES>,
    steps: Vec<GuidedStep>,
}

pub struct SkeletonPathTracer {
    pub strength: f32,
    pub c_skel: f32,
    pub settings: GuidanceSettings,
    pub adaptive: bool,
    /// Made by [`Integrator::prepare`].
    prepared: Option<Prepared>,
}

/// What sampling reads.
struct Prepared {
    guide: Arc<SkeletonGuide>,
    directions: Directions,
    /// The importance nodes and their values (for pictures and reports).
    importance: Vec<(u32, f64)>,
    /// Per node, the strength and c_skel of the current pass.
    node_params: Vec<(f32, f32)>,
    /// What the adaptive mode has observed so far.
    moments: NodeMoments,
}

impl SkeletonPathTracer {
    pub fn from_params(p: &Params) -> SkeletonPathTracer {
        SkeletonPathTracer {
            strength: p.float("strength") as f32,
            c_skel: p.float("c_skel") as f32,
            settings: GuidanceSettings::from_params(p),
            adaptive: p.bool("adaptive"),
            prepared: None,
        }
    }
}

/// The skeleton's offer at the vertices of a prepared render.
struct SkeletonGuidance<'a> {
    guide: &'a SkeletonGuide,
    directions: &'a Directions,
    /// Strength and c_skel per node.
    node_params: &'a [(f32, f32)],
    /// Whether paths are recorded for learning: then a node whose c_skel is 0 still offers
    /// its (never sampled) mixture, so that its steps keep being observed and it can turn
    /// guidance back on when later passes show it helps.
    learning: bool,
}

/// Eq. 167's mixture at one vertex.
pub struct SkeletonVertex<'a> {
    node: u32,
    targets: &'a [Target],
    strength: f32,
    c_skel: f32,
    x: Vec3,
    normal: Vec3,
}

impl GuidedVertex for SkeletonVertex<'_> {
    #[inline]
    fn key(&self) -> u32 {
        self.node
    }
    #[inline]
    fn selection(&self) -> f32 {
        self.c_skel
    }
    #[inline]
    fn pdf(&self, wo: Vec3) -> f32 {
        mixture_pdf(self.targets, self.strength, self.x, self.normal, wo)
    }
    #[inline]
    fn sample(&self, rng: &mut Rng) -> Vec3 {
        let pick = rng.next_f32();
        sample_mixture(self.targets, self.strength, self.x, self.normal, pick, rng.next_2d())
    }
}

impl<'g> DirectionGuide for SkeletonGuidance<'g> {
    type Vertex<'a>
        = SkeletonVertex<'a>
    where
        Self: 'a;
    #[inline]
    fn at<'a>(&'a self, si: &SurfaceInteraction, bsdf: &Bsdf) -> Option<SkeletonVertex<'a>> {
        if !guidable(si, bsdf) {
            return None;
        }
        let node = self.guide.node_at(si.p, si.ng, si.wi)?;
        let targets = self.directions.at(node);
        let (strength, c_skel) = self.node_params[node as usize];
        if targets.is_empty() || (c_skel <= 0.0 && !self.learning) {
            return None;
        }
        Some(SkeletonVertex { node, targets, strength, c_skel, x: si.p, normal: si.ng })
    }
}

impl Integrator for SkeletonPathTracer {
    fn name(&self) -> &'static str {
        "skelpt"
    }

    fn describe(&self) -> String {
        format!(
            "skelpt strength={} c_skel={} {} importance_rays={} importance_bounces={} importance_nodes={} adaptive={}",
            self.strength,
            self.c_skel,
            self.settings.guide.describe(),
            self.settings.importance_rays,
            self.settings.importance_bounces,
            self.settings.importance_nodes,
            self.adaptive
        )
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Preparation, PrepareError> {
        self.prepared = None;
        let mut prep = Preparation::default();
        if let Some(why) = unguided_because(scene, "c_skel", self.c_skel) {
            prep.notes.push(why);
            return Ok(prep);
        }
        let Some(Guidance { guide, directions, importance }) = Guidance::prepare(scene, &self.settings, &mut prep)?
        else {
            return Ok(prep);
        };
        let nodes = guide.graph.nodes.len();
        self.prepared = Some(Prepared {
            guide,
            directions,
            importance,
            node_params: vec![(self.strength, self.c_skel); nodes],
            moments: NodeMoments::new(if self.adaptive { nodes } else { 0 }),
        });
        Ok(prep)
    }

    fn new_scratch(&self) -> Scratch {
        match &self.prepared {
            Some(p) if self.adaptive => Scratch::new(Learning { moments: TileMoments::default(), steps: Vec::new() }),
            _ => Scratch::none(),
        }
    }

    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let pos = vec2(x as f32, y as f32) + rng.next_2d();
        let ray = scene.camera.generate_ray(pos, rng.next_2d());
        let max_depth = scene.settings.max_depth;
        let l = match &self.prepared {
            Some(p) => {
                let g = SkeletonGuidance {
                    guide: &p.guide,
                    directions: &p.directions,
                    node_params: &p.node_params,
                    learning: self.adaptive,
                };
                if self.adaptive {
                    let learning = cx.scratch.get::<Learning>();
                    learning.steps.clear();
                    let l = trace(scene, max_depth, ray, rng, &g, Some(&mut learning.steps));
                    observe(&p.directions, l, learning);
                    l
                } else {
                    trace(scene, max_depth, ray, rng, &g, None)
                }
            }
            None => trace(scene, max_depth, ray, rng, &crate::paths::walk::Unguided, None),
        };
        cx.tile.add(pos, l);
    }

    /// The guidance pictures (`importance_view.png`, `node_per_pixel.png`) and
    /// `importance.json`.
    fn debug_files(&self, scene: &Scene) -> Vec<DebugFile> {
        let Some(p) = &self.prepared else { return Vec::new() };
        let (pictures, nodes) = guidance_pictures(scene, &p.guide, &p.directions, &p.importance);
        let mut files: Vec<DebugFile> =
            pictures.into_iter().map(|(name, image)| DebugFile::Png { name: name.into(), image }).collect();
        let text = serde_json::to_string_pretty(&ImportanceFile { importance_nodes: nodes }).unwrap_or_default() + "\n";
        files.push(DebugFile::Text { name: "importance.json".into(), text });
        files
    }

    fn learns_across_passes(&self) -> bool {
        self.adaptive
    }

    fn finish_pass(&mut self, _scene: &Scene, scratches: &mut [Scratch]) {
        let Some(p) = self.prepared.as_mut().filter(|_| self.adaptive) else { return };
        for s in scratches.iter_mut() {
            p.moments.add(&s.get::<Learning>().moments);
        }
        for (node, params) in p.node_params.iter_mut().enumerate() {
            if let Some(best) = p.moments.best(node) {
                *params = (STRENGTHS[best / SELECTIONS.len()], SELECTIONS[best % SELECTIONS.len()]);
            }
        }
    }
}

/// Adds one finished path's guided steps to the moments of every candidate (see
/// [`Moments`]): `total` is the path's radiance.
fn observe(directions: &Directions, total: crate::color::Rgb, learning: &mut Learning) {
    for step in &learning.steps {
        let h = step.integrand(total) as f64;
        learning.moments.observe(step.key, h, step.pdf as f64, || {
            let skels = mixture_pdfs(directions.at(step.key), &STRENGTHS, step.x, step.normal, step.wo);
            std::array::from_fn(|i| {
                let c = SELECTIONS[i % SELECTIONS.len()];
                ((1.0 - c) * step.bsdf_pdf + c * skels[i / SELECTIONS.len()]) as f64
            })
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::FilmTile;
    use crate::integrator::Iteration;

    /// A node whose learned c_skel is 0 keeps being observed (its steps recorded), so that a
    /// later pass can turn guidance back on there: a node is never frozen by one choice.
    #[test]
    fn nodes_without_guidance_are_still_observed() {
        let mut scene = crate::scene::builtin::two_rooms();
        scene.set_resolution(16, 16);
        let params = Params::new("skelpt", PARAMS, &[]).unwrap();
        let mut skelpt = SkeletonPathTracer::from_params(&params);
        skelpt.prepare(&scene).expect("prepares");
        for p in &mut skelpt.prepared.as_mut().expect("guided").node_params {
            p.1 = 0.0;
        }
        let mut scratch = skelpt.new_scratch();
        let mut tile = FilmTile::new(0, 0, 16, 16, scene.settings.filter);
        let iteration = Iteration::default();
        for y in 0..16 {
            for x in 0..16 {
                for s in 0..16 {
                    let mut rng = Rng::new(1, (y * 16 + x) as u64, s);
                    let mut cx = SampleContext { tile: &mut tile, iteration: &iteration, scratch: &mut scratch };
                    skelpt.sample(&scene, x, y, &mut rng, &mut cx);
                }
            }
        }
        skelpt.finish_pass(&scene, std::slice::from_mut(&mut scratch));
        let p = skelpt.prepared.as_ref().expect("guided");
        let observed: u64 = p.moments.counts.iter().sum();
        let on = p.node_params.iter().filter(|&&(_, c)| c > 0.0).count();
        println!("{observed} steps observed; guidance back on at {on} of {} nodes", p.node_params.len());
        assert!(observed >= 1000, "only {observed} steps observed at nodes without guidance");
        assert!(on > 0, "no node turned guidance back on");
    }

    /// Smooth plastic and coatings (a delta lobe beside a smooth one) are left to BSDF
    /// sampling: guiding would draw their specular lobe with probability 1 − c only. A
    /// diffuse surface at the same point is guided.
    #[test]
    fn bsdfs_with_a_delta_lobe_are_not_guided() {
        use crate::color::Rgb;
        use crate::material::{Coating, Diffuse, Plastic};
        use crate::texture::Texture;
        let mut scene = crate::scene::builtin::two_rooms();
        scene.set_resolution(16, 16);
        let params = Params::new("skelpt", PARAMS, &[("adaptive".into(), "false".into())]).unwrap();
        let mut skelpt = SkeletonPathTracer::from_params(&params);
        skelpt.prepare(&scene).expect("prepares");
        let p = skelpt.prepared.as_ref().expect("guided");
        let g = SkeletonGuidance {
            guide: &p.guide,
            directions: &p.directions,
            node_params: &p.node_params,
            learning: false,
        };
        let diffuse = || Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(0.5) });
        let plastic = Bsdf::Plastic(Plastic::new(Texture::constant(0.5), Texture::constant(1.0), 1.5, false));
        let coating = Bsdf::Coating(Coating::new(1.5, Rgb::WHITE, Rgb::BLACK, diffuse()));
        let mut guided = 0;
        for (px, py) in [(8, 8), (4, 12), (12, 4), (8, 14)] {
            let ray = scene.camera.generate_ray(vec2(px as f32 + 0.5, py as f32 + 0.5), vec2(0.5, 0.5));
            let Some(si) = scene.intersect(&ray) else { continue };
            if g.at(&si, &diffuse()).is_none() {
                continue;
            }
            guided += 1;
            assert!(g.at(&si, &plastic).is_none(), "smooth plastic guided at pixel ({px}, {py})");
            assert!(g.at(&si, &coating).is_none(), "a coating guided at pixel ({px}, {py})");
        }
        assert!(guided >= 2, "too few guided diffuse vertices: {guided}");
    }
}
