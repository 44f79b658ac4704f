//! Importance nodes (thesis §9.5.1): each skeleton node's importance is the emitted power
//! arriving on the surfaces mapped to it (eq. 171–175), estimated by tracing rays from the
//! lights and crediting each ray's power to the node of its first hit (eq. 176). Every light
//! type starts rays the way light tracing starts them (area, point, spot, directional,
//! environment, sun-sky), so every type is handled by the same estimate.

use rayon::prelude::*;

use super::SkeletonGuide;
use crate::integrator::subpath::start_light_subpath;
use crate::sampling::Rng;
use crate::scene::Scene;

/// Rays per task: a task's sums are added in task order, so the estimate does not depend
/// on the thread count.
const CHUNK: usize = 4096;

/// Eq. 176 for every node of `guide` from `rays` rays of random stream `seed`: the mean
/// power (luminance) of the rays whose first hit maps to each node.
pub fn incident_power(scene: &Scene, guide: &SkeletonGuide, rays: usize, seed: u64) -> Vec<f64> {
    let nodes = guide.graph.nodes.len();
    let partial: Vec<Vec<f64>> = (0..rays.div_ceil(CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let mut sums = vec![0.0f64; nodes];
            for i in chunk * CHUNK..((chunk + 1) * CHUNK).min(rays) {
                // A stream of its own, apart from every pixel's (pixel indices are < 2^28).
                let mut rng = Rng::new(seed, u64::MAX, i as u64);
                let Some(start) = start_light_subpath(scene, &mut rng, -1) else { continue };
                let power = start.beta.luminance() as f64;
                if !(power.is_finite() && power > 0.0) {
                    continue;
                }
                let Some(hit) = scene.intersect(&start.ray) else { continue };
                if let Some(n) = guide.node_at(hit.p, hit.ng, -start.ray.d) {
                    sums[n as usize] += power;
                }
            }
            sums
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

/// The importance nodes: every node with a positive value, the `most` largest if there are
/// more, as (node, value) from the largest down (ties by node index).
pub fn importance_nodes(values: &[f64], most: usize) -> Vec<(u32, f64)> {
    let mut nodes: Vec<(u32, f64)> =
        values.iter().enumerate().filter(|(_, v)| **v > 0.0).map(|(i, v)| (i as u32, *v)).collect();
    nodes.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    nodes.truncate(most);
    nodes
}
