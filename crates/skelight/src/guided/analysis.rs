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

use crate::geometry::Ray;
pub use crate::integrator::params::AnalysisBounds;
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
    /// Voxels on the longest side of the analysed box (the seeds' 128).
    pub resolution: usize,
    /// Which box is analysed.
    pub bounds: AnalysisBounds,
}

impl Default for GuideSettings {
    fn default() -> GuideSettings {
        GuideSettings { resolution: 128, bounds: AnalysisBounds::Occupied }
    }
}

impl GuideSettings {
    /// From an estimator's `resolution` and `bounds` parameters.
    pub fn from_params(p: &crate::integrator::params::Params) -> GuideSettings {
        GuideSettings { resolution: p.int("resolution") as usize, bounds: p.bounds("bounds") }
    }

    /// `resolution=N`, and `bounds=…` where it is not the default, for `describe()`.
    pub fn describe(&self) -> String {
        match self.bounds {
            AnalysisBounds::Occupied => format!("resolution={}", self.resolution),
            AnalysisBounds::Scene => format!("resolution={} bounds=scene", self.resolution),
            AnalysisBounds::Box([a, b]) => {
                format!("resolution={} bounds={};{};{};{};{};{}", self.resolution, a[0], a[1], a[2], b[0], b[1], b[2])
            }
        }
    }
}

impl AnalysisBounds {
    /// The region the analysis clips the scene to (`None`: the scene's box grown by 10 %).
    pub fn region(&self, scene: &Scene) -> Option<[[f64; 3]; 2]> {
        match self {
            AnalysisBounds::Occupied => occupied_box(scene),
            AnalysisBounds::Scene => None,
            AnalysisBounds::Box(b) => Some(*b),
        }
    }
}

/// Rays cast from each camera or light position to find the surfaces around it.
const PROBE_RAYS: usize = 4096;
/// Hits farther than this multiple of a source's 90th-percentile hit distance are dropped:
/// what the camera sees far off through a window is not the room it is in. (Not the median:
/// a camera or light right by a chair or a lamp shade has half its hits within centimetres.)
const FAR_HITS: f32 = 2.0;
/// The found box grows by this fraction of its longest side on every side, so that the air
/// outside a window is a thick region of its own (a portal joins two regions only when it is
/// narrow for both), not a sliver the window's opening would swallow.
const OCCUPIED_MARGIN: f32 = 0.25;
/// The found box replaces the scene's only where its longest side is at most this share of
/// the scene box's: where it is a small part of the scene (classroom: 25 m of 243 m).
const OCCUPIED_SHRINK: f32 = 0.5;

/// The box that the camera and the lights occupy: the surfaces that rays from them (camera,
/// point and spot lights, area lights' centroids) reach, near hits only, grown by
/// [`OCCUPIED_MARGIN`] and kept inside the scene's box. `None` (the scene's box) where that
/// box is not a small part of the scene's ([`OCCUPIED_SHRINK`]) — an enclosed building, the
/// door scenes, sibenik, Sponza — or where nothing is found.
///
/// Why: a scene whose bounds are set by a huge ground plane or sky dome (classroom: 221 m
/// around a 3 m tall room) leaves the room a few voxels tall at any resolution an analysis
/// can afford, and every opening in it unresolved.
pub fn occupied_box(scene: &Scene) -> Option<[[f64; 3]; 2]> {
    let scene_box = scene.bounds();
    let grown = (scene_box.max - scene_box.min) * 0.05;
    let (outer_min, outer_max) = (scene_box.min - grown, scene_box.max + grown);
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for anchor in sources(scene) {
        let p = vec3(anchor.position[0] as f32, anchor.position[1] as f32, anchor.position[2] as f32);
        let side = vec3(anchor.side[0] as f32, anchor.side[1] as f32, anchor.side[2] as f32);
        let eps = 1e-4 * (scene_box.max - scene_box.min).max_component().max(1e-6);
        let origin = if side.length_squared() > 0.0 { p + side.normalize() * eps } else { p };
        lo = lo.min(p);
        hi = hi.max(p);
        let hits: Vec<(Vec3, f32)> = (0..PROBE_RAYS)
            .filter_map(|i| {
                let d = fibonacci_sphere(i, PROBE_RAYS);
                scene.intersect(&Ray::new(origin, d)).map(|h| (h.p, h.t))
            })
            .collect();
        if hits.is_empty() {
            continue;
        }
        let mut t: Vec<f32> = hits.iter().map(|h| h.1).collect();
        t.sort_by(f32::total_cmp);
        let far = FAR_HITS * t[(t.len() - 1) * 9 / 10];
        for (q, _) in hits.iter().filter(|h| h.1 <= far) {
            lo = lo.min(*q);
            hi = hi.max(*q);
        }
    }
    if !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) {
        return None;
    }
    let margin = OCCUPIED_MARGIN * (hi - lo).max_component();
    let (lo, hi) = ((lo - Vec3::splat(margin)).max(outer_min), (hi + Vec3::splat(margin)).min(outer_max));
    // Unless it at least doubles the voxels' resolution, keep the thesis' box: a long nave
    // seen from one end (sibenik) is one space, not a room and its far-off surroundings.
    if (hi - lo).max_component() > OCCUPIED_SHRINK * (outer_max - outer_min).max_component() {
        return None;
    }
    Some([to_f64(lo), to_f64(hi)])
}

