//! Importance nodes (thesis §9.5.1): each skeleton node's importance is the emitted power
//! arriving on the surfaces mapped to it (eq. 171–175), estimated by tracing rays from the
//! lights and crediting each ray's power to the node of its first hit (eq. 176). Every light
//! type starts rays the way light tracing starts them (area, point, spot, directional,
//! environment, sun-sky), so every type is handled by the same estimate.
//!
//! Beyond the thesis, the light paths may go on for more bounces (BSDF sampling, as light
//! tracing walks them), each hit crediting the power that reaches it: the importance of
//! light that arrives only after reflections, such as a room lit through a door ajar
//! (`why-not-2x.md`, H3). One bounce is eq. 176.

use rayon::prelude::*;

use super::SkeletonGuide;
use crate::material::TransportMode;
use crate::paths::subpath::{random_walk, start_light_subpath, VertexSink};
use crate::paths::vertex::{Vertex, VertexKind};
use crate::sampling::Rng;
use crate::scene::Scene;

/// Rays per task: a task's sums are added in task order, so the estimate does not depend
/// on the thread count.
const CHUNK: usize = 4096;

/// Eq. 176 for every node of `guide` from `rays` rays of random stream `seed`: the mean
/// power (luminance) of the rays whose first hit maps to each node, and with `bounces` > 1
/// the power reaching each later hit of the light path, up to `bounces` hits.
pub fn incident_power(scene: &Scene, guide: &SkeletonGuide, rays: usize, bounces: u32, seed: u64) -> Vec<f64> {
    let nodes = guide.graph.nodes.len();
    let partial: Vec<Vec<f64>> = (0..rays.div_ceil(CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let mut credit = Credit { guide, sums: vec![0.0f64; nodes], path: Vec::new() };
            for i in chunk * CHUNK..((chunk + 1) * CHUNK).min(rays) {
                // A stream of its own, apart from every pixel's (pixel indices are < 2^28).
                let mut rng = Rng::new(seed, u64::MAX, i as u64);
                let Some(start) = start_light_subpath(scene, &mut rng, -1) else { continue };
                let power = start.beta.luminance() as f64;
                if !(power.is_finite() && power > 0.0) {
                    continue;
                }
                credit.path.clear();
                credit.path.push(start.vertex);
                let limit = bounces as usize + 1;
                let mode = TransportMode::Importance;
                random_walk(scene, start.ray, start.beta, start.pdf_dir, &mut rng, limit, mode, &mut credit);
            }
            credit.sums
        })
        .collect();
    let mut total = vec![0.0f64; nodes];
    for sums in &partial {
        for (t, s) in total.iter_mut().zip(sums) {
            *t += s;
        }
    }
    let n = rays.max(1) as f64;
    total.iter_mut().for_each(|t| *t /= n);
    total
}

/// A light path's walk crediting the power that reaches each surface hit to the hit's
/// node (the path, at most `bounces` + 1 vertices, is kept for the walk to read).
struct Credit<'a> {
    guide: &'a SkeletonGuide,
    sums: Vec<f64>,
    path: Vec<Vertex>,
}

impl VertexSink for Credit<'_> {
    fn push(&mut self, v: Vertex) {
        if v.kind == VertexKind::Surface {
            let power = v.beta.luminance() as f64;
            if power.is_finite() && power > 0.0 {
                if let Some(n) = self.guide.node_at(v.si.p, v.si.ng, v.si.wi) {
                    self.sums[n as usize] += power;
                }
            }
        }
        self.path.push(v);
    }
    fn count(&self) -> usize {
        self.path.len()
    }
    fn back(&self, i: usize) -> &Vertex {
        &self.path[self.path.len() - 1 - i]
    }
    fn back_mut(&mut self, i: usize) -> &mut Vertex {
        let n = self.path.len();
        &mut self.path[n - 1 - i]
    }
}

/// The importance nodes: every node with a positive value, the `most` largest if there are
/// more, as (node, value) from the largest down (ties by node index).
pub fn importance_nodes(values: &[f64], most: usize) -> Vec<(u32, f64)> {
    let mut nodes: Vec<(u32, f64)> =
        values.iter().enumerate().filter(|(_, v)| **v > 0.0).map(|(i, v)| (i as u32, *v)).collect();
    nodes.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    nodes.truncate(most);
    nodes
}
