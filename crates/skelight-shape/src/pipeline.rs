//! The whole empty-space analysis of a triangle scene, stage by stage with timings:
//! voxelisation, distance and opening maps, thinning into the curvilinear skeleton, its
//! graph, the filtered graph, the node mapping grid, the opening-forest labels and portals.

use std::time::Instant;

use crate::bottlenecks::{widths, Widths};
use crate::complex::Complex;
use crate::distance::{chessboard, EuclideanRows};
use crate::grid::{Grid, GridError, GridSpec};
use crate::labeling::{opening_forest_labelling, Labelling};
use crate::mapping::NodeMapping;
use crate::opening::opening;
use crate::portals::{portals, Portal};
use crate::reach::{enclosed_share, keep_reachable, place, reached_from_border, Kept, Reach};
use crate::skeleton::SkeletonGraph;
use crate::thinning::{thin_constrained, DatedThinning, EdgeConstraint, TooManyLayers};
use crate::voxelize::{empty_space, voxelize};

/// Bytes the analysis holds per voxel at its peak: the doubled grid of the complex (8 cells
/// per voxel: the complex, the dated collapse's state bytes, which hold the dates, the
/// constraint flags, and a copy of the complex or the replay's state bytes), plus the maps
/// and the collapse's work lists; the maps are made during the thinning. (Measured below
/// it, whole process, one run: classroom 430 935 MB, 55 a voxel; ajar 364 671 MB, 89; door
/// 163 MB, 87, of which the scene's meshes and the binary are a larger share.)
pub const BYTES_PER_VOXEL: u64 = 8 * (1 + 1 + 1 + 1) + 64;

#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    #[error("the scene has no usable triangles to voxelise")]
    NoTriangles,
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error("no empty voxel at this resolution: the scene fills its whole grid")]
    NoEmptySpace,
    #[error("the scene encloses no empty space at this resolution (every empty voxel reaches the grid's border), so nothing is left with enclosed-only")]
    NothingEnclosed,
    #[error(transparent)]
    Thinning(#[from] TooManyLayers),
}

pub struct Analysis {
    pub spec: GridSpec,
    pub empty: Grid<bool>,
    pub complex: Complex,
    pub skeleton: SkeletonGraph,
    pub filtered: SkeletonGraph,
    /// Nodes of the filtered skeleton for every empty voxel and surface point (§6.4).
    pub mapping: NodeMapping,
    pub labelling: Labelling,
    pub portals: Vec<Portal>,
    /// The regions' peaks and the portals' openings, for joining regions across wide portals.
    pub widths: Widths,
    /// The empty voxel standing for each anchor, `None` where none lies within
    /// [`ANCHOR_REACH`] voxels on its side.
    pub anchor_voxels: Vec<Option<usize>>,
    /// The empty voxel standing for each source, as for the anchors.
    pub source_voxels: Vec<Option<usize>>,
    /// What was kept of the empty space, and how much was dropped.
    pub reach: Reach,
    /// Fraction of the empty voxels analysed (those kept, see `reach`; with `enclosed_only`,
    /// all of them before the outside is cut away) that no 6-path joins to the grid's
    /// border: 0 for a scene that encloses no space (an open plane, a model seen from
    /// outside) or whose camera sees out of its box.
    pub enclosed: f64,
    /// Seconds each phase took, in order: together, the whole analysis.
    pub timings: Vec<(&'static str, f64)>,
    /// Seconds each step took on its thread; the steps of a phase run side by side.
    pub steps: Vec<(&'static str, f64)>,
}

/// A point the skeleton must reach (seed 001 §3.2: lights, the camera). `side` picks the
/// half-space to look in for the empty voxel standing for it, such as the side a light quad
/// emits to; zero for either side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anchor {
    pub position: [f64; 3],
    pub side: [f64; 3],
}

/// How far, in voxels, an anchor may lie from the empty voxel that stands for it.
pub const ANCHOR_REACH: i64 = 4;

/// The grid's size: voxels on the longest side (the seeds' way), or exact dimensions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Resolution {
    Longest(usize),
    Dims([usize; 3]),
}

