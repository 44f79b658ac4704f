//! The empty-space analysis of a scene (thesis ch. 6) as rendering needs it: the scene's
//! triangles and anchors handed to `skelight-shape`, and only what sampling reads kept
//! afterwards — the filtered skeleton graph and its node mapping grid (Alg. 5), not the
//! thinning's working arrays. Analyses are cached in memory per scene geometry and
//! settings, so a second render (a comparison, a test loop) of the same scene pays nothing.

use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use skelight_shape::bottlenecks::Widths;
use skelight_shape::labeling::Labelling;
use skelight_shape::mapping::NodeMapping;
use skelight_shape::pipeline::{analyse, Analysis, AnalysisSettings, Anchor, Resolution};
use skelight_shape::portals::Portal;
use skelight_shape::skeleton::SkeletonGraph;

use crate::light::Light;
use crate::math::{vec3, Vec3};
use crate::scene::Scene;

/// Which scene elements the skeleton must reach (the thinning's constraint set).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AnchorKind {
    Lights,
    Camera,
}

/// What a guided estimator asks of the analysis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuideSettings {
    /// Voxels on the longest side of the scene's box grown by 10 % (the seeds' 128).
    pub resolution: usize,
}

/// What sampling reads of a scene's analysis.
pub struct SkeletonGuide {
    /// The filtered skeleton (Alg. 4): the nodes directions are computed between.
    pub graph: SkeletonGraph,
    /// Which node each empty voxel maps to (Alg. 5); surface points via eq. 151–155.
    pub mapping: NodeMapping,
    /// The skeleton before filtering (thesis §6.3), for the visibility gates (ch. 7).
    pub raw: SkeletonGraph,
    /// The opening-forest regions of the empty voxels (§6.2.2), for portal-guided sampling.
    pub labelling: Labelling,
    /// The portals between regions (ch. 10): each joins two regions of `labelling`.
    pub portals: Vec<Portal>,
    /// The regions' peaks and the portals' openings (for [`crate::guided::regions::Regions::joined`]).
    pub widths: Widths,
    /// Stages of the analysis and their wall times in seconds (zero when cached).
    pub timings: Vec<(String, f64)>,
    /// Memory kept for sampling, in bytes.
    pub bytes: usize,
}

impl SkeletonGuide {
    /// The node standing for surface point `p` with geometric normal `ng`, seen from the
    /// direction `towards_viewer` (eq. 151–155); `None` outside the grid or where no node
    /// reaches.
    #[inline]
    pub fn node_at(&self, p: Vec3, ng: Vec3, towards_viewer: Vec3) -> Option<u32> {
        self.mapping.node_at(to_f64(p), to_f64(ng), to_f64(towards_viewer))
    }

    /// A node's position.
    #[inline]
    pub fn position(&self, node: u32) -> Vec3 {
        let [x, y, z] = self.graph.nodes[node as usize].position;
        vec3(x as f32, y as f32, z as f32)
    }

    fn from_analysis(a: Analysis, seconds: f64) -> SkeletonGuide {
        let mut timings: Vec<(String, f64)> = a.timings.iter().map(|(s, t)| (s.to_string(), *t)).collect();
        timings.push(("empty-space analysis (total)".into(), seconds));
        let node = std::mem::size_of::<skelight_shape::skeleton::Node>();
        let bytes = a.mapping.grid.data.len() * 4
            + a.filtered.nodes.len() * node
            + a.filtered.edges.len() * 8
            + a.skeleton.nodes.len() * node
            + a.skeleton.edges.len() * 8
            + a.labelling.labels.data.len() * 4
            + a.portals.iter().map(|p| p.squares.len() * 16).sum::<usize>();
        SkeletonGuide {
            graph: a.filtered,
            mapping: a.mapping,
            raw: a.skeleton,
            labelling: a.labelling,
            portals: a.portals,
            widths: a.widths,
            timings,
            bytes,
        }
    }

    /// The region graph: for every opening-forest region (1..=count; index 0 unused), the
    /// regions it shares a portal with and that portal's index in [`SkeletonGuide::portals`].
    pub fn region_graph(&self) -> Vec<Vec<(u32, usize)>> {
        let mut graph = vec![Vec::new(); self.labelling.count as usize + 1];
        for (i, p) in self.portals.iter().enumerate() {
            for (a, b) in [(p.from, p.to), (p.to, p.from)] {
                if let Some(links) = graph.get_mut(a as usize) {
                    links.push((b, i));
                }
            }
        }
        graph
    }
}

/// The analysis settings for `scene`: its lights and camera as anchors and sources.
pub fn analysis_settings(scene: &Scene, settings: &GuideSettings) -> AnalysisSettings {
    AnalysisSettings {
        resolution: Resolution::Longest(settings.resolution),
        anchors: anchors(scene, &[AnchorKind::Lights, AnchorKind::Camera]),
        sources: sources(scene),
        ..AnalysisSettings::default()
    }
}

