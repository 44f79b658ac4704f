//! What the resampling estimators (`skelbpt`, `icbpt`) share on top of `bpt`: the join of a
//! drawn candidate with an eye vertex (eq. 186, 191), which contributions a render records
//! (per-distribution images, thesis Fig. 106), the parameters they both take, and their
//! build report.

use super::candidates::{Candidates, Draw, Table};
use super::node_tables::{BuildStats, Origin};
use crate::color::Rgb;
use crate::film::FilmTile;
use crate::integrator::diagnostics::{DebugPart, DebugParts};
use crate::integrator::params::{ParamKind, ParamSpec, Params};
use crate::integrator::{Integrator, Iteration};
use crate::paths::bidir::{PixelPaths, PixelSampler, PixelScratch};
use crate::paths::mis::{AllStrategies, Heuristic};
use crate::paths::mutation::{factor, Strategy};
use crate::paths::strategies;
use crate::paths::vertex::{Vertex, VertexKind};
use crate::sampling::Rng;
use crate::scene::Scene;

/// N, as both estimators take it.
pub const CANDIDATES: ParamSpec = ParamSpec {
    name: "candidates",
    kind: ParamKind::Int { min: 1, max: 65_536 },
    default: "1024",
    doc: "N: light sub-paths resampled per iteration, drawn at random among the iteration's (one per pixel)",
};

/// Per-distribution images, as both estimators take it.
pub const ONLY: ParamSpec = ParamSpec {
    name: "only",
    kind: ParamKind::Choice(&["all", "V", "U", "C", "fallback", "unresampled"]),
    default: "all",
    doc: "record only the joins drawn from this distribution, or only the strategies not resampled \
          (per-distribution images; the parts add up to the full image)",
};

/// Which contributions are recorded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Only {
    All,
    Drawn(Origin),
    Unresampled,
}

impl Only {
    pub fn from_params(p: &Params) -> Only {
        match p.choice("only") {
            "all" => Only::All,
            "unresampled" => Only::Unresampled,
            name => Only::Drawn(Origin::ALL.into_iter().find(|o| o.name() == name).unwrap_or(Origin::Fallback)),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Only::All => "all",
            Only::Unresampled => "unresampled",
            Only::Drawn(o) => o.name(),
        }
    }

    /// Whether `bpt`'s own strategies are recorded.
    pub fn records_unresampled(self) -> bool {
        !matches!(self, Only::Drawn(_))
    }

    /// Whether a join drawn from `origin` is recorded.
    pub fn records(self, origin: Origin) -> bool {
        self == Only::All || self == Only::Drawn(origin)
    }
}

/// Where a resampled candidate is joined: its vertex s and camera vertex t of `camera`.
pub struct Join<'a> {
    pub s: usize,
    pub camera: &'a [Vertex],
    /// The camera sub-path's MIS running sums.
    pub camera_sums: &'a [f32],
    pub t: usize,
    pub heuristic: Heuristic,
}

/// Eq. 186's term for one drawn candidate: the join of its light vertex s with camera
/// vertex t, MIS-weighted as `bpt` weighs the path it makes, over N times the probability
/// of the draw — so that its expectation over draws is the mean of that join over the N
/// candidates (those with no vertex there counting as zero).
pub fn resampled_join(scene: &Scene, pool: &Candidates, draw: &Draw, at: &Join) -> Rgb {
    let light = pool.path(draw.candidate);
    let w =
        AllStrategies { heuristic: at.heuristic, light_sums: pool.sums(draw.candidate), camera_sums: at.camera_sums };
    let n = pool.candidates() as f32;
    strategies::connect_vertices(scene, light, at.s, at.camera, at.t, &w) * factor(Strategy::Resampled)
        / (n * draw.probability)
}

/// The report line of the iterations' table builds: `places` names where tables are
/// cached ("nodes accepted", "importance records").
pub fn build_report(stats: &BuildStats, bytes: usize, places: &str) -> Vec<String> {
    if stats.iterations == 0 {
        return Vec::new();
    }
    let per = |x: u64| x as f64 / stats.iterations as f64;
    vec![format!(
        "resampling tables: {} iterations, {:.1} {places} and {:.0} tables per iteration, {:.0} shadow rays \
         per iteration ({:.1} % saw the table's point), {:.2} ms per iteration ({:.2} s in all), at most {:.1} MB \
         per iteration",
        stats.iterations,
        per(stats.accepted_nodes),
        per(stats.tables),
        per(stats.shadow_rays),
        100.0 * stats.visible as f64 / stats.shadow_rays.max(1) as f64,
        1e3 * stats.seconds / stats.iterations as f64,
        stats.seconds,
        bytes as f64 / 1e6
    )]
}

/// The deepest light vertex a join with t ≥ 2 can use at `max_depth` (negative: unlimited):
/// tables stop there.
pub fn deepest_join(max_depth: i32) -> usize {
    if max_depth < 0 {
        usize::MAX
    } else {
        (max_depth - 1).max(0) as usize
    }
}

