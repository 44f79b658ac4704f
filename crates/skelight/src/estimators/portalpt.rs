//! `portalpt`: path tracing guided through the opening portals of the empty space (thesis
//! §10.4.1, the shortest-paths strategy). Before rendering, the empty space is analysed and
//! labelled into opening-forest regions with the portals between them (§10.3.3–10.3.4); the
//! regions holding a light are found ([`Regions::lit`]) and a shortest-path tree over the
//! region graph leads every other region to one of them, through one portal of its own.
//!
//! **Bottlenecks.** The opening forest cuts one room into a region per local maximum of the
//! opening map, and from most of a room the route's next portal was then a face in mid-air
//! between two of its regions, not the door (issue 68's reading, confirmed in
//! `docs/studies/portalpt-named`). So regions are joined across every portal that is not a
//! bottleneck (`bottleneck`, [`Regions::joined`]): a portal stays when the widest ball through
//! it is narrower than that fraction of the widest balls on both sides — a door, a window, a
//! gap. Routes, blends and densities then read the joined regions. With `portal_shape=quad`
//! (the default) each portal on a route is drawn as rectangles fitted to its faces
//! ([`Regions::fitted_quads`]), by solid angle as named portals are, each weighted by the
//! point's blend of the regions it routes; `faces` draws a point uniformly by area on the
//! voxel faces, as below.
//!
//! At an eye vertex x, with probability c(x) a point y is drawn uniformly by area on the
//! portal to x's next region and ω = (y − x)/|y − x|; otherwise the BSDF draws. The direction
//! is weighted by the density of the whole mixture (one-sample MIS, eq. 168–169), with the
//! guide's density exact: Σ over every portal face the line x + tω crosses of
//! p_A·d²/|cos θ| ([`Regions::portal_pdf`]). Next-event estimation and MIS on emitter hits
//! are `pt`'s, against the same mixture (the walk of `paths::walk`). So it is unbiased
//! wherever the BSDF can draw every direction it reflects into, whatever the portals.
//!
//! **No seams (§10.5).** The thesis switches strategy where the region changes, and its images
//! show the border (Figs. 91, 94). Here x's strategy is the mixture of its nearby regions'
//! ([`Regions::blend_at`]: weights w_R(x) varying continuously over `blend` voxels):
//! c(x) = c·Σ_{R routed} w_R(x), and the guide's density Σ_R w_R(x)·p_R(ω | x)/Σ w_R — the
//! whole mixture, not the drawn region's part. In a lit region (and a region with no route)
//! p_R is absent: there BSDF sampling and next-event estimation alone, as the thesis says.
//!
//! **Named portals.** With `portals=FILE` the portals are the user's (a door's opening, the gap
//! of a door left ajar; [`NamedPortals`]): at x, a direction is drawn within the solid angle
//! of a portal triangle on the side x reflects into, triangles picked by their solid angle,
//! and its density is exact over every triangle its line crosses. No analysis is run.
//!
//! **Learned selection.** Where portals help and where they waste samples differs over the
//! scene (a point in the lit room, a point facing away from the door). With `learn` (the
//! default), c is learned per cell of a grid over the scene and per side a surface faces,
//! pass by pass, among [`SELECTIONS`] (0 included: portal sampling off), by the estimated
//! second moment of each candidate ([`Moments`]); fixed within a pass, so every pass is
//! unbiased. The value a point uses is interpolated between cell centres (continuous over
//! surfaces); `c_portal` is the first pass's and where a cell has seen too few paths.
//!
//! The face-irradiance strategy (§10.4.2) is not built yet (`strategy` offers `paths`).

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::sync::Arc;

use crate::guided::analysis::{prepare_guide, unguided_because, GuideSettings};
use crate::guided::learning::{Moments, SelectionCells, TileMoments};
use crate::guided::named_portals::{NamedPortals, NamedVertex, MAX_TRIANGLES};
use crate::guided::pictures::{label_picture, value_picture};
use crate::guided::regions::{RegionBlend, Regions, MAX_BLEND};
use crate::integrator::diagnostics::DebugFile;
use crate::integrator::params::{ParamKind, ParamSpec, Params};
use crate::integrator::{Integrator, Preparation, PrepareError, SampleContext, Scratch};
use crate::material::Bsdf;
use crate::math::{vec2, Vec3};
use crate::paths::walk::{guidable, trace, DirectionGuide, GuidedStep, GuidedVertex, Unguided};
use crate::sampling::Rng;
use crate::scene::{Scene, SurfaceInteraction};