type Cache = Mutex<HashMap<u64, Arc<SkeletonGuide>>>;

fn cache() -> &'static Cache {
    static CACHE: std::sync::OnceLock<Cache> = std::sync::OnceLock::new();
    CACHE.get_or_init(|| Mutex::new(HashMap::new()))
}

/// How many analyses the cache keeps (the oldest goes first); each is a few megabytes.
const CACHED_ANALYSES: usize = 8;

/// The guide of `scene` at `settings`, analysed now or taken from the cache (then with
/// `cached` true and no timings of its own).
pub fn guide_for(scene: &Scene, settings: &GuideSettings) -> Result<(Arc<SkeletonGuide>, bool), String> {
    let triangles = scene_triangles(scene);
    let analysis = analysis_settings(scene, settings);
    let key = cache_key(&triangles, &analysis);
    if let Some(g) = cache().lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return Ok((g.clone(), true));
    }
    let start = Instant::now();
    let a = analyse(&triangles, &analysis).map_err(|e| format!("empty-space analysis: {e}"))?;
    let guide = Arc::new(SkeletonGuide::from_analysis(a, start.elapsed().as_secs_f64()));
    let mut c = cache().lock().unwrap_or_else(|e| e.into_inner());
    if c.len() >= CACHED_ANALYSES {
        c.clear();
    }
    c.insert(key, guide.clone());
    Ok((guide, false))
}

/// [`guide_for`] as an estimator's preparation step: the analysis's stages (or the cache
/// hit) recorded in `prep`.
pub fn prepare_guide(
    scene: &Scene,
    settings: &GuideSettings,
    prep: &mut crate::integrator::Preparation,
) -> Result<Arc<SkeletonGuide>, crate::integrator::PrepareError> {
    let clock = Instant::now();
    let (guide, cached) = guide_for(scene, settings).map_err(crate::integrator::PrepareError)?;
    if cached {
        prep.stages.push(("empty-space analysis (cached)".into(), clock.elapsed().as_secs_f64()));
    } else {
        prep.stages.extend(guide.timings.iter().cloned());
    }
    Ok(guide)
}

/// Why a guided path tracer renders as plain path tracing, without an analysis, if it does:
/// its probability `c` of drawing from the guide (the parameter `name`) is 0, or the scene
/// has no light to guide towards.
pub fn unguided_because(scene: &Scene, name: &str, c: f32) -> Option<String> {
    if c == 0.0 {
        Some(format!("{name} = 0: plain path tracing, no analysis"))
    } else if scene.lights.is_empty() {
        Some("the scene has no lights: plain path tracing".into())
    } else {
        None
    }
}

/// A hash of everything the analysis reads: the triangles and the settings.
fn cache_key(triangles: &[[[f64; 3]; 3]], settings: &AnalysisSettings) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    triangles.len().hash(&mut h);
    for t in triangles {
        for v in t {
            for c in v {
                c.to_bits().hash(&mut h);
            }
        }
    }
    format!("{settings:?}").hash(&mut h);
    h.finish()
}

/// The camera and the lights, where light paths start and end: the analysis keeps the
/// empty space that holds them.
pub fn sources(scene: &Scene) -> Vec<Anchor> {
    anchors(scene, &[AnchorKind::Lights, AnchorKind::Camera])
}

/// Anchors for the scene's lights (an area light's centroid, on the side it faces; point
/// and spot lights' positions; distant lights have no place) and its camera.
pub fn anchors(scene: &Scene, kinds: &[AnchorKind]) -> Vec<Anchor> {
    let f = to_f64;
    let mut out = Vec::new();
    if kinds.contains(&AnchorKind::Lights) {
        for light in &scene.lights {
            match light {
                Light::Area(e) => {
                    let (mut centroid, mut normal, mut area) = (Vec3::ZERO, Vec3::ZERO, 0.0);
                    for [a, b, c] in &e.triangles {
                        let n = (*b - *a).cross(*c - *a) * 0.5;
                        centroid += (*a + *b + *c) * (n.length() / 3.0);
                        normal += n;
                        area += n.length();
                    }
                    if area > 0.0 {
                        out.push(Anchor { position: f(centroid / area), side: f(normal) });
                    }
                }
                Light::Point { position, .. } | Light::Spot { position, .. } => {
                    out.push(Anchor { position: f(*position), side: [0.0; 3] })
                }
                _ => {}
            }
        }
    }
    if kinds.contains(&AnchorKind::Camera) {
        out.push(Anchor { position: f(scene.camera.position), side: [0.0; 3] });
    }
    out
}

/// A renderer vector as the shape analysis takes points.
#[inline]
pub fn to_f64(v: Vec3) -> [f64; 3] {
    [v.x as f64, v.y as f64, v.z as f64]
}

/// The scene's triangles as the analysis takes them.
pub fn scene_triangles(scene: &Scene) -> Vec<[[f64; 3]; 3]> {
    scene.surface_triangles().iter().map(|t| t.map(to_f64)).collect()
}