/// Camera vertex z_t of `paths` if a resampled light vertex can be joined to it (a surface
/// with a non-specular part).
pub fn joinable<'a>(scene: &Scene, paths: &PixelPaths<'a>, t: usize) -> Option<&'a Vertex> {
    let z = &paths.camera[t - 1];
    (z.kind == VertexKind::Surface && z.can_connect(scene)).then_some(z)
}

/// The joins of camera vertex t with one candidate of `pool` per light depth s ≥ 2 that the
/// path length allows, each drawn by `draw(s, rng)` and recorded as `only` says.
#[allow(clippy::too_many_arguments)]
pub fn joins_at(
    bpt: &PixelSampler,
    scene: &Scene,
    pool: &Candidates,
    paths: &PixelPaths,
    t: usize,
    rng: &mut Rng,
    only: Only,
    mut draw: impl FnMut(usize, &mut Rng) -> Option<Draw>,
) -> Rgb {
    let mut l = Rgb::BLACK;
    for s in 2..=pool.depths() + 1 {
        if !bpt.fits(scene, s, t) {
            break;
        }
        let Some(d) = draw(s, rng) else { continue };
        if !only.records(d.origin) {
            continue;
        }
        let join = Join { s, camera: paths.camera, camera_sums: paths.camera_sums, t, heuristic: bpt.heuristic };
        l += resampled_join(scene, pool, &d, &join);
    }
    l
}

/// One pixel sample of the bidirectional sampler whose joins s, t ≥ 2 are `joins` when the iteration has
/// resampling tables, and the pixel's own light sub-path's (plain `bpt`) otherwise.
#[allow(clippy::too_many_arguments)]
pub fn sample_pixel(
    bpt: &PixelSampler,
    scene: &Scene,
    xy: (usize, usize),
    rng: &mut Rng,
    it: &Iteration,
    buffers: &mut PixelScratch,
    tile: &mut FilmTile,
    joins: Option<impl FnMut(&PixelPaths, usize, &mut Rng) -> Rgb>,
) {
    match joins {
        Some(mut joins) => bpt.sample_pixel(scene, xy, rng, &it.light_paths, buffers, tile, &mut joins),
        None => {
            let mut own = |paths: &PixelPaths, t: usize, _: &mut Rng| bpt.own_path_joins(scene, paths, t);
            bpt.sample_pixel(scene, xy, rng, &it.light_paths, buffers, tile, &mut own)
        }
    }
}

/// Summed build statistics of one iteration's tables, from each table's (shadow rays,
/// rays that found the table's point), with `places` the points tables were built for.
pub fn table_stats(
    built: Vec<(Table, u64, u64)>,
    places: usize,
    clock: std::time::Instant,
) -> (Vec<Table>, BuildStats) {
    let mut stats = BuildStats { iterations: 1, accepted_nodes: places as u64, ..BuildStats::default() };
    let mut tables = Vec::with_capacity(built.len());
    for (table, rays, visible) in built {
        stats.tables += !table.is_empty() as u64;
        stats.shadow_rays += rays;
        stats.visible += visible;
        tables.push(table);
    }
    stats.seconds = clock.elapsed().as_secs_f64();
    (tables, stats)
}

/// The iterations' table builds summed, and the most memory one held (iterations are
/// prepared behind `&self`, hence the lock; taken once per iteration).
#[derive(Default)]
pub struct BuildLog(std::sync::Mutex<(BuildStats, usize)>);

impl BuildLog {
    fn lock(&self) -> std::sync::MutexGuard<'_, (BuildStats, usize)> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn reset(&self) {
        *self.lock() = (BuildStats::default(), 0);
    }

    pub fn add(&self, stats: &BuildStats, bytes: usize) {
        let mut log = self.lock();
        log.0.add(stats);
        log.1 = log.1.max(bytes);
    }

    pub fn get(&self) -> (BuildStats, usize) {
        *self.lock()
    }

    /// The report line, `places` naming where tables are cached.
    pub fn report(&self, places: &str) -> Vec<String> {
        let (stats, bytes) = self.get();
        build_report(&stats, bytes, places)
    }
}

/// The per-distribution parts of a resampling estimator (thesis Fig. 106): the estimator
/// `make` builds from `params` with `only` set to each distribution, and to the strategies
/// not resampled; the parts add up to the full image.
pub fn distribution_parts(
    params: &Params,
    make: fn(&Params) -> Box<dyn Integrator>,
) -> Result<Option<DebugParts>, String> {
    let mut parts = Vec::new();
    for only in ["V", "U", "C", "fallback", "unresampled"] {
        let mut p = params.clone();
        p.set("only", only).map_err(|e| e.to_string())?;
        parts.push(DebugPart { stem: only.into(), columns: only.into(), estimator: make(&p) });
    }
    Ok(Some(DebugParts { table: ("distributions.csv", "part"), parts }))
}
