//! `portalpt`: path tracing guided through the opening portals of the empty space (thesis
//! §10.4.1, the shortest-paths strategy). Before rendering, the empty space is analysed and
//! labelled into opening-forest regions with the portals between them (§10.3.3–10.3.4); the
//! regions holding a light are found ([`Regions::lit`]) and a shortest-path tree over the
//! region graph leads every other region to one of them, through one portal of its own.
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
//! The face-irradiance strategy (§10.4.2) is not built yet (`strategy` offers `paths`).

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::sync::Arc;

use crate::guided::analysis::{prepare_guide, unguided_because, GuideSettings};
use crate::guided::pictures::{label_picture, value_picture};
use crate::guided::regions::{RegionBlend, Regions, MAX_BLEND};
use crate::integrator::diagnostics::DebugFile;
use crate::integrator::params::{ParamKind, ParamSpec, Params};
use crate::integrator::{Integrator, Preparation, PrepareError, SampleContext};
use crate::material::Bsdf;
use crate::math::{vec2, Vec3};
use crate::paths::walk::{guidable, trace, DirectionGuide, GuidedVertex, Unguided};
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
        default: "0.5",
        doc: "probability of drawing a direction through a portal rather than from the BSDF, where a region \
              has a route; 0 is pt; below 1, or directions no portal reaches would never be drawn (a bias)",
    },
    ParamSpec {
        name: "blend",
        kind: ParamKind::Float { min: 0.0, max: 8.0 },
        default: "1.5",
        doc: "voxels over which a point's strategy mixes its neighbouring regions' (no seams at region \
              borders); 0 switches hard at the border, as the thesis did",
    },
    crate::integrator::params::SKELETON_RESOLUTION,
];

pub struct PortalPathTracer {
    pub c_portal: f32,
    pub blend: f32,
    pub resolution: usize,
    prepared: Option<Prepared>,
}

/// What sampling reads.
struct Prepared {
    regions: Regions,
    /// Per region, the portal towards its next region on the way to a lit one (`None` in a
    /// lit region and where no route exists).
    route: Vec<Option<usize>>,
    lit: Vec<bool>,
}

impl PortalPathTracer {
    pub fn from_params(p: &Params) -> PortalPathTracer {
        PortalPathTracer {
            c_portal: p.float("c_portal") as f32,
            blend: p.float("blend") as f32,
            resolution: p.int("resolution") as usize,
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

/// The portals' offer at the vertices of a prepared render.
struct PortalGuidance<'a> {
    prepared: &'a Prepared,
    c_portal: f32,
    blend: f32,
}

/// The portal mixture at one vertex: portals and their weights (summing to 1).
pub struct PortalVertex<'a> {
    regions: &'a Regions,
    x: Vec3,
    parts: [(usize, f32); MAX_BLEND],
    len: usize,
    selection: f32,
}

impl GuidedVertex for PortalVertex<'_> {
    #[inline]
    fn selection(&self) -> f32 {
        self.selection
    }
    #[inline]
    fn pdf(&self, wo: Vec3) -> f32 {
        self.parts[..self.len].iter().map(|&(k, w)| w * self.regions.portal_pdf(k, self.x, wo)).sum()
    }
    #[inline]
    fn sample(&self, rng: &mut Rng) -> Vec3 {
        let mut pick = rng.next_f32();
        let mut chosen = self.parts[self.len - 1].0;
        for &(k, w) in &self.parts[..self.len] {
            if pick < w {
                chosen = k;
                break;
            }
            pick -= w;
        }
        let y = self.regions.sample_portal(chosen, rng.next_f32(), [rng.next_f32(), rng.next_f32()]);
        (y - self.x).normalize()
    }
}