/// What to analyse and how finely.
#[derive(Clone, Debug)]
pub struct AnalysisSettings {
    pub resolution: Resolution,
    pub constraint: EdgeConstraint,
    /// The box to analyse, `[min, max]`; `None` for the scene's bounds grown by 10 % (the
    /// seeds' set-up). A scene inside a huge ground plane or sky needs its building's box.
    pub region: Option<[[f64; 3]; 2]>,
    /// Drop the empty voxels joined to the grid's border before thinning: for a closed
    /// building, the shell of air around it in the grid's margin, which has a skeleton of
    /// its own that no light path inside ever uses.
    pub enclosed_only: bool,
    /// Points the skeleton must reach.
    pub anchors: Vec<Anchor>,
    /// Where light paths start and end: the camera and the lights. Only the empty-space
    /// components holding them are analysed (see [`crate::reach`]): the insides of closed
    /// solids, which no path enters, get no skeleton. With none, the largest enclosed
    /// component is kept.
    pub sources: Vec<Anchor>,
    /// Analyse every empty component, the insides of closed solids too.
    pub keep_all_space: bool,
}

impl Default for AnalysisSettings {
    fn default() -> Self {
        AnalysisSettings {
            resolution: Resolution::Longest(128),
            constraint: EdgeConstraint::Thesis,
            region: None,
            enclosed_only: false,
            anchors: Vec::new(),
            sources: Vec::new(),
            keep_all_space: false,
        }
    }
}

