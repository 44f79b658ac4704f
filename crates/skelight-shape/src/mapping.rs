//! Skeleton mapping (thesis §6.4): which skeleton node stands for a place in the scene.
//!
//! The node mapping grid (Alg. 5) labels every empty voxel with the node reached first by a
//! breadth-first search from all nodes at once along 6-paths of the empty space, so the
//! label follows geodesic, not straight-line, distance: a voxel behind a wall maps to a
//! node on its own side. A surface point lies in a scene voxel, which has no label; it
//! takes the label of the empty neighbour on the side it is seen from (eq. 151–155).

use crate::grid::{axis_neighbours, Grid, GridSpec, Padded};
use crate::skeleton::SkeletonGraph;

/// The node mapping grid of one skeleton graph.
#[derive(Clone, Debug)]
pub struct NodeMapping {
    /// Node index + 1 for every empty voxel a node reaches; 0 for scene voxels and for
    /// empty pockets with no node.
    pub grid: Grid<u32>,
}

impl NodeMapping {
    /// Alg. 5 on the empty space `empty` for the nodes of `graph`.
    pub fn new(graph: &SkeletonGraph, empty: &Grid<bool>) -> NodeMapping {
        // A breadth-first flood from every node's voxel at once, on a padded grid so that
        // neighbours are fixed offsets. One array says both whether a cell may be entered
        // and which node holds it (BLOCKED for scene voxels and the padding), so each
        // neighbour costs one read; the flood goes level by level through two lists of
        // indices, in the order a FIFO queue would (u32: `check_memory` refuses grids far
        // below 2³² cells).
        const BLOCKED: u32 = u32::MAX;
        let spec = empty.spec;
        let layout = Padded::new(spec.dims);
        let strides = layout.strides();
        let mut label = layout.pad(&empty.data, BLOCKED, |e| if e { 0 } else { BLOCKED });
        let mut level: Vec<u32> = Vec::new();
        for (l, node) in graph.nodes.iter().enumerate() {
            let [x, y, z] = spec.coords(node.voxel);
            let i = layout.index(x, y, z);
            if label[i] == 0 {
                label[i] = l as u32 + 1;
                level.push(i as u32);
            }
        }
        let mut next: Vec<u32> = Vec::new();
        while !level.is_empty() {
            for &i in &level {
                let i = i as usize;
                // Read once: the stores below could be to it, as far as the compiler knows.
                let node = label[i];
                for j in axis_neighbours(i, strides) {
                    if label[j] == 0 {
                        label[j] = node;
                        next.push(j as u32);
                    }
                }
            }
            std::mem::swap(&mut level, &mut next);
            next.clear();
        }
        let data = layout.unpad_map(&label, |l| if l == BLOCKED { 0 } else { l });
        let grid = Grid { spec, data };
        NodeMapping { grid }
    }

    /// The node of the voxel with linear index `voxel`, if it has one.
    pub fn node_of_voxel(&self, voxel: usize) -> Option<u32> {
        self.grid.data.get(voxel).and_then(|&l| l.checked_sub(1))
    }

    /// The node mapped to the surface point `point` with normal `normal`, seen from the
    /// direction `incident` (a vector from the point towards where it is seen from, e.g. the
    /// previous path vertex): [`surface_voxel`]'s voxel, then its label (eq. 155).
    pub fn node_at(&self, point: [f64; 3], normal: [f64; 3], incident: [f64; 3]) -> Option<u32> {
        let labelled = |v: usize| self.grid.data[v] != 0;
        surface_voxel(&self.grid.spec, labelled, point, normal, incident).and_then(|v| self.node_of_voxel(v))
    }
}

/// Eq. 151–154: the labelled empty voxel that stands for a surface point seen from
/// `incident`, for any labelling of the empty space (skeleton nodes, opening regions);
/// `None` when the point lies outside the grid or no labelled voxel is near it.
///
/// Eq. 151: the point's voxel v_x. Eq. 152–153: the normal turned towards `incident` (the
/// grid is axis-aligned with cubic voxels, so it keeps its direction in grid space).
/// Eq. 154: among the 26 neighbours of v_x that are labelled, the one whose offset from v_x
/// best follows that normal. When v_x itself is labelled (a point inside a wall thinner than
/// the voxelisation resolved) it is the answer, and when no neighbour is labelled (a wall two
/// voxels thick at this point) the search moves one voxel along the normal, at most twice.
pub fn surface_voxel(
    spec: &GridSpec,
    labelled: impl Fn(usize) -> bool,
    point: [f64; 3],
    normal: [f64; 3],
    incident: [f64; 3],
) -> Option<usize> {
    let facing = normal[0] * incident[0] + normal[1] * incident[1] + normal[2] * incident[2];
    let n = if facing >= 0.0 { normal } else { normal.map(|c| -c) };
    let mut v = voxel_of(spec, point)?;
    for _ in 0..3 {
        let here = spec.index(v[0], v[1], v[2]);
        if labelled(here) {
            return Some(here);
        }
        if let Some(best) = best_neighbour(spec, &labelled, v, n) {
            return Some(best);
        }
        // Step to the neighbour nearest the normal's direction, labelled or not.
        let step = n.map(|c| (c * std::f64::consts::SQRT_2).round() as i64);
        v = spec.offset(v, step)?;
    }
    None
}

