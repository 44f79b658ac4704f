//! The whole empty-space analysis of a triangle scene, stage by stage with timings:
//! voxelisation, distance and opening maps, thinning into the curvilinear skeleton, its
//! graph, the filtered graph, the node mapping grid, the opening-forest labels and portals.

use std::time::Instant;

use crate::complex::Complex;
use crate::distance::{chessboard, euclidean_squared};
use crate::grid::{Grid, GridError, GridSpec};
use crate::labeling::{opening_forest_labelling, Labelling};
use crate::mapping::NodeMapping;
use crate::opening::opening;
use crate::portals::{portals, Portal};
use crate::skeleton::SkeletonGraph;
use crate::thinning::{curvilinear_skeleton, EdgeConstraint};
use crate::voxelize::{empty_space, voxelize};

/// Bytes the analysis holds per voxel at its peak: the doubled grid of the complex (8 cells
/// per voxel) with two dates, a constraint flag and traversal flags, plus the maps.
pub const BYTES_PER_VOXEL: u64 = 8 * (1 + 8 + 1 + 1 + 1) + 32;

#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    #[error("the scene has no usable triangles to voxelise")]
    NoTriangles,
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error("no empty voxel at this resolution: the scene fills its whole grid")]
    NoEmptySpace,
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
    /// Seconds spent in each stage, in order.
    pub timings: Vec<(&'static str, f64)>,
}

/// Runs every stage on `triangles` with a grid whose longest side has `resolution` voxels
/// over the scene's bounds grown by 10 % (the seeds' set-up).
pub fn analyse(
    triangles: &[[[f64; 3]; 3]],
    resolution: usize,
    constraint: EdgeConstraint,
) -> Result<Analysis, AnalysisError> {
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
    let spec = GridSpec::from_bounds(lo, hi, resolution, 0.05)?;
    spec.check_memory(BYTES_PER_VOXEL)?;
    let empty = empty_space(&voxelize(&spec, triangles));
    if !empty.data.iter().any(|&e| e) {
        return Err(AnalysisError::NoEmptySpace);
    }
    lap("voxelise", &mut timings);
    let chess = chessboard(&empty, true);
    let edt = euclidean_squared(&empty, true);
    let open = opening(&chess);
    lap("distance and opening maps", &mut timings);
    let (complex, _) = curvilinear_skeleton(&empty, constraint);
    lap("thinning (Alg. 2-3, piercing)", &mut timings);
    let skeleton = SkeletonGraph::from_complex(&complex, &spec, &empty, &edt);
    let filtered = skeleton.filtered();
    lap("skeleton graph and filtering (Alg. 4)", &mut timings);
    let mapping = NodeMapping::new(&filtered, &empty);
    lap("node mapping grid (Alg. 5)", &mut timings);
    let labelling = opening_forest_labelling(&open);
    let portals = portals(&labelling);
    lap("opening-forest labels and portals", &mut timings);
    Ok(Analysis { spec, empty, complex, skeleton, filtered, mapping, labelling, portals, timings })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed box of 12 triangles: one room, a connected skeleton inside it.
    fn closed_box(lo: f64, hi: f64) -> Vec<[[f64; 3]; 3]> {
        let c = |i: usize| [0, 1, 2].map(|a| if i >> a & 1 == 1 { hi } else { lo });
        let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
        quads.iter().flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]]).collect()
    }

    #[test]
    fn a_closed_room_gives_one_connected_skeleton() {
        let a = analyse(&closed_box(0.0, 1.0), 24, EdgeConstraint::Thesis).unwrap();
        assert_eq!(a.skeleton.components(), a.filtered.components());
        assert!(!a.filtered.nodes.is_empty());
        assert_eq!(a.timings.len(), 6);
        // Every empty voxel inside the walls maps to a node.
        let inside = (0..a.spec.len()).filter(|&i| a.empty.data[i]).all(|i| a.mapping.node_of_voxel(i).is_some());
        assert!(inside);
    }

    #[test]
    fn bad_input_is_refused_with_a_reason() {
        assert!(matches!(analyse(&[], 32, EdgeConstraint::Thesis), Err(AnalysisError::NoTriangles)));
        let nan = [[[f64::NAN; 3]; 3]];
        assert!(matches!(analyse(&nan, 32, EdgeConstraint::Thesis), Err(AnalysisError::NoTriangles)));
        // Degenerate triangles (all on a point) have empty bounds.
        let point = [[[1.0; 3]; 3]];
        assert!(matches!(
            analyse(&point, 32, EdgeConstraint::Thesis),
            Err(AnalysisError::Grid(GridError::EmptyBounds))
        ));
        let err = analyse(&closed_box(0.0, 1.0), 100_000, EdgeConstraint::Thesis).err().unwrap();
        assert!(matches!(err, AnalysisError::Grid(GridError::TooLarge(..))), "{err}");
        assert!(analyse(&closed_box(0.0, 1.0), 0, EdgeConstraint::Thesis).is_err());
    }
}
