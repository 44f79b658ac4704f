//! Skeleton sampling of directions (thesis §9.2–9.3): for every skeleton node, the
//! importance point towards each importance node (eq. 162) and the probability of choosing
//! it (eq. 164–165); at a surface point, a cos^s lobe around the direction to the chosen
//! importance point (eq. 163), and the density of the whole mixture (eq. 167) that MIS
//! needs (a sum over every importance node of every light, not only the chosen one's).

use std::cmp::Reverse;
use std::collections::hash_map::Entry;
use std::collections::{BinaryHeap, HashMap};

use rayon::prelude::*;

use super::SkeletonGuide;
use crate::geometry::Ray;
use crate::math::{Frame, Vec2, Vec3};
use crate::sampling::{cos_power, power_cosine, power_cosine_norm, power_cosine_pdf};
use crate::scene::Scene;

/// Targets whose c'_i is below this share of the node's largest are dropped (and the rest
/// renormalised): they would cost a lobe evaluation in every density for nothing.
const NEGLIGIBLE: f32 = 1e-3;

/// One importance node as seen from one skeleton node.
#[derive(Clone, Copy, Debug)]
pub struct Target {
    /// The importance point (eq. 162).
    pub point: Vec3,
    /// c_i (eq. 165).
    pub probability: f32,
    /// Sum of the probabilities up to and including this one.
    pub cumulative: f32,
}

/// Per skeleton node, its targets, in one array.
#[derive(Clone, Debug, Default)]
pub struct Directions {
    /// Node k's targets are `targets[offsets[k]..offsets[k + 1]]`.
    offsets: Vec<u32>,
    targets: Vec<Target>,
}

impl Directions {
    /// Shortest paths on the skeleton graph from every node to each importance node
    /// (Dijkstra, Euclidean edge lengths), the importance points along them with the
    /// visibility test (eq. 162), and the selection probabilities c_i ∝ f_i / d_skel²
    /// (eq. 164–165). The distance is floored at the importance node's maximal-ball radius
    /// (and one voxel), so a point at an importance node does not divide by zero.
    pub fn build(scene: &Scene, guide: &SkeletonGuide, importance: &[(u32, f64)]) -> Directions {
        let n = guide.graph.nodes.len();
        let adjacency = guide.graph.adjacency();
        let voxel = guide.mapping.grid.spec.voxel;
        // Per importance node: (node k, importance point, unnormalised c'_i) for every
        // node that reaches it.
        let per_target: Vec<Vec<(u32, Vec3, f64)>> = importance
            .par_iter()
            .map(|&(target, value)| {
                let (dist, next) = shortest_paths(guide, &adjacency, target);
                let floor = guide.graph.nodes[target as usize].radius.max(voxel);
                (0..n as u32)
                    .filter(|&k| dist[k as usize].is_finite())
                    .map(|k| {
                        let d = dist[k as usize].max(floor);
                        (k, importance_point(scene, guide, &next, k), value / (d * d))
                    })
                    .collect()
            })
            .collect();
        let mut lists: Vec<Vec<(Vec3, f64)>> = vec![Vec::new(); n];
        for entries in per_target {
            for (k, point, weight) in entries {
                lists[k as usize].push((point, weight));
            }
        }
        let mut offsets = Vec::with_capacity(n + 1);
        let mut targets = Vec::new();
        offsets.push(0);
        for list in lists {
            let list = merge_identical_points(list);
            // Targets far below the node's largest are dropped; the rest renormalised.
            let largest = list.iter().map(|e| e.1).fold(0.0f64, f64::max);
            if largest > 0.0 && largest.is_finite() {
                let kept: Vec<(Vec3, f64)> = list.into_iter().filter(|e| e.1 >= NEGLIGIBLE as f64 * largest).collect();
                let total: f64 = kept.iter().map(|e| e.1).sum();
                let (mut before, mut cumulative) = (0.0f32, 0.0f64);
                for (i, &(point, weight)) in kept.iter().enumerate() {
                    cumulative += weight / total;
                    let upto = if i + 1 == kept.len() { 1.0 } else { cumulative as f32 };
                    // The probability is the step the sampler takes, so the two agree exactly.
                    targets.push(Target { point, probability: upto - before, cumulative: upto });
                    before = upto;
                }
            }
            offsets.push(targets.len() as u32);
        }
        Directions { offsets, targets }
    }

    /// Node `node`'s targets (empty where no importance node is reached).
    #[inline]
    pub fn at(&self, node: u32) -> &[Target] {
        let k = node as usize;
        match (self.offsets.get(k), self.offsets.get(k + 1)) {
            (Some(&a), Some(&b)) => &self.targets[a as usize..b as usize],
            _ => &[],
        }
    }

    /// Memory used, in bytes.
    pub fn bytes(&self) -> usize {
        self.offsets.len() * 4 + self.targets.len() * std::mem::size_of::<Target>()
    }