/// portalpt's parameters, as the registry offers them.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "strategy",
        kind: ParamKind::Choice(&["paths"]),
        default: "paths",
        doc: "paths: towards the lit regions along the region graph's shortest paths, through one portal per \
              region (thesis §10.4.1)",
    },
    ParamSpec {
        name: "c_portal",
        kind: ParamKind::Float { min: 0.0, max: 0.99 },
        default: "0.25",
        doc: "probability of drawing a direction through a portal rather than from the BSDF, where a region \
              has a route (with learn: in the first pass, and where too few paths were seen); 0 is pt; below 1, \
              or directions no portal reaches would never be drawn (a bias)",
    },
    ParamSpec {
        name: "portals",
        kind: ParamKind::Path,
        default: "",
        doc: "portals named by the user instead of the analysis' (a door's opening): a JSON file of quads or an \
              OBJ of triangles, in the scene's world space (guided/named_portals.rs documents the format)",
    },
    ParamSpec {
        name: "portal_sampling",
        kind: ParamKind::Choice(&["solid_angle", "area"]),
        default: "solid_angle",
        doc: "with named portals: directions uniform within each triangle's solid angle, triangles picked by solid \
              angle; area: points uniform by area on the portals (for comparison)",
    },
    ParamSpec {
        name: "learn",
        kind: ParamKind::Bool,
        default: "true",
        doc: "learn c per cell of space and surface side, pass by pass, among 0, 0.1, 0.25 and 0.5 (fixed within \
              a pass, so unbiased); false keeps c_portal everywhere",
    },
    ParamSpec {
        name: "cells",
        kind: ParamKind::Int { min: 1, max: 128 },
        default: "16",
        doc: "cells along the scene's longest side over which learn chooses c",
    },
    ParamSpec {
        name: "bottleneck",
        kind: ParamKind::Float { min: 0.0, max: 2.0 },
        default: "0.5",
        doc: "which of the analysis' portals are kept: those whose widest ball through them is narrower than this               fraction of the widest balls on both sides (doors, windows, gaps); the regions across every other               portal are joined into one (issue 68 item 2); above 1 keeps every portal (the thesis' regions)",
    },
    ParamSpec {
        name: "portal_shape",
        kind: ParamKind::Choice(&["quad", "faces"]),
        default: "quad",
        doc: "how the analysis' portals are drawn: quad, a rectangle fitted to each portal's voxel faces, drawn \
              by solid angle as named portals are; faces, a point uniform by area on its voxel faces (the thesis')",
    },
    ParamSpec {
        name: "blend",
        kind: ParamKind::Float { min: 0.0, max: 8.0 },
        default: "1.5",
        doc: "voxels over which a point's strategy mixes its neighbouring regions' (no seams at region \
              borders); 0 switches hard at the border, as the thesis did",
    },
    crate::integrator::params::SKELETON_RESOLUTION,
    crate::integrator::params::SKELETON_BOUNDS,
];

/// The candidate selection probabilities the learned mode chooses among; 0 turns portal
/// sampling off where it does harm.
pub const SELECTIONS: [f32; 4] = [0.0, 0.1, 0.25, 0.5];
/// Directions after which a cell that chose c = 0 stops being observed: on the door corner
/// 85 % of the learned cells choose 0, and observing them cost a portal offer per vertex.
const SETTLED_OBSERVATIONS: u64 = 1024;

pub struct PortalPathTracer {
    pub c_portal: f32,
    pub bottleneck: f64,
    pub fit_quads: bool,
    pub blend: f32,
    /// The analysis' resolution and box.
    pub guide: GuideSettings,
    pub portals: Option<std::path::PathBuf>,
    pub by_area: bool,
    pub learn: bool,
    pub cells: usize,
    prepared: Option<Prepared>,
}

/// Where the portals come from.
enum Source {
    /// The analysis' regions and portals, routed towards the lit regions.
    Analysis {
        regions: Box<Regions>,
        /// Per region, the portal towards its next region on the way to a lit one (`None`
        /// in a lit region and where no route exists).
        route: Vec<Option<usize>>,
        lit: Vec<bool>,
        /// With `portal_shape=quad`, the routes' portals as fitted rectangles (named portal
        /// q stands for the regions' portal `fitted.1[q]`), drawn as named portals are.
        fitted: Option<(NamedPortals, Vec<usize>)>,
    },
    /// The user's.
    Named(NamedPortals),
}

