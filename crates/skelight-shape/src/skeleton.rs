//! The skeleton as a graph (thesis §6.3): nodes at the vertices of the curvilinear complex,
//! with world position, the empty voxel they stand for and their maximal-ball radius
//! (Euclidean distance to the scene); edges from the complex's edges. Filtering is in
//! [`crate::filter`], the mapping of voxels and surface points to nodes in
//! [`crate::mapping`].

use crate::complex::Complex;
use crate::grid::{par_flagged_positions, Grid, GridSpec};
use rayon::prelude::*;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    /// World-space position (the vertex of the voxel grid it stands on).
    pub position: [f64; 3],
    /// Linear index of the empty voxel it stands for (the most central of those around it).
    pub voxel: usize,
    /// Radius of the largest empty ball centred on that voxel (world units).
    pub radius: f64,
}

#[derive(Clone, Debug, Default)]
pub struct SkeletonGraph {
    pub nodes: Vec<Node>,
    pub edges: Vec<[u32; 2]>,
}

impl SkeletonGraph {
    /// The graph of a curvilinear complex `x` on the grid `spec` of the empty space `empty`,
    /// with `edt` the squared Euclidean distance of an empty voxel to the scene (in voxels²).
    pub fn from_complex(
        x: &Complex,
        spec: &GridSpec,
        empty: &Grid<bool>,
        edt: impl Fn(usize) -> u64 + Sync,
    ) -> SkeletonGraph {
        // A skeleton keeps few faces of a large array: find them in parallel.
        SkeletonGraph::from_faces(x, &par_flagged_positions(&x.cells, |_| true), spec, empty, edt)
    }

    /// [`SkeletonGraph::from_complex`] given the faces of `x` in increasing order, as the
    /// thinning leaves them listed.
    pub fn from_faces(
        x: &Complex,
        faces: &[usize],
        spec: &GridSpec,
        empty: &Grid<bool>,
        edt: impl Fn(usize) -> u64 + Sync,
    ) -> SkeletonGraph {
        // Nodes are looked up by face in the sorted list instead of a node array as large as
        // the complex.
        let mut graph = SkeletonGraph::default();
        let mut node_at: Vec<(usize, u32)> = Vec::new();
        // The empty voxel around each vertex farthest from the scene. `edt` may search (see
        // [`crate::distance::EuclideanRows::at`]): each voxel is asked once (door: 3.2 k for
        // 8 k vertex-voxel pairs), in parallel.
        let (vertices, edges): (Vec<usize>, Vec<usize>) =
            faces.iter().filter(|&&i| x.dim(i) <= 1).partition(|&&i| x.dim(i) == 0);
        let mut voxels: Vec<usize> =
            vertices.iter().flat_map(|&i| x.voxels_around(i)).filter(|&v| empty.data[v]).collect();
        voxels.sort_unstable();
        voxels.dedup();
        let distances: Vec<u64> = voxels.par_iter().map(|&v| edt(v)).collect();
        let distance =
            |v: usize| distances[voxels.binary_search(&v).expect("every empty voxel around a vertex was asked")];
        for i in vertices {
            let best = x.voxels_around(i).filter(|&v| empty.data[v]).map(|v| (distance(v), v)).reduce(|a, b| {
                if b.0 > a.0 {
                    b
                } else {
                    a
                }
            });
            let Some((d2, voxel)) = best else { continue };
            node_at.push((i, graph.nodes.len() as u32));
            let p = x.coords(i);
            let position = [0, 1, 2].map(|a| spec.origin[a] + (p[a] / 2) as f64 * spec.voxel);
            graph.nodes.push(Node { position, voxel, radius: (d2 as f64).sqrt() * spec.voxel });
        }
        let node_of = |f: usize| node_at.binary_search_by_key(&f, |&(face, _)| face).ok().map(|k| node_at[k].1);
        for e in edges {
            let ends: Vec<Option<u32>> = x.facets(e).map(|f| node_of(f.0)).collect();
            if let [Some(a), Some(b)] = ends[..] {
                graph.edges.push([a, b]);
            }
        }
        graph
    }

    /// Neighbour lists.
    pub fn adjacency(&self) -> Vec<Vec<u32>> {
        let mut adj = vec![Vec::new(); self.nodes.len()];
        for &[a, b] in &self.edges {
            adj[a as usize].push(b);
            adj[b as usize].push(a);
        }
        adj
    }

    /// Number of connected components of the graph.
    pub fn components(&self) -> usize {
        let adj = self.adjacency();
        let mut seen = vec![false; self.nodes.len()];
        let mut count = 0;
        for s in 0..self.nodes.len() {
            if seen[s] {
                continue;
            }
            count += 1;
            seen[s] = true;
            let mut stack = vec![s];
            while let Some(i) = stack.pop() {
                for &j in &adj[i] {
                    if !std::mem::replace(&mut seen[j as usize], true) {
                        stack.push(j as usize);
                    }
                }
            }
        }
        count
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::euclidean_squared;
    use crate::testing::two_rooms_and_a_gap;
    use crate::thinning::{curvilinear_skeleton, EdgeConstraint};

    #[test]
    fn graph_and_filtered_graph_of_two_rooms() {
        let empty = two_rooms_and_a_gap(0.5);
        let x = curvilinear_skeleton(&empty, EdgeConstraint::Thesis, &[]).unwrap();
        let edt = euclidean_squared(&empty, true);
        let g = SkeletonGraph::from_complex(&x, &empty.spec, &empty, |v| edt.data[v]);
        assert!(!g.nodes.is_empty());
        assert_eq!(g.components(), 1);
        // A tree (the rooms have no tunnel): edges = nodes − 1.
        assert_eq!(g.edges.len(), g.nodes.len() - 1);
        for n in &g.nodes {
            assert!(empty.data[n.voxel] && n.radius > 0.0);
        }
        let f = g.filtered();
        assert!(f.nodes.len() < g.nodes.len(), "{} → {}", g.nodes.len(), f.nodes.len());
        assert_eq!(f.components(), 1, "filtering keeps the skeleton connected");
    }
}