/// Eq. 154: the labelled 26-neighbour u of `v` maximising (u − v)·n. Ties (an axis-aligned
/// normal scores all nine neighbours on its side alike) go to the offset closest in angle,
/// the face neighbour straight ahead.
fn best_neighbour(spec: &GridSpec, labelled: &impl Fn(usize) -> bool, v: [usize; 3], n: [f64; 3]) -> Option<usize> {
    // (u − v)·n is largest at the offset of n's signs (0 where n has none), and among offsets
    // of equal dot that one is the shortest: when it is labelled it is the answer, without
    // the search (the common case at render time, where this runs at every path vertex).
    let sign = |c: f64| {
        if c > 0.0 {
            1
        } else if c < 0.0 {
            -1
        } else {
            0
        }
    };
    let ahead = n.map(sign);
    if ahead != [0, 0, 0] {
        if let Some(u) = spec.offset(v, ahead) {
            let u = spec.index(u[0], u[1], u[2]);
            if labelled(u) {
                return Some(u);
            }
        }
    }
    let mut best: Option<((f64, f64), usize)> = None;
    for dz in -1..=1i64 {
        for dy in -1..=1i64 {
            for dx in -1..=1i64 {
                if (dx, dy, dz) == (0, 0, 0) {
                    continue;
                }
                let Some(u) = spec.offset(v, [dx, dy, dz]) else { continue };
                let u = spec.index(u[0], u[1], u[2]);
                if !labelled(u) {
                    continue;
                }
                let dot = dx as f64 * n[0] + dy as f64 * n[1] + dz as f64 * n[2];
                let score = (dot, dot / ((dx * dx + dy * dy + dz * dz) as f64).sqrt());
                if best.is_none_or(|(s, _)| score > s) {
                    best = Some((score, u));
                }
            }
        }
    }
    best.map(|(_, u)| u)
}

/// Eq. 151: the voxel containing `point`; points up to half a voxel outside the grid are
/// clamped onto its border (geometry on the bounds' faces), farther ones have none.
pub fn voxel_of(spec: &GridSpec, point: [f64; 3]) -> Option<[usize; 3]> {
    let mut v = [0; 3];
    for a in 0..3 {
        let t = (point[a] - spec.origin[a]) / spec.voxel;
        if !(t >= -0.5 && t < spec.dims[a] as f64 + 0.5) {
            return None;
        }
        v[a] = (t.floor().max(0.0) as usize).min(spec.dims[a] - 1);
    }
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::euclidean_squared;
    use crate::grid::neighbours6;
    use crate::testing::two_rooms_and_a_gap;
    use crate::thinning::{curvilinear_skeleton, EdgeConstraint};

    fn two_rooms() -> (Grid<bool>, SkeletonGraph, NodeMapping) {
        let empty = two_rooms_and_a_gap(0.5);
        let x = curvilinear_skeleton(&empty, EdgeConstraint::Thesis, &[]).unwrap();
        let edt = euclidean_squared(&empty, true);
        let graph = SkeletonGraph::from_complex(&x, &empty.spec, &empty, |v| edt.data[v]).filtered();
        let mapping = NodeMapping::new(&graph, &empty);
        (empty, graph, mapping)
    }

    /// 6-connected components of the empty space, as a label per voxel (0 outside it).
    fn components(empty: &Grid<bool>) -> Vec<u32> {
        let mut label = vec![0u32; empty.data.len()];
        let mut next = 0;
        for s in 0..empty.data.len() {
            if !empty.data[s] || label[s] != 0 {
                continue;
            }
            next += 1;
            label[s] = next;
            let mut stack = vec![s];
            while let Some(i) = stack.pop() {
                for j in neighbours6(empty.spec.dims, i) {
                    if empty.data[j] && label[j] == 0 {
                        label[j] = next;
                        stack.push(j);
                    }
                }
            }
        }
        label
    }

    #[test]
    fn every_empty_voxel_maps_to_a_node_it_can_reach() {
        let (empty, graph, m) = two_rooms();
        let component = components(&empty);
        for i in 0..empty.data.len() {
            let node = m.node_of_voxel(i);
            assert_eq!(empty.data[i], node.is_some(), "voxel {i}");
            if let Some(node) = node {
                assert_eq!(component[i], component[graph.nodes[node as usize].voxel], "voxel {i}");
            }
        }
        // The two rooms map to different nodes.
        assert_ne!(m.node_of_voxel(empty.spec.index(4, 4, 4)), m.node_of_voxel(empty.spec.index(20, 4, 4)));
    }

    #[test]
    fn a_wall_point_maps_to_the_side_it_is_seen_from() {
        let (empty, graph, m) = two_rooms();
        // The middle of the wall voxel (12, 4, 4), 0.5 units wide: the wall's plane x = 6.25.
        let p = [6.25, 2.25, 2.25];
        let wall_x = 6.25;
        for (normal, incident, right) in [
            ([1.0, 0.0, 0.0], [1.0, 0.0, 0.0], true),
            ([1.0, 0.0, 0.0], [-1.0, 0.2, 0.0], false),
            ([-1.0, 0.0, 0.0], [0.7, 0.0, 0.7], true),
            ([-1.0, 0.0, 0.0], [-0.3, 0.0, -0.9], false),
        ] {
            let node = m.node_at(p, normal, incident).expect("a wall between two rooms has a node on each side");
            let x = graph.nodes[node as usize].position[0];
            assert_eq!(x > wall_x, right, "normal {normal:?}, incident {incident:?}: node at x = {x}");
            // The chosen node is that of the empty voxel next to the wall on that side.
            let side = if right { 13 } else { 11 };
            assert_eq!(Some(node), m.node_of_voxel(empty.spec.index(side, 4, 4)));
        }
        // Far outside the grid: no node.
        assert_eq!(m.node_at([100.0, 2.0, 2.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]), None);
        // On the outer wall (x = 0 voxel), seen from inside: the left room's node.
        let node = m.node_at([0.25, 2.25, 2.25], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        assert_eq!(node, m.node_of_voxel(empty.spec.index(1, 4, 4)));
    }
}