/// Runs every stage on `triangles` (those outside the region are clipped away).
pub fn analyse(triangles: &[[[f64; 3]; 3]], settings: &AnalysisSettings) -> Result<Analysis, AnalysisError> {
    let mut timings = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |name: &'static str, timings: &mut Vec<(&'static str, f64)>| {
        timings.push((name, clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in triangles.iter().filter(|t| t.iter().flatten().all(|v| v.is_finite())).flatten() {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    if !lo[0].is_finite() {
        return Err(AnalysisError::NoTriangles);
    }
    let ([min, max], margin) = match settings.region {
        Some(region) => (region, 0.0),
        None => ([lo, hi], 0.05),
    };
    let spec = match settings.resolution {
        Resolution::Longest(n) => GridSpec::from_bounds(min, max, n, margin)?,
        Resolution::Dims(dims) => GridSpec::from_bounds_dims(min, max, dims, margin)?,
    };
    spec.check_memory(BYTES_PER_VOXEL)?;
    let mut empty = empty_space(&voxelize(&spec, triangles));
    if !empty.data.iter().any(|&e| e) {
        return Err(AnalysisError::NoEmptySpace);
    }
    // Measured here only when the outside is to be cut away; otherwise beside the maps,
    // off the path every other stage waits on (door: 1.5-2.5 ms; beside the node mapping
    // at the end, it made the longer of the last stage's two sides longer still).
    let enclosed_before = if settings.enclosed_only {
        let outside = reached_from_border(&empty);
        let enclosed = enclosed_share(&empty, &outside);
        if enclosed == 0.0 {
            return Err(AnalysisError::NothingEnclosed);
        }
        for (e, &out) in empty.data.iter_mut().zip(&outside) {
            *e &= !out;
        }
        Some(enclosed)
    } else {
        None
    };
    lap("voxelise", &mut timings);
    let source_voxels: Vec<Option<usize>> = settings.sources.iter().map(|a| place(&empty, a)).collect();
    let (empty, reach) =
        if settings.keep_all_space { (empty, Reach::all(Kept::All)) } else { keep_reachable(empty, &source_voxels) };
    lap("the space light reaches (flood from camera and lights)", &mut timings);
    let anchor_voxels: Vec<Option<usize>> = settings.anchors.iter().map(|a| place(&empty, a)).collect();
    let anchors: Vec<usize> = anchor_voxels.iter().flatten().copied().collect();
    // Two phases of two sides each. The maps need nothing from the thinning, and the
    // thinning needs only the empty space: side by side, the maps' parallel passes fill
    // the threads the thinning's serial steps leave idle. The Euclidean map is wanted only
    // at the skeleton's nodes, so only its pass along x is made, beside the dated collapse.
    // The chessboard map, the opening and its labels and portals, wanted only at the end,
    // go beside W, the constrained thinning (its replay and piercing rounds mostly
    // serial), the graph and the node mapping (a sequential flood, as the labelling is).
    // Door, best of 10, means over eight alternating rounds: all maps beside the whole
    // thinning, labels beside the mapping 0.1244 s; the opening beside the constrained
    // thinning 0.1221; W too 0.1200; the chessboard map too 0.1182-0.1193; the graph and
    // the mapping beside the labels 0.1182 -> 0.1168 (peak memory 199-218 MB throughout).
    let (((edt, enclosed), rows_time), (dated, dated_time)) = rayon::join(
        || {
            timed(|| {
                let enclosed = || enclosed_share(&empty, &reached_from_border(&empty));
                (EuclideanRows::new(&empty, true), enclosed_before.unwrap_or_else(enclosed))
            })
        },
        || timed(|| DatedThinning::of(&empty)),
    );
    let dated = dated?;
    lap("dated thinning (Alg. 2) beside the Euclidean rows", &mut timings);
    let ((complex, skeleton, filtered, mapping, skeleton_steps), (labelling, portals, widths, opening_steps)) =
        rayon::join(
            || {
                let (keep, w_time) = timed(|| dated.constraint_set(&empty, settings.constraint, &anchors));
                let ((complex, faces), thin_time) = timed(|| thin_constrained(dated.complex, dated.dates, &keep));
                let ((skeleton, filtered), graph_time) = timed(|| {
                    let skeleton = SkeletonGraph::from_faces(&complex, &faces, &spec, &empty, |v| edt.at(v));
                    let filtered = skeleton.filtered();
                    (skeleton, filtered)
                });
                let (mapping, mapping_time) = timed(|| NodeMapping::new(&filtered, &empty));
                let steps = [
                    ("constraint set W (Alg. 3)", w_time),
                    ("constrained thinning, piercing (Alg. 3)", thin_time),
                    ("skeleton graph and filtering (Alg. 4)", graph_time),
                    ("node mapping (Alg. 5)", mapping_time),
                ];
                (complex, skeleton, filtered, mapping, steps)
            },
            || {
                let (open, opening_time) = timed(|| opening(&chessboard(&empty, true)));
                let (labelling, labels_time) = timed(|| opening_forest_labelling(&open));
                let ((portals, widths), portals_time) = timed(|| {
                    let portals = portals(&labelling);
                    let widths = widths(&labelling, &open, &portals);
                    (portals, widths)
                });
                let steps = [
                    ("chessboard and opening maps", opening_time),
                    ("opening labels", labels_time),
                    ("opening portals and their widths", portals_time),
                ];
                (labelling, portals, widths, steps)
            },
        );
    lap("skeleton, graph, mapping beside the opening, labels, portals", &mut timings);
    let mut steps = vec![("dated thinning (Alg. 2)", dated_time), ("Euclidean rows, enclosed share", rows_time)];
    steps.extend(skeleton_steps);
    steps.extend(opening_steps);
    Ok(Analysis {
        spec,
        empty,
        complex,
        skeleton,
        filtered,
        mapping,
        labelling,
        portals,
        widths,
        anchor_voxels,
        source_voxels,
        reach,
        enclosed,
        timings,
        steps,
    })
}

/// `f()`, and the seconds it took.
fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let value = f();
    (value, start.elapsed().as_secs_f64())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::closed_box;

    fn at(resolution: usize) -> AnalysisSettings {
        AnalysisSettings { resolution: Resolution::Longest(resolution), ..Default::default() }
    }

    #[test]
    fn a_closed_room_gives_one_connected_skeleton() {
        let a = analyse(&closed_box([0.0; 3], [1.0; 3]), &at(24)).unwrap();
        assert_eq!(a.skeleton.components(), a.filtered.components());
        assert!(!a.filtered.nodes.is_empty());
        assert_eq!(a.timings.len(), 4);
        assert_eq!(a.steps.len(), 9);
        // Every empty voxel inside the walls maps to a node.
        let inside = (0..a.spec.len()).filter(|&i| a.empty.data[i]).all(|i| a.mapping.node_of_voxel(i).is_some());
        assert!(inside);
    }

    /// A huge ground plane far from the room does not dilute the grid when a region is given,
    /// and a scene that encloses nothing says so.
    #[test]
    fn a_region_clips_the_scene_and_open_scenes_enclose_nothing() {
        let room = closed_box([0.0; 3], [1.0; 3]);
        let alone = analyse(&room, &AnalysisSettings { keep_all_space: true, ..at(24) }).unwrap();
        assert!(alone.enclosed > 0.3, "{}", alone.enclosed);
        let mut with_ground = room.clone();
        with_ground.push([[-100.0, -1.0, -100.0], [100.0, -1.0, -100.0], [0.0, -1.0, 100.0]]);
        let region = Some([[-0.05, -0.05, -0.05], [1.05, 1.05, 1.05]]);
        let clipped = analyse(&with_ground, &AnalysisSettings { region, ..at(24) }).unwrap();
        assert!((clipped.spec.voxel - 1.1 / 24.0).abs() < 1e-12);
        assert!(clipped.enclosed > 0.5 && !clipped.filtered.nodes.is_empty());
        let diluted = analyse(&with_ground, &at(24)).unwrap();
        assert!(diluted.spec.voxel > 5.0, "the plane sets the grid: the room is a voxel or two");
        let plane = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]];
        assert_eq!(analyse(&plane, &at(16)).unwrap().enclosed, 0.0);
        let only = AnalysisSettings { enclosed_only: true, ..at(16) };
        assert!(matches!(analyse(&plane, &only), Err(AnalysisError::NothingEnclosed)));
        // Inside only: the shell of air around the box goes, the room stays.
        let inside = analyse(&room, &AnalysisSettings { enclosed_only: true, ..at(24) }).unwrap();
        assert_eq!(inside.enclosed, alone.enclosed);
        assert!(inside.empty.data.iter().filter(|&&e| e).count() < alone.empty.data.iter().filter(|&&e| e).count());
        assert_eq!(inside.filtered.components(), 1);
        assert!(alone.filtered.components() >= 2, "room and shell");
        // By default, with no camera or light, the largest enclosed component: the room.
        let room_only = analyse(&room, &at(24)).unwrap();
        assert_eq!(room_only.reach.kept, Kept::LargestEnclosed);
        assert!(room_only.empty.data == inside.empty.data);
        assert_eq!(room_only.filtered.components(), 1);
        let inverted = Some([[1.0; 3], [0.0; 3]]);
        assert!(analyse(&room, &AnalysisSettings { region: inverted, ..at(16) }).is_err());
    }

    /// A light under the ceiling, anchored on its emitting side: the skeleton gains a node
    /// next to it; an anchor far outside the grid resolves to nothing.
    #[test]
    fn anchors_pull_the_skeleton_to_lights() {
        let room = closed_box([0.0; 3], [1.0; 3]);
        let light = Anchor { position: [0.5, 0.4, 0.999], side: [0.0, 0.0, -1.0] };
        let lost = Anchor { position: [50.0, 0.0, 0.0], side: [0.0; 3] };
        let settings = AnalysisSettings { anchors: vec![light, lost], ..at(24) };
        let a = analyse(&room, &settings).unwrap();
        assert!(a.anchor_voxels[0].is_some() && a.anchor_voxels[1].is_none());
        let near = |g: &SkeletonGraph| {
            g.nodes
                .iter()
                .map(|n| (0..3).map(|k| (n.position[k] - light.position[k]).powi(2)).sum::<f64>().sqrt())
                .fold(f64::INFINITY, f64::min)
        };
        let plain = analyse(&room, &at(24)).unwrap();
        let voxel = a.spec.voxel;
        // The ceiling's voxel and, by conservative voxelisation, possibly the one below are
        // full: the anchor voxel's centre is at most 1.5 voxels below the light, and the kept
        // corner at most √3/2 from that centre, so a node lies within 2.4 voxels.
        assert!(near(&a.skeleton) < 2.5 * voxel, "{} voxels away", near(&a.skeleton) / voxel);
        assert!(near(&plain.skeleton) > 4.0 * voxel, "{} voxels away", near(&plain.skeleton) / voxel);
        assert_eq!(a.skeleton.components(), plain.skeleton.components());
    }

    #[test]
    fn bad_input_is_refused_with_a_reason() {
        assert!(matches!(analyse(&[], &at(32)), Err(AnalysisError::NoTriangles)));
        let nan = [[[f64::NAN; 3]; 3]];
        assert!(matches!(analyse(&nan, &at(32)), Err(AnalysisError::NoTriangles)));
        // Degenerate triangles (all on a point) have empty bounds.
        let point = [[[1.0; 3]; 3]];
        assert!(matches!(analyse(&point, &at(32)), Err(AnalysisError::Grid(GridError::EmptyBounds))));
        let err = analyse(&closed_box([0.0; 3], [1.0; 3]), &at(100_000)).err().unwrap();
        assert!(matches!(err, AnalysisError::Grid(GridError::TooLarge(..))), "{err}");
        assert!(analyse(&closed_box([0.0; 3], [1.0; 3]), &at(0)).is_err());
    }
}