/// What sampling reads.
struct Prepared {
    source: Source,
    cells: SelectionCells,
    /// Per cell key, the c of the current pass.
    selection: Vec<f32>,
    /// Per cell key, whether c = 0 has been chosen on [`SETTLED_OBSERVATIONS`] directions:
    /// then its vertices (where the interpolated c is 0 too) are no longer offered the
    /// portals, and pay nothing for them; a settled cell stays so (it sees no new paths).
    settled: Vec<bool>,
    /// What learning has observed so far.
    moments: Moments<{ SELECTIONS.len() }>,
}

/// A tile's learning memory: its moments and one path's guided steps.
struct Learning {
    moments: TileMoments<{ SELECTIONS.len() }>,
    steps: Vec<GuidedStep>,
}

impl PortalPathTracer {
    pub fn from_params(p: &Params) -> PortalPathTracer {
        PortalPathTracer {
            c_portal: p.float("c_portal") as f32,
            bottleneck: p.float("bottleneck"),
            fit_quads: p.choice("portal_shape") == "quad",
            blend: p.float("blend") as f32,
            guide: GuideSettings::from_params(p),
            portals: p.path("portals"),
            by_area: p.choice("portal_sampling") == "area",
            learn: p.bool("learn"),
            cells: p.int("cells") as usize,
            prepared: None,
        }
    }
}

/// The shortest-path tree over the region graph towards the lit regions (Dijkstra from all
/// of them at once): edge a–b through portal P costs |centroid_a − P| + |P − centroid_b|, the
/// length of a walk between the regions' centres through the portal's. Returns, per region,
/// the portal to take next.
fn routes(regions: &Regions, graph: &[Vec<(u32, usize)>], lit: &[bool]) -> Vec<Option<usize>> {
    #[derive(PartialEq)]
    struct Entry(f32, u32);
    impl Eq for Entry {}
    impl PartialOrd for Entry {
        fn partial_cmp(&self, o: &Entry) -> Option<Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for Entry {
        fn cmp(&self, o: &Entry) -> Ordering {
            o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
        }
    }
    let n = graph.len();
    let mut dist = vec![f32::INFINITY; n];
    let mut next = vec![None; n];
    let mut heap = BinaryHeap::new();
    for (r, &l) in lit.iter().enumerate().take(n) {
        if l {
            dist[r] = 0.0;
            heap.push(Entry(0.0, r as u32));
        }
    }
    while let Some(Entry(d, r)) = heap.pop() {
        if d > dist[r as usize] {
            continue;
        }
        for &(s, portal) in &graph[r as usize] {
            let p = regions.portals[portal].centroid;
            let cost = (regions.centroids[r as usize] - p).length() + (p - regions.centroids[s as usize]).length();
            let nd = d + cost;
            if nd < dist[s as usize] {
                dist[s as usize] = nd;
                next[s as usize] = Some(portal);
                heap.push(Entry(nd, s));
            }
        }
    }
    next
}

/// The portals on the routes as rectangles fitted to their faces ([`Regions::fitted_quads`]),
/// each two triangles, and which of the regions' portals each named portal stands for;
/// `None` (faces are drawn) where they are more than [`MAX_TRIANGLES`] triangles or a fit is
/// degenerate.
fn fitted_quads(
    regions: &Regions,
    route: &[Option<usize>],
    prep: &mut Preparation,
) -> Option<(NamedPortals, Vec<usize>)> {
    let mut portal_of: Vec<usize> = route.iter().flatten().copied().collect();
    portal_of.sort_unstable();
    portal_of.dedup();
    let quads: Vec<(String, Vec<[Vec3; 3]>)> = portal_of
        .iter()
        .map(|&k| {
            (
                format!("portal {k}"),
                regions.fitted_quads(k).iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect(),
            )
        })
        .collect();
    let triangles: usize = quads.iter().map(|(_, t)| t.len()).sum();
    if triangles == 0 {
        return None;
    }
    if triangles > MAX_TRIANGLES {
        prep.notes.push(format!(
            "the {} portals on the routes fit {triangles} triangles, more than {MAX_TRIANGLES}: their voxel faces are \
             drawn (portal_shape=faces)",
            portal_of.len()
        ));
        return None;
    }
    match NamedPortals::new(quads) {
        Ok(named) => Some((named, portal_of)),
        Err(why) => {
            prep.notes.push(format!("a portal's fitted rectangle is degenerate ({why}): voxel faces are drawn"));
            None
        }
    }
}

/// The portals' offer at the vertices of a prepared render.
struct PortalGuidance<'a> {
    prepared: &'a Prepared,
    blend: f32,
    /// Whether paths are recorded for learning: then a vertex whose c is 0 still offers its
    /// (never sampled) distribution, so that its steps keep being observed.
    learning: bool,
}

