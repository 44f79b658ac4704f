//! Bounding volume hierarchy: binned-SAH build (parallel over subtrees), flat 32-byte nodes
//! with the two children of a node side by side in one 64-byte cache line,
//! triangles stored in leaf order so a leaf is one contiguous read.

use super::{intersect_triangle, Accelerator, BuildTriangle, Hit, HitFilter, Ray, RayPrecomp};
use crate::math::{Aabb, Vec3};

const BINS: usize = 16;
const MAX_LEAF: usize = 8;
const TRAVERSAL_COST: f32 = 1.0;
const PARALLEL_THRESHOLD: usize = 4096;
const MASKED_BIT: u32 = 1 << 31;

#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct Node {
    min: Vec3,
    /// Interior: index of the first child (the second is `offset + 1`). Leaf: first triangle.
    offset: u32,
    max: Vec3,
    /// Number of triangles; 0 for interior nodes.
    count: u32,
}

/// Shape of a built hierarchy, for benchmarks and tests.
#[derive(Clone, Copy, Debug, Default)]
pub struct BvhStats {
    pub nodes: usize,
    pub leaves: usize,
    pub max_depth: usize,
    pub sah_cost: f32,
}

pub struct Bvh {
    /// Node pairs, 64-byte aligned: node i is `nodes[i / 2].0[i % 2]`. The root is node 0
    /// (its partner, node 1, is unused) so that every sibling pair starts a cache line.
    nodes: Vec<NodePair>,
    tris: Vec<[Vec3; 3]>,
    /// Global triangle index per leaf slot; the top bit marks alpha-masked triangles.
    prim_ids: Vec<u32>,
    bounds: Aabb,
}

#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct NodePair([Node; 2]);

const EMPTY_NODE: Node = Node { min: Vec3::ZERO, offset: 0, max: Vec3::ZERO, count: 0 };

impl Bvh {
    #[inline(always)]
    fn node(&self, i: usize) -> &Node {
        &self.nodes[i >> 1].0[i & 1]
    }
}

enum BuildNode {
    Leaf { bounds: Aabb, start: usize, count: usize },
    Interior { bounds: Aabb, children: Box<[BuildNode; 2]> },
}

#[derive(Clone, Copy)]
struct PrimRef {
    bounds: Aabb,
    centroid: Vec3,
    index: u32,
}

impl Bvh {
    pub fn build(triangles: &[BuildTriangle]) -> Bvh {
        let mut refs: Vec<PrimRef> = triangles
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let b = t.bounds();
                PrimRef { bounds: b, centroid: b.center(), index: i as u32 }
            })
            .collect();
        let root = if refs.is_empty() {
            BuildNode::Leaf { bounds: Aabb::EMPTY, start: 0, count: 0 }
        } else {
            build_recursive(&mut refs, 0)
        };
        let mut flat = vec![EMPTY_NODE, EMPTY_NODE];
        flat[0] = leaf_or_placeholder(&root);
        flatten_children(&root, 0, &mut flat);
        let nodes = flat.chunks(2).map(|c| NodePair([c[0], *c.get(1).unwrap_or(&EMPTY_NODE)])).collect();
        let tris = refs.iter().map(|r| triangles[r.index as usize].v).collect();
        let prim_ids =
            refs.iter().map(|r| r.index | if triangles[r.index as usize].masked { MASKED_BIT } else { 0 }).collect();
        let bounds = match &root {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => *bounds,
        };
        Bvh { nodes, tris, prim_ids, bounds }
    }

    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats { nodes: 2 * self.nodes.len() - 1, ..Default::default() };
        let root_area = self.bounds.half_area().max(1e-30);
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, depth)) = stack.pop() {
            let n = self.node(i);
            let area = Aabb { min: n.min, max: n.max }.half_area() / root_area;
            s.max_depth = s.max_depth.max(depth);
            if n.count > 0 {
                s.leaves += 1;
                s.sah_cost += area * n.count as f32;
            } else {
                s.sah_cost += area * TRAVERSAL_COST;
                stack.push((n.offset as usize, depth + 1));
                stack.push((n.offset as usize + 1, depth + 1));
            }
        }
        s
    }

    #[inline]
    fn traverse<const ANY: bool>(&self, ray: &Ray, filter: &dyn HitFilter) -> Option<Hit> {
        if self.tris.is_empty() {
            return None;
        }
        let pre = RayPrecomp::new(ray);
        let mut best: Option<Hit> = None;
        let mut tmax = ray.tmax;
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut node_index = 0usize;
        slab(self.node(0), ray.o, pre.inv_d, tmax)?;
        loop {
            let node = self.node(node_index);
            if node.count > 0 {
                let start = node.offset as usize;
                for i in start..start + node.count as usize {
                    if let Some((t, b1, b2)) = intersect_triangle(ray, &pre, &self.tris[i], tmax) {
                        let id = self.prim_ids[i];
                        let prim = id & !MASKED_BIT;
                        if id & MASKED_BIT != 0 && !filter.accept(ray, prim, b1, b2) {
                            continue;
                        }
                        let hit = Hit { t, prim, b1, b2 };
                        if ANY {
                            return Some(hit);
                        }
                        tmax = t;
                        best = Some(hit);
                    }
                }
            } else {
                let a = node.offset as usize;
                let b = a + 1;
                let ta = slab(self.node(a), ray.o, pre.inv_d, tmax);
                let tb = slab(self.node(b), ray.o, pre.inv_d, tmax);
                match (ta, tb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far) = if ta <= tb { (a, b) } else { (b, a) };
                        if sp < stack.len() {
                            stack[sp] = far as u32;
                            sp += 1;
                        }
                        node_index = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node_index = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        node_index = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            node_index = stack[sp] as usize;
        }
        best
    }
}