    /// Targets over all nodes (for reports).
    pub fn len(&self) -> usize {
        self.targets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }
}

/// Importance nodes whose shortest paths share the run of nodes a node sees give that node
/// the same importance point (eq. 162), bit for bit: one lobe with their summed weight is the
/// same mixture (eq. 167), evaluated once (Sponza: 3384 targets → 1723). First occurrences
/// keep their order.
fn merge_identical_points(list: Vec<(Vec3, f64)>) -> Vec<(Vec3, f64)> {
    let mut index: HashMap<[u32; 3], usize> = HashMap::with_capacity(list.len());
    let mut merged: Vec<(Vec3, f64)> = Vec::with_capacity(list.len());
    for (point, weight) in list {
        match index.entry([point.x.to_bits(), point.y.to_bits(), point.z.to_bits()]) {
            Entry::Occupied(e) => merged[*e.get()].1 += weight,
            Entry::Vacant(e) => {
                e.insert(merged.len());
                merged.push((point, weight));
            }
        }
    }
    merged
}

/// Dijkstra from `source` over the skeleton graph: each node's distance to it and the next
/// node on a shortest path towards it (`u32::MAX` for the source and unreached nodes).
fn shortest_paths(guide: &SkeletonGuide, adjacency: &[Vec<u32>], source: u32) -> (Vec<f64>, Vec<u32>) {
    let n = adjacency.len();
    let mut dist = vec![f64::INFINITY; n];
    let mut next = vec![u32::MAX; n];
    let mut heap = BinaryHeap::new();
    dist[source as usize] = 0.0;
    heap.push((Reverse(Ordered(0.0)), source));
    let pos = |k: u32| guide.graph.nodes[k as usize].position;
    while let Some((Reverse(Ordered(d)), k)) = heap.pop() {
        if d > dist[k as usize] {
            continue;
        }
        let [x, y, z] = pos(k);
        for &j in &adjacency[k as usize] {
            let [a, b, c] = pos(j);
            let nd = d + ((a - x).powi(2) + (b - y).powi(2) + (c - z).powi(2)).sqrt();
            if nd < dist[j as usize] {
                dist[j as usize] = nd;
                next[j as usize] = k;
                heap.push((Reverse(Ordered(nd)), j));
            }
        }
    }
    (dist, next)
}

/// Eq. 162: the mean position of the longest run of nodes of node `k`'s shortest path that
/// `k` sees (k itself first).
fn importance_point(scene: &Scene, guide: &SkeletonGuide, next: &[u32], k: u32) -> Vec3 {
    let from = guide.position(k);
    let (mut sum, mut count) = (from, 1.0f32);
    let mut j = next[k as usize];
    // A path has at most as many nodes as the graph (guards a corrupted `next`).
    for _ in 0..next.len() {
        if j == u32::MAX {
            break;
        }
        let p = guide.position(j);
        let ray = Ray { o: from, d: p - from, tmax: 1.0 - 1e-4 };
        if scene.occluded(&ray) {
            break;
        }
        sum += p;
        count += 1.0;
        j = next[j as usize];
    }
    sum / count
}

