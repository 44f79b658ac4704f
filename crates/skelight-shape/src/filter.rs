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
                    if visited[k] == i as u32 || distance(self.nodes[k].position, ci) > ri {
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
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