impl Accelerator for Bvh {
    fn intersect(&self, ray: &Ray, filter: &dyn HitFilter) -> Option<Hit> {
        self.traverse::<false>(ray, filter)
    }
    fn occluded(&self, ray: &Ray, filter: &dyn HitFilter) -> bool {
        self.traverse::<true>(ray, filter).is_some()
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
}

#[inline(always)]
fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// Entry distance of the ray into the node's box, if it enters before `tmax`.
/// `inv_d` is finite (see `RayPrecomp`), so no operand here is NaN.
#[inline(always)]
fn slab(n: &Node, o: Vec3, inv_d: Vec3, tmax: f32) -> Option<f32> {
    let tx1 = (n.min.x - o.x) * inv_d.x;
    let tx2 = (n.max.x - o.x) * inv_d.x;
    let ty1 = (n.min.y - o.y) * inv_d.y;
    let ty2 = (n.max.y - o.y) * inv_d.y;
    let tz1 = (n.min.z - o.z) * inv_d.z;
    let tz2 = (n.max.z - o.z) * inv_d.z;
    let tnear = fmax(fmax(fmax(fmin(tx1, tx2), fmin(ty1, ty2)), fmin(tz1, tz2)), 0.0);
    let tfar = fmin(fmin(fmin(fmax(tx1, tx2), fmax(ty1, ty2)), fmax(tz1, tz2)), tmax);
    // Widen by a few ulps so that flat boxes (axis-aligned walls) are not missed.
    if tnear <= tfar * 1.000_000_4 {
        Some(tnear)
    } else {
        None
    }
}

fn bounds_of(refs: &[PrimRef]) -> (Aabb, Aabb) {
    let mut b = Aabb::EMPTY;
    let mut c = Aabb::EMPTY;
    for r in refs {
        b = b.union(r.bounds);
        c.grow(r.centroid);
    }
    (b, c)
}

fn build_recursive(refs: &mut [PrimRef], start: usize) -> BuildNode {
    let (bounds, cbounds) = bounds_of(refs);
    let n = refs.len();
    let leaf = BuildNode::Leaf { bounds, start, count: n };
    if n <= 2 {
        return leaf;
    }
    let Some((axis, split_bin, cost)) = best_split(refs, &bounds, &cbounds) else {
        return if n <= MAX_LEAF { leaf } else { median_split(refs, start, bounds, &cbounds) };
    };
    if cost >= n as f32 && n <= MAX_LEAF {
        return leaf;
    }
    let lo = cbounds.min[axis];
    let scale = BINS as f32 / (cbounds.max[axis] - lo);
    let mid = partition(refs, |r| bin_of(r.centroid[axis], lo, scale) <= split_bin);
    if mid == 0 || mid == n {
        return median_split(refs, start, bounds, &cbounds);
    }
    split_at(refs, mid, start, bounds)
}

fn split_at(refs: &mut [PrimRef], mid: usize, start: usize, bounds: Aabb) -> BuildNode {
    let n = refs.len();
    let (left, right) = refs.split_at_mut(mid);
    let (l, r) = if n > PARALLEL_THRESHOLD {
        rayon::join(|| build_recursive(left, start), || build_recursive(right, start + mid))
    } else {
        (build_recursive(left, start), build_recursive(right, start + mid))
    };
    BuildNode::Interior { bounds, children: Box::new([l, r]) }
}

fn median_split(refs: &mut [PrimRef], start: usize, bounds: Aabb, cbounds: &Aabb) -> BuildNode {
    let axis = cbounds.extent().max_axis();
    let mid = refs.len() / 2;
    refs.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
    split_at(refs, mid, start, bounds)
}

#[inline]
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// Best (axis, last bin of the left side, SAH cost in triangle-test units) over all axes.
fn best_split(refs: &[PrimRef], bounds: &Aabb, cbounds: &Aabb) -> Option<(usize, usize, f32)> {
    let parent_area = bounds.half_area();
    let mut best: Option<(usize, usize, f32)> = None;
    for axis in 0..3 {
        let lo = cbounds.min[axis];
        let extent = cbounds.max[axis] - lo;
        if !(extent > 0.0) {
            continue;
        }
        let scale = BINS as f32 / extent;
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_counts = [0usize; BINS];
        for r in refs {
            let b = bin_of(r.centroid[axis], lo, scale);
            bin_bounds[b] = bin_bounds[b].union(r.bounds);
            bin_counts[b] += 1;
        }
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for i in (1..BINS).rev() {
            acc = acc.union(bin_bounds[i]);
            cnt += bin_counts[i];
            right_area[i] = acc.half_area();
            right_count[i] = cnt;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for i in 0..BINS - 1 {
            acc = acc.union(bin_bounds[i]);
            cnt += bin_counts[i];
            if cnt == 0 || right_count[i + 1] == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (acc.half_area() * cnt as f32 + right_area[i + 1] * right_count[i + 1] as f32)
                    / parent_area.max(1e-30);
            if best.is_none_or(|b| cost < b.2) {
                best = Some((axis, i, cost));
            }
        }
    }
    best
}

fn partition(refs: &mut [PrimRef], pred: impl Fn(&PrimRef) -> bool) -> usize {
    let mut i = 0;
    for j in 0..refs.len() {
        if pred(&refs[j]) {
            refs.swap(i, j);
            i += 1;
        }
    }
    i
}

/// The flat node for `node`: complete for leaves; interior nodes get their child offset
/// from `flatten_children`.
fn leaf_or_placeholder(node: &BuildNode) -> Node {
    match node {
        BuildNode::Leaf { bounds, start, count } => {
            Node { min: bounds.min, offset: *start as u32, max: bounds.max, count: *count as u32 }
        }
        BuildNode::Interior { bounds, .. } => Node { min: bounds.min, offset: 0, max: bounds.max, count: 0 },
    }
}

/// Writes the children of the interior node at `index` as an adjacent pair, depth first.
fn flatten_children(node: &BuildNode, index: usize, out: &mut Vec<Node>) {
    let BuildNode::Interior { children, .. } = node else { return };
    let first = out.len();
    out.push(leaf_or_placeholder(&children[0]));
    out.push(leaf_or_placeholder(&children[1]));
    out[index].offset = first as u32;
    flatten_children(&children[0], first, out);
    flatten_children(&children[1], first + 1, out);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::NoFilter;
    use crate::math::vec3;
    use crate::sampling::{uniform_sphere, Rng};

    fn random_soup(n: usize, rng: &mut Rng) -> Vec<BuildTriangle> {
        (0..n)
            .map(|_| {
                let c = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                let v = [0, 1, 2].map(|_| c + vec3(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5));
                BuildTriangle { v, masked: false }
            })
            .collect()
    }

    /// The BVH must find exactly what testing every triangle finds.
    #[test]
    fn matches_brute_force() {
        let mut rng = Rng::new(5, 0, 0);
        let tris = random_soup(5000, &mut rng);
        let bvh = Bvh::build(&tris);
        let stats = bvh.stats();
        assert!(stats.leaves > 100 && stats.max_depth < 64);
        for _ in 0..2000 {
            let o = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 12.0 - Vec3::splat(1.0);
            let ray = Ray::new(o, uniform_sphere(rng.next_2d()));
            let pre = RayPrecomp::new(&ray);
            let brute = tris
                .iter()
                .enumerate()
                .filter_map(|(i, t)| intersect_triangle(&ray, &pre, &t.v, f32::INFINITY).map(|h| (h.0, i)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let hit = bvh.intersect(&ray, &NoFilter);
            match (brute, hit) {
                (None, None) => {}
                (Some((t, i)), Some(h)) => {
                    assert!((t - h.t).abs() <= 1e-5 * t.max(1.0), "t {t} vs {}", h.t);
                    assert!(h.prim as usize == i || (t - h.t).abs() < 1e-6);
                }
                other => panic!("mismatch {other:?}"),
            }
            assert_eq!(bvh.occluded(&ray, &NoFilter), brute.is_some());
        }
    }

    #[test]
    fn empty_bvh_hits_nothing() {
        let bvh = Bvh::build(&[]);
        let ray = Ray::new(Vec3::ZERO, vec3(0.0, 0.0, 1.0));
        assert!(bvh.intersect(&ray, &NoFilter).is_none());
    }
}