/// The `i`-th of `n` directions spread evenly over the sphere (a spherical Fibonacci set).
fn fibonacci_sphere(i: usize, n: usize) -> Vec3 {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let z = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = golden * i as f32;
    vec3(r * phi.cos(), r * phi.sin(), z)
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
        region: settings.bounds.region(scene),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_parse_words_and_boxes_and_refuse_the_rest() {
        assert_eq!(AnalysisBounds::parse("occupied"), Ok(AnalysisBounds::Occupied));
        assert_eq!(AnalysisBounds::parse(" scene "), Ok(AnalysisBounds::Scene));
        let b = AnalysisBounds::Box([[-1.0, 0.0, -2.5], [1.0, 3.0, 2.5]]);
        for text in ["-1;0;-2.5;1;3;2.5", "-1,0,-2.5,1,3,2.5", "-1 0 -2.5 1 3 2.5"] {
            assert_eq!(AnalysisBounds::parse(text), Ok(b), "{text}");
        }
        for bad in ["", "room", "1;2;3;4;5", "0;0;0;1;1;nan", "0;0;0;1;inf;1", "1;0;0;0;1;1", "0;0;0;1;x;1"] {
            assert!(AnalysisBounds::parse(bad).is_err(), "{bad} was accepted");
        }
    }

    /// A 6 × 3 × 8 room (a closed cube, a light and the camera inside) on a 1 km ground
    /// plane: the occupied box is the room with its margin, not the plane; without the
    /// plane the room is the whole scene and its box is kept.
    #[test]
    fn the_occupied_box_is_the_room_not_its_ground_plane() {
        let dir = std::env::temp_dir().join(format!("skelight-occupied-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let room = r#"<shape type="cube"><transform name="to_world"><scale x="3" y="1.5" z="4"/>
            <translate y="1.5"/></transform></shape>
            <emitter type="point"><point name="position" x="0" y="2" z="0"/></emitter>"#;
        let ground = r#"<shape type="rectangle"><transform name="to_world"><scale value="500"/>
            <rotate x="1" angle="-90"/><translate y="-0.01"/></transform></shape>"#;
        let load = |name: &str, body: &str| {
            let path = dir.join(name);
            std::fs::write(
                &path,
                format!(
                    r#"<scene version="3.0.0"><sensor type="perspective"><transform name="to_world">
                    <lookat origin="0, 1.5, -2" target="0, 1.5, 1" up="0, 1, 0"/></transform>
                    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
                    </sensor>{body}</scene>"#
                ),
            )
            .unwrap();
            crate::scene::load::load(&path, &[]).unwrap()
        };
        let on_ground = load("ground.xml", &format!("{room}{ground}"));
        let [lo, hi] = occupied_box(&on_ground).expect("a room on a huge plane is a small part of it");
        for (k, (l, h)) in [(-3.0, 3.0), (0.0, 3.0), (-4.0, 4.0)].into_iter().enumerate() {
            assert!(lo[k] <= l - 0.01 && hi[k] >= h - 0.01, "axis {k}: [{}, {}] misses the room", lo[k], hi[k]);
        }
        let longest = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        assert!(longest < 20.0, "{lo:?} – {hi:?} is not the room's box");
        assert_eq!(AnalysisBounds::Occupied.region(&on_ground), Some([lo, hi]));
        assert_eq!(AnalysisBounds::Scene.region(&on_ground), None);
        assert_eq!(occupied_box(&load("room.xml", room)), None);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
