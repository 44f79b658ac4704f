//! The skeleton as a graph (thesis §6.3–6.4): nodes at the vertices of the curvilinear
//! complex, with world position, the empty voxel they stand for and their maximal-ball
//! radius (Euclidean distance to the scene); edges from the complex's edges. Also the
//! filtered skeleton (Alg. 4), which merges nodes lying in the maximal ball of a larger
//! one, and the node mapping grid (Alg. 5), a breadth-first labelling of the empty space
//! by nearest node along 6-paths.

use std::collections::VecDeque;

use crate::complex::Complex;
use crate::grid::{neighbours6, Grid, GridSpec};

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
    /// with `edt` the squared Euclidean distance map of the empty space (in voxels²).
    pub fn from_complex(x: &Complex, spec: &GridSpec, empty: &Grid<bool>, edt: &Grid<u64>) -> SkeletonGraph {
        let mut node_of = vec![u32::MAX; x.cells.len()];
        let mut graph = SkeletonGraph::default();
        for (i, node) in node_of.iter_mut().enumerate() {
            if !x.cells[i] || x.dim(i) != 0 {
                continue;
            }
            // The empty voxel around the vertex farthest from the scene.
            let best = x
                .voxels_around(i)
                .into_iter()
                .filter(|&v| empty.data[v])
                .map(|v| (edt.data[v], v))
                .reduce(|a, b| if b.0 > a.0 { b } else { a });
            let Some((d2, voxel)) = best else { continue };
            *node = graph.nodes.len() as u32;
            let p = x.coords(i);
            let position = [0, 1, 2].map(|a| spec.origin[a] + (p[a] / 2) as f64 * spec.voxel);
            graph.nodes.push(Node { position, voxel, radius: (d2 as f64).sqrt() * spec.voxel });
        }
        for e in 0..x.cells.len() {
            if !x.cells[e] || x.dim(e) != 1 {
                continue;
            }
            let ends: Vec<u32> = x.facets(e).map(|f| node_of[f.0]).collect();
            if ends.len() == 2 && ends.iter().all(|&n| n != u32::MAX) {
                graph.edges.push([ends[0], ends[1]]);
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

    /// Alg. 4: visiting nodes by decreasing radius, each node not yet merged takes every
    /// unmerged node it reaches through the graph without leaving its maximal ball; merged
    /// nodes' edges go to their representatives.
    pub fn filtered(&self) -> SkeletonGraph {
        let n = self.nodes.len();
        let adj = self.adjacency();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| self.nodes[b].radius.total_cmp(&self.nodes[a].radius).then(a.cmp(&b)));
        let mut visited = vec![u32::MAX; n];
        let mut queue = VecDeque::new();
        for &i in &order {
            if parent[i] as usize != i {
                continue;
            }
            let (ci, ri) = (self.nodes[i].position, self.nodes[i].radius);
            visited[i] = i as u32;
            queue.push_back(i);
            while let Some(j) = queue.pop_front() {
                for &k in &adj[j] {
                    let k = k as usize;
                    if visited[k] == i as u32 || dist(self.nodes[k].position, ci) > ri {
                        continue;
                    }
                    visited[k] = i as u32;
                    if parent[k] as usize == k && k != i {
                        parent[k] = i as u32;
                    }
                    queue.push_back(k);
                }
            }
        }
        let mut index = vec![u32::MAX; n];
        let mut out = SkeletonGraph::default();
        for i in 0..n {
            if parent[i] as usize == i {
                index[i] = out.nodes.len() as u32;
                out.nodes.push(self.nodes[i]);
            }
        }
        let mut edges: Vec<[u32; 2]> = self
            .edges
            .iter()
            .map(|&[a, b]| (index[parent[a as usize] as usize], index[parent[b as usize] as usize]))
            .filter(|(a, b)| a != b)
            .map(|(a, b)| [a.min(b), a.max(b)])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        out.edges = edges;
        out
    }

    /// Alg. 5: every empty voxel gets the index + 1 of the node reached first by a
    /// breadth-first search from all nodes at once along 6-paths in the empty space (0 for
    /// voxels no node reaches, such as empty pockets with no skeleton).
    pub fn mapping_grid(&self, empty: &Grid<bool>) -> Grid<u32> {
        let spec = empty.spec;
        let mut grid = Grid::new(spec, 0u32);
        let mut queue = VecDeque::new();
        for (l, node) in self.nodes.iter().enumerate() {
            if grid.data[node.voxel] == 0 {
                grid.data[node.voxel] = l as u32 + 1;
                queue.push_back(node.voxel);
            }
        }
        while let Some(i) = queue.pop_front() {
            for j in neighbours6(spec.dims, i) {
                if empty.data[j] && grid.data[j] == 0 {
                    grid.data[j] = grid.data[i];
                    queue.push_back(j);
                }
            }
        }
        grid
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

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::euclidean_squared;
    use crate::testing::two_rooms_and_a_gap;
    use crate::thinning::{curvilinear_skeleton, EdgeConstraint};

    #[test]
    fn graph_filter_and_mapping_of_two_rooms() {
        let empty = two_rooms_and_a_gap(0.5);
        let (x, _) = curvilinear_skeleton(&empty, EdgeConstraint::Thesis);
        let edt = euclidean_squared(&empty, true);
        let g = SkeletonGraph::from_complex(&x, &empty.spec, &empty, &edt);
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
        // Every empty voxel maps to a node, reached inside the empty space.
        let m = f.mapping_grid(&empty);
        for i in 0..empty.data.len() {
            assert_eq!(empty.data[i], m.data[i] != 0, "voxel {i}");
        }
        // The two rooms map to different nodes.
        let (left, right) = (*m.get(4, 4, 4), *m.get(20, 4, 4));
        assert_ne!(left, right);
    }
}