/// The portals' distribution at one vertex.
enum Offer<'a> {
    /// The analysis' portals of the vertex's blended regions, with their weights (summing
    /// to 1).
    Regions {
        regions: &'a Regions,
        x: Vec3,
        parts: [(usize, f32); MAX_BLEND],
        len: usize,
    },
    Named(NamedVertex<'a>),
}

impl Offer<'_> {
    #[inline]
    fn pdf(&self, wo: Vec3) -> f32 {
        match self {
            Offer::Regions { regions, x, parts, len } => {
                parts[..*len].iter().map(|&(k, w)| w * regions.portal_pdf(k, *x, wo)).sum()
            }
            Offer::Named(v) => v.pdf(wo),
        }
    }
}

/// The portal mixture at one vertex, and the probability of drawing from it.
pub struct PortalVertex<'a> {
    offer: Offer<'a>,
    selection: f32,
    key: u32,
}

impl GuidedVertex for PortalVertex<'_> {
    #[inline]
    fn key(&self) -> u32 {
        self.key
    }
    #[inline]
    fn selection(&self) -> f32 {
        self.selection
    }
    #[inline]
    fn pdf(&self, wo: Vec3) -> f32 {
        self.offer.pdf(wo)
    }
    #[inline]
    fn sample(&self, rng: &mut Rng) -> Vec3 {
        match &self.offer {
            Offer::Regions { regions, x, parts, len } => {
                let mut pick = rng.next_f32();
                let mut chosen = parts[len - 1].0;
                for &(k, w) in &parts[..*len] {
                    if pick < w {
                        chosen = k;
                        break;
                    }
                    pick -= w;
                }
                let y = regions.sample_portal(chosen, rng.next_f32(), [rng.next_f32(), rng.next_f32()]);
                (y - *x).normalize()
            }
            Offer::Named(v) => v.sample(rng),
        }
    }
}

/// The portal mixture for a region blend: each routed region's portal with its weight, and
/// the routed regions' total weight.
fn mixture(route: &[Option<usize>], blend: &RegionBlend) -> ([(usize, f32); MAX_BLEND], usize, f32) {
    let mut parts = [(0usize, 0.0f32); MAX_BLEND];
    let mut len = 0;
    let mut routed = 0.0;
    for (r, w) in blend.iter() {
        let Some(portal) = route.get(r as usize).copied().flatten() else { continue };
        routed += w;
        if let Some(part) = parts[..len].iter_mut().find(|(k, _)| *k == portal) {
            part.1 += w;
        } else {
            parts[len] = (portal, w);
            len += 1;
        }
    }
    for part in &mut parts[..len] {
        part.1 /= routed;
    }
    (parts, len, routed)
}

/// The side a surface point reflects into: its geometric normal turned towards `wi`.
#[inline]
fn side(ng: Vec3, wi: Vec3) -> Vec3 {
    if ng.dot(wi) >= 0.0 {
        ng
    } else {
        -ng
    }
}