impl PortalGuidance<'_> {
    /// The portal mixture at point `p` for a region blend: each routed region's portal with
    /// its weight, and the routed regions' total weight.
    fn mixture(&self, blend: &RegionBlend) -> ([(usize, f32); MAX_BLEND], usize, f32) {
        let mut parts = [(0usize, 0.0f32); MAX_BLEND];
        let mut len = 0;
        let mut routed = 0.0;
        for (r, w) in blend.iter() {
            let Some(portal) = self.prepared.route.get(r as usize).copied().flatten() else { continue };
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
        let regions = &self.prepared.regions;
        let blend = regions.blend_at(si.p, si.ng, si.wi, self.blend);
        let (parts, len, routed) = self.mixture(&blend);
        if len == 0 {
            return None;
        }
        Some(PortalVertex { regions, x: si.p, parts, len, selection: self.c_portal * routed })
    }
}

impl Integrator for PortalPathTracer {
    fn name(&self) -> &'static str {
        "portalpt"
    }

    fn describe(&self) -> String {
        format!(
            "portalpt strategy=paths c_portal={} blend={} resolution={}",
            self.c_portal, self.blend, self.resolution
        )
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Preparation, PrepareError> {
        self.prepared = None;
        let mut prep = Preparation::default();
        if let Some(why) = unguided_because(scene, "c_portal", self.c_portal) {
            prep.notes.push(why);
            return Ok(prep);
        }
        let guide = prepare_guide(scene, &GuideSettings { resolution: self.resolution }, &mut prep)?;
        let clock = std::time::Instant::now();
        let graph = guide.region_graph();
        let regions = Regions::new(Arc::clone(&guide));
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
        self.prepared = Some(Prepared { regions, route, lit });
        Ok(prep)
    }

    fn sample(&self, scene: &Scene, x: usize, y: usize, rng: &mut Rng, cx: &mut SampleContext) {
        let pos = vec2(x as f32, y as f32) + rng.next_2d();
        let ray = scene.camera.generate_ray(pos, rng.next_2d());
        let max_depth = scene.settings.max_depth;
        let l = match &self.prepared {
            Some(p) => {
                let g = PortalGuidance { prepared: p, c_portal: self.c_portal, blend: self.blend };
                trace(scene, max_depth, ray, rng, &g, None)
            }
            None => trace(scene, max_depth, ray, rng, &Unguided, None),
        };
        cx.tile.add(pos, l);
    }

    /// `regions.png` (each primary hit's heaviest region, as false colours; lit regions are
    /// the sampler's destinations) and `portal_selection.png` (c(x) at each primary hit, the
    /// probability of drawing through a portal there, over c_portal: white where every
    /// neighbouring region has a route).
    fn debug_files(&self, scene: &Scene) -> Vec<DebugFile> {
        let Some(p) = &self.prepared else { return Vec::new() };
        let guidance = PortalGuidance { prepared: p, c_portal: self.c_portal, blend: self.blend };
        let regions = label_picture(scene, |si| {
            let blend = p.regions.blend_at(si.p, si.ng, si.wi, self.blend);
            blend.iter().max_by(|a, b| a.1.total_cmp(&b.1)).map(|(r, _)| r)
        });
        let selection = value_picture(scene, |si| {
            let blend = p.regions.blend_at(si.p, si.ng, si.wi, self.blend);
            guidance.mixture(&blend).2
        });
        let lit: Vec<usize> = p.lit.iter().enumerate().filter(|(_, &l)| l).map(|(r, _)| r).collect();
        let routes = serde_json::json!({
            "regions": p.regions.count,
            "portals": p.regions.portals.len(),
            "lit_regions": lit,
            "routed_regions": p.route.iter().filter(|r| r.is_some()).count(),
        });
        let text = serde_json::to_string_pretty(&routes).unwrap_or_default() + "\n";
        vec![
            DebugFile::Png { name: "regions.png".into(), image: regions },
            DebugFile::Png { name: "portal_selection.png".into(), image: selection },
            DebugFile::Text { name: "routes.json".into(), text },
        ]
    }
}