/// f64 ordered for the heap (distances are never NaN).
#[derive(Clone, Copy, PartialEq, PartialOrd)]
struct Ordered(f64);
impl Eq for Ordered {}
#[allow(clippy::derive_ord_xor_partial_ord)]
impl Ord for Ordered {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// The skeleton importance direction from `x` to `point` (eq. 163's axis); the surface's
/// normal when the two coincide, so that sampling and density agree on it.
#[inline]
fn axis(x: Vec3, point: Vec3, normal: Vec3) -> Vec3 {
    let d = point - x;
    let len = d.length();
    if len > 1e-6 {
        d / len
    } else {
        normal
    }
}

/// Eq. 163: the density (s+1)/2π · max(0, cos)^s of a direction `cos` off the axis.
#[inline]
pub fn lobe_pdf(strength: f32, cos: f32) -> f32 {
    power_cosine_pdf(cos, strength)
}

/// Samples eq. 163's lobe around `axis`.
#[inline]
pub fn sample_lobe(strength: f32, axis: Vec3, u: Vec2) -> Vec3 {
    Frame::from_normal(axis).to_world(power_cosine(u, strength))
}

/// Eq. 167: the mixture over `targets` of their lobes at `x`, evaluated for direction `wo`
/// (unit, world space).
#[inline]
pub fn mixture_pdf(targets: &[Target], strength: f32, x: Vec3, normal: Vec3, wo: Vec3) -> f32 {
    mixture_pdfs(targets, &[strength], x, normal, wo)[0]
}

/// [`mixture_pdf`] for several strengths at once (the adaptive mode's candidates): each
/// target's axis and cosine once, then cos^s per strength; the lobes' normalisation
/// (s+1)/2π once per strength, outside the loop over targets (this sum is most of skelpt's
/// cost per vertex).
#[inline]
pub fn mixture_pdfs<const N: usize>(
    targets: &[Target],
    strengths: &[f32; N],
    x: Vec3,
    normal: Vec3,
    wo: Vec3,
) -> [f32; N] {
    let mut sums = [0.0; N];
    for t in targets {
        let cos = axis(x, t.point, normal).dot(wo);
        if cos <= 0.0 {
            continue;
        }
        for (sum, &s) in sums.iter_mut().zip(strengths) {
            *sum += t.probability * cos_power(cos, s);
        }
    }
    for (sum, &s) in sums.iter_mut().zip(strengths) {
        *sum *= power_cosine_norm(s);
    }
    sums
}

/// Draws a direction from eq. 167's mixture: a target by its probability (`u_pick`), then
/// a direction in its lobe (`u`).
#[inline]
pub fn sample_mixture(targets: &[Target], strength: f32, x: Vec3, normal: Vec3, u_pick: f32, u: Vec2) -> Vec3 {
    let i = targets.partition_point(|t| t.cumulative <= u_pick).min(targets.len() - 1);
    sample_lobe(strength, axis(x, targets[i].point, normal), u)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::vec3;

    /// Merging the targets that share a point keeps eq. 167's mixture: at any x and ω, the
    /// normalised sum over the merged list equals the one over the list with repeats
    /// (dropping a repeat's weight instead of adding it: fails).
    #[test]
    fn merging_identical_points_keeps_the_mixture() {
        let (a, b, c) = (vec3(1.0, 2.0, 0.5), vec3(-1.0, 1.0, 0.0), vec3(0.2, 3.0, -0.4));
        let list = vec![(a, 0.2), (b, 0.3), (a, 0.1), (c, 0.4), (b, 0.05), (a, 0.7)];
        let merged = merge_identical_points(list.clone());
        assert_eq!(merged.iter().map(|e| e.0).collect::<Vec<_>>(), vec![a, b, c]);
        let mixture = |l: &[(Vec3, f64)], x: Vec3, wo: Vec3| {
            let total: f64 = l.iter().map(|e| e.1).sum();
            l.iter().map(|&(p, w)| w / total * lobe_pdf(8.0, (p - x).normalize().dot(wo)) as f64).sum::<f64>()
        };
        for (x, wo) in [
            (vec3(0.0, 0.0, 0.0), vec3(0.3, 0.9, 0.1)),
            (vec3(0.5, -0.2, 0.1), vec3(-0.6, 0.7, 0.2)),
            (vec3(0.1, 0.4, -0.3), vec3(0.1, 0.95, -0.2)),
        ] {
            let wo = wo.normalize();
            let (repeats, once) = (mixture(&list, x, wo), mixture(&merged, x, wo));
            assert!((repeats - once).abs() <= 1e-12 * repeats.max(1e-30), "{once} against {repeats}");
        }
    }

    /// The adaptive mode's candidates evaluated at once equal eq. 167 summed term by term,
    /// and cos^n by squaring equals powf (checked by dropping a target from `mixture_pdfs`:
    /// fails).
    #[test]
    fn mixture_pdfs_equal_the_mixture_per_strength() {
        let targets = [
            Target { point: vec3(1.0, 2.0, 0.5), probability: 0.25, cumulative: 0.25 },
            Target { point: vec3(-1.0, 1.0, 0.0), probability: 0.5, cumulative: 0.75 },
            Target { point: vec3(0.2, 3.0, -0.4), probability: 0.25, cumulative: 1.0 },
        ];
        let (x, normal) = (vec3(0.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0));
        let strengths = [1.0, 4.0, 16.0, 64.0, 2.5, 0.0];
        for wo in [vec3(0.3, 0.9, 0.1), vec3(-0.6, 0.7, 0.2), vec3(0.0, -1.0, 0.0)] {
            let wo = wo.normalize();
            let all = mixture_pdfs(&targets, &strengths, x, normal, wo);
            for (k, &s) in strengths.iter().enumerate() {
                // Eq. 167 term by term: each target's lobe (eq. 163) around its own axis.
                let one: f32 =
                    targets.iter().map(|t| t.probability * lobe_pdf(s, (t.point - x).normalize().dot(wo))).sum();
                assert_eq!(mixture_pdf(&targets, s, x, normal, wo), all[k], "one strength alone, or all at once");
                assert!((all[k] - one).abs() <= 1e-6 * one.max(1.0), "strength {s}: {} against {one}", all[k]);
            }
        }
        for n in [0u32, 1, 2, 7, 8, 64, 1000] {
            let (by_squaring, powf) = (crate::sampling::powi_by_squaring(0.93, n), 0.93f32.powf(n as f32));
            assert!((by_squaring - powf).abs() <= 1e-5 * powf.max(1e-30), "0.93^{n}: {by_squaring} against {powf}");
        }
    }
}