impl PortalGuidance<'_> {
    /// The portals' distribution at point `p` (geometric normal `ng`, seen from `wi`) and
    /// the share of it that portals may draw (the routed regions' weight; 1 for named
    /// portals); `None` where no portal is offered.
    fn offer(&self, p: Vec3, ng: Vec3, wi: Vec3) -> Option<(Offer<'_>, f32)> {
        match &self.prepared.source {
            Source::Analysis { regions, route, fitted, .. } => {
                let blend = regions.blend_at(p, ng, wi, self.blend);
                let (parts, len, routed) = mixture(route, &blend);
                if len == 0 {
                    return None;
                }
                match fitted {
                    Some((quads, portal_of)) => {
                        let weight = |q: u16| {
                            let k = portal_of[q as usize];
                            parts[..len].iter().find(|(part, _)| *part == k).map_or(0.0, |(_, w)| *w)
                        };
                        quads.at_weighted(p, side(ng, wi), weight).map(|v| (Offer::Named(v), routed))
                    }
                    None => Some((Offer::Regions { regions, x: p, parts, len }, routed)),
                }
            }
            Source::Named(portals) => portals.at(p, side(ng, wi)).map(|v| (Offer::Named(v), 1.0)),
        }
    }

    /// The learned (or fixed) c at `p` for a surface facing `side`.
    fn c_at(&self, p: Vec3, side: Vec3) -> f32 {
        self.prepared.cells.interpolate(&self.prepared.selection, p, side)
    }
}

impl<'g> DirectionGuide for PortalGuidance<'g> {
    type Vertex<'a>
        = PortalVertex<'a>
    where
        Self: 'a;
    #[inline]
    fn at<'a>(&'a self, si: &SurfaceInteraction, bsdf: &Bsdf) -> Option<PortalVertex<'a>> {
        if !guidable(si, bsdf) {
            return None;
        }
        let facing = side(si.ng, si.wi);
        let c = self.c_at(si.p, facing);
        let key = self.prepared.cells.key(si.p, facing);
        if c <= 0.0 && (!self.learning || self.prepared.settled[key as usize]) {
            return None;
        }
        let (offer, routed) = self.offer(si.p, si.ng, si.wi)?;
        Some(PortalVertex { offer, selection: c * routed, key })
    }
}

/// Directions drawn towards the named portals from each primary hit, [`VISIBILITY_DRAWS`] per
/// pixel: the share that reaches a portal unoccluded, as a grey level (black where no portal
/// is offered), and over every primary hit that offers one.
fn portal_visibility(scene: &Scene, named: &NamedPortals) -> (crate::imageio::Image, f64) {
    let (seen, offered) = (std::sync::atomic::AtomicU64::new(0), std::sync::atomic::AtomicU64::new(0));
    let picture = value_picture(scene, |si| {
        let Some(v) = named.at(si.p, side(si.ng, si.wi)) else { return 0.0 };
        let mut rng = Rng::new(0, (si.p.x.to_bits() as u64) << 32 | si.p.y.to_bits() as u64, 0);
        let clear = (0..VISIBILITY_DRAWS)
            .filter(|_| {
                let w = v.sample(&mut rng);
                let Some(d) = v.distance_to_portal(w) else { return false };
                scene.intersect(&si.spawn_ray(w)).is_none_or(|hit| hit.t >= d)
            })
            .count() as u64;
        seen.fetch_add(clear, std::sync::atomic::Ordering::Relaxed);
        offered.fetch_add(VISIBILITY_DRAWS as u64, std::sync::atomic::Ordering::Relaxed);
        clear as f32 / VISIBILITY_DRAWS as f32
    });
    let offered = offered.into_inner();
    (picture, if offered > 0 { seen.into_inner() as f64 / offered as f64 } else { 0.0 })
}

/// Portal directions per pixel in `portal_visibility.png`.
const VISIBILITY_DRAWS: usize = 16;

/// Adds one finished path's guided steps to the moments of every candidate c: `total` is
/// the path's radiance.
fn observe(guidance: &PortalGuidance<'_>, total: crate::color::Rgb, learning: &mut Learning) {
    for step in &learning.steps {
        let h = step.integrand(total) as f64;
        learning.moments.observe(step.key, h, step.pdf as f64, || {
            let (guide_pdf, routed) =
                guidance.offer(step.x, step.normal, step.wi).map_or((0.0, 0.0), |(o, r)| (o.pdf(step.wo), r));
            SELECTIONS.map(|c| {
                let c = c * routed;
                ((1.0 - c) * step.bsdf_pdf + c * guide_pdf) as f64
            })
        });
    }
}

