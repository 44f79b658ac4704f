//! The filtered skeleton (thesis Alg. 4): the skeleton graph with every node that lies in
//! the maximal ball of a larger node, and is reached from it without leaving that ball,
//! merged into it. Rooms keep a few central nodes instead of hundreds along their medial
//! curves, which is what the sampling methods that walk the skeleton want.

use std::collections::VecDeque;

use crate::skeleton::SkeletonGraph;

impl SkeletonGraph {
    /// Alg. 4: visiting nodes by decreasing radius, each node not yet merged takes every
    /// unmerged node it reaches through the graph without leaving its maximal ball; merged
    /// nodes' edges go to their representatives.
    ///
    /// A node that has already taken others is never taken itself. The thesis' line 7 allows
    /// it (a smaller ball can reach a larger node that did not reach it, the paths inside the
    /// two balls differing), which leaves merged nodes pointing at a node that is no longer a
    /// representative, while its lines 13–18 read P(n) as one.
    pub fn filtered(&self) -> SkeletonGraph {
        let n = self.nodes.len();
        let adj = self.adjacency();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| self.nodes[b].radius.total_cmp(&self.nodes[a].radius).then(a.cmp(&b)));
        let mut visited = vec![u32::MAX; n];
        let mut representative = vec![false; n];
        let mut queue = VecDeque::new();
        for &i in &order {
            if parent[i] as usize != i {
                continue;
            }
            representative[i] = true;
            let (ci, ri) = (self.nodes[i].position, self.nodes[i].radius);
            visited[i] = i as u32;
            queue.push_back(i);
            while let Some(j) = queue.pop_front() {
                for &k in &adj[j] {
                    let k = k as usize;
                    if visited[k] == i as u32 || distance(self.nodes[k].position, ci) > ri {
                        continue;
                    }
                    visited[k] = i as u32;
                    if parent[k] as usize == k && !representative[k] {
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
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use crate::skeleton::{Node, SkeletonGraph};

    fn node(x: f64, radius: f64) -> Node {
        Node { position: [x, 0.0, 0.0], voxel: 0, radius }
    }

    /// A small ball reaches a larger node that did not reach it: J (r 5) takes its neighbour
    /// c; I (r 4.5) reaches J through q, which lies outside J's ball. J must stay a
    /// representative, or c would point at a merged node.
    #[test]
    fn a_representative_is_never_taken_by_a_smaller_ball() {
        let g = SkeletonGraph {
            nodes: vec![node(0.0, 5.0), node(1.0, 0.5), node(8.0, 1.0), node(4.0, 4.5)],
            edges: vec![[0, 1], [0, 2], [2, 3]],
        };
        let f = g.filtered();
        assert_eq!(f.nodes.iter().map(|n| n.position[0]).collect::<Vec<_>>(), vec![0.0, 4.0]);
        assert_eq!(f.edges, vec![[0, 1]]);
        assert_eq!(f.components(), 1);
    }
}