impl PortalPathTracer {
    fn guidance<'a>(&self, prepared: &'a Prepared) -> PortalGuidance<'a> {
        PortalGuidance { prepared, blend: self.blend, learning: self.learn }
    }

    /// The analysis' regions, portals and routes.
    fn analysed(&self, scene: &Scene, prep: &mut Preparation) -> Result<Source, PrepareError> {
        let guide = prepare_guide(scene, &self.guide, prep)?;
        let clock = std::time::Instant::now();
        let mut regions = Regions::joined(Arc::clone(&guide), self.bottleneck);
        regions.prepare_blend(self.blend);
        let graph = regions.graph();
        let lit = regions.lit(scene);
        let route = routes(&regions, &graph, &lit);
        let lit_count = lit.iter().filter(|&&l| l).count();
        let routed = route.iter().filter(|r| r.is_some()).count();
        prep.stages.push(("regions, portals and routes".into(), clock.elapsed().as_secs_f64()));
        prep.notes.push(format!(
            "{} regions ({lit_count} lit, {routed} with a route), {} portals",
            regions.count,
            regions.portals.len()
        ));
        if routed == 0 {
            prep.notes.push("no region has a route to a lit one: plain path tracing".into());
        }
        let fitted = self.fit_quads.then(|| fitted_quads(&regions, &route, prep)).flatten();
        Ok(Source::Analysis { regions: Box::new(regions), route, lit, fitted })
    }
}

impl Integrator for PortalPathTracer {
    fn name(&self) -> &'static str {
        "portalpt"
    }

    fn describe(&self) -> String {
        let portals = self.portals.as_ref().map_or(String::new(), |p| {
            let sampling = if self.by_area { "area" } else { "solid_angle" };
            format!(" portals={} portal_sampling={sampling}", p.display())
        });
        format!(
            "portalpt strategy=paths c_portal={} bottleneck={} portal_shape={} blend={} {}{portals} learn={} cells={}",
            self.c_portal,
            self.bottleneck,
            if self.fit_quads { "quad" } else { "faces" },
            self.blend,
            self.guide.describe(),
            self.learn,
            self.cells
        )
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Preparation, PrepareError> {
        self.prepared = None;
        let mut prep = Preparation::default();
        if let Some(why) = unguided_because(scene, "c_portal", self.c_portal) {
            prep.notes.push(why);
            return Ok(prep);
        }
        let source = match &self.portals {
            Some(path) => {
                let mut named = NamedPortals::load(path).map_err(PrepareError)?;
                named.by_area = self.by_area;
                prep.notes.push(format!(
                    "{} named portals ({} triangles) from {}",
                    named.names.len(),
                    named.triangles.len(),
                    path.display()
                ));
                Source::Named(named)
            }
            None => match self.analysed(scene, &mut prep)? {
                // Nothing to guide: plain path tracing, at pt's cost per sample.
                Source::Analysis { route, .. } if route.iter().all(Option::is_none) => return Ok(prep),
                analysed => analysed,
            },
        };
        let cells = SelectionCells::new(scene.bounds(), self.cells);
        let keys = cells.keys();
        self.prepared = Some(Prepared {
            source,
            cells,
            selection: vec![self.c_portal; keys],
            settled: vec![false; keys],
            moments: Moments::new(if self.learn { keys } else { 0 }),
        });
        Ok(prep)
    }

    fn new_scratch(&self) -> Scratch {
        match &self.prepared {
            Some(_) if self.learn => Scratch::new(Learning { moments: TileMoments::default(), steps: Vec::new() }),
            _ => Scratch::none(),
        }
    }

    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let pos = vec2(x as f32, y as f32) + rng.next_2d();
        let ray = scene.camera.generate_ray(pos, rng.next_2d());
        let max_depth = scene.settings.max_depth;
        let l = match &self.prepared {
            Some(p) if self.learn => {
                let g = self.guidance(p);
                let learning = cx.scratch.get::<Learning>();
                learning.steps.clear();
                let l = trace(scene, max_depth, ray, rng, &g, Some(&mut learning.steps));
                observe(&g, l, learning);
                l
            }
            Some(p) => trace(scene, max_depth, ray, rng, &self.guidance(p), None),
            None => trace(scene, max_depth, ray, rng, &Unguided, None),
        };
        cx.tile.add(pos, l);
    }

    /// `portal_selection.png` (the probability of drawing through a portal at each primary
    /// hit, over 0.5, the largest candidate: white where half the directions go through a
    /// portal); with named portals and the analysis' fitted ones, `portal_visibility.png` (the
    /// share of portal directions from each primary hit that reach a portal unoccluded); with
    /// the analysis' portals, `regions.png` (each primary hit's heaviest region, as false
    /// colours; lit regions are the sampler's destinations); `routes.json` (with the
    /// analysis' portals, each portal's regions, centroid, area and fitted rectangles).
    fn debug_files(&self, scene: &Scene) -> Vec<DebugFile> {
        let Some(p) = &self.prepared else { return Vec::new() };
        let guidance = PortalGuidance { prepared: p, blend: self.blend, learning: false };
        let selection = value_picture(scene, |si| {
            let share = guidance.offer(si.p, si.ng, si.wi).map_or(0.0, |(_, r)| r);
            guidance.c_at(si.p, side(si.ng, si.wi)) * share / SELECTIONS[SELECTIONS.len() - 1]
        });
        let mut files = vec![DebugFile::Png { name: "portal_selection.png".into(), image: selection }];
        // The learned cells and how many chose each candidate c.
        let learned: Vec<usize> = (0..p.moments.counts.len()).filter(|&k| p.moments.best(k).is_some()).collect();
        let chosen: serde_json::Map<String, serde_json::Value> = SELECTIONS
            .iter()
            .map(|&c| (c.to_string(), learned.iter().filter(|&&k| p.selection[k] == c).count().into()))
            .collect();
        let mut summary = serde_json::json!({ "cells_learned": learned.len(), "cells_choosing_c": chosen });
        match &p.source {
            Source::Analysis { regions, route, lit, fitted } => {
                if let Some((quads, _)) = fitted {
                    let (picture, share) = portal_visibility(scene, quads);
                    summary["unoccluded_share"] = share.into();
                    files.insert(0, DebugFile::Png { name: "portal_visibility.png".into(), image: picture });
                }
                let picture = label_picture(scene, |si| {
                    let blend = regions.blend_at(si.p, si.ng, si.wi, self.blend);
                    blend.iter().max_by(|a, b| a.1.total_cmp(&b.1)).map(|(r, _)| r)
                });
                files.insert(0, DebugFile::Png { name: "regions.png".into(), image: picture });
                let lit: Vec<usize> = lit.iter().enumerate().filter(|(_, &l)| l).map(|(r, _)| r).collect();
                summary["regions"] = regions.count.into();
                summary["portals"] = regions.portals.len().into();
                summary["lit_regions"] = lit.into();
                summary["routed_regions"] = route.iter().filter(|r| r.is_some()).count().into();
                let on_a_route = |k: usize| route.contains(&Some(k));
                summary["portal_list"] = regions
                    .portals
                    .iter()
                    .enumerate()
                    .map(|(k, q)| {
                        serde_json::json!({
                            "regions": [q.from, q.to],
                            "centroid": [q.centroid.x, q.centroid.y, q.centroid.z],
                            "area": q.area,
                            "fitted_quads": regions
                                .fitted_quads(k)
                                .iter()
                                .map(|quad| quad.map(|c| [c.x, c.y, c.z]))
                                .collect::<Vec<_>>(),
                            "on_a_route": on_a_route(k),
                        })
                    })
                    .collect::<Vec<_>>()
                    .into();
            }
            Source::Named(named) => {
                summary["named_portals"] = named.names.clone().into();
                summary["triangles"] = named.triangles.len().into();
                let (picture, share) = portal_visibility(scene, named);
                summary["unoccluded_share"] = share.into();
                files.insert(0, DebugFile::Png { name: "portal_visibility.png".into(), image: picture });
            }
        }
        let text = serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n";
        files.push(DebugFile::Text { name: "routes.json".into(), text });
        files
    }

    fn learns_across_passes(&self) -> bool {
        self.learn
    }

    fn finish_pass(&mut self, _scene: &Scene, scratches: &mut [Scratch]) {
        let Some(p) = self.prepared.as_mut().filter(|_| self.learn) else { return };
        for s in scratches.iter_mut() {
            p.moments.add(&s.get::<Learning>().moments);
        }
        for (key, c) in p.selection.iter_mut().enumerate() {
            if let Some(best) = p.moments.best(key) {
                *c = SELECTIONS[best];
                p.settled[key] = best == 0 && p.moments.counts[key] >= SETTLED_OBSERVATIONS;
            }
        }
    }
}
