//! The GPU's BVH: a binary tree built by the surface-area heuristic, and its two layouts, one
//! per traversal kernel (`SKELIGHT_GPU_TRAVERSAL`, launch.rs):
//! - stackless (`traverse_stackless.wgsl`): one box per 48-byte [`Node`], depth-first with
//!   a miss link per node, children visited in a fixed order;
//! - ordered (`traverse_ordered.wgsl`): one [`PairNode`] per inner node holding both
//!   children's boxes (Aila and Laine 2009's layout), the nearer child first and the farther
//!   on a stack of [`MAX_DEPTH`] entries, popped only while its box begins before the closest
//!   hit so far.
//!
//! Both are mirrored here on the CPU ([`reference_traverse`]), counting the work a ray costs,
//! so that the kernels' correctness and their work per ray are checked without a GPU.

use bytemuck::{Pod, Zeroable};
use skelight::geometry::{intersect_triangle, Ray, RayPrecomp};
use skelight::math::vec3;

use crate::flatten::{Tri, NONE};

/// One box of the stackless layout: a leaf (`count` triangles from `first`) or an inner node
/// (count 0) whose left child follows it and whose right child is its left child's `miss`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug)]
pub struct Node {
    pub lo: [f32; 3],
    pub first: u32,
    pub hi: [f32; 3],
    pub count: u32,
    /// The next node when this one is missed or done (NONE: the end).
    pub miss: u32,
    pub pad: [u32; 3],
}

/// An inner node of the ordered layout: both children's boxes, each child an inner node
/// (`count` 0, `index` a [`PairNode`]) or a leaf (`count` = [`LEAF`] | triangles, `index`
/// its first triangle; a leaf of no triangles stands for a missing child). 64 bytes, one
/// fetch tests two boxes.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug)]
pub struct PairNode {
    pub lo_a: [f32; 3],
    pub index_a: u32,
    pub hi_a: [f32; 3],
    pub count_a: u32,
    pub lo_b: [f32; 3],
    pub index_b: u32,
    pub hi_b: [f32; 3],
    pub count_b: u32,
}

/// The leaf flag of [`PairNode`]'s counts.
pub const LEAF: u32 = 1 << 31;

/// The tree's depth bound (levels, the root's included): deeper subtrees become one leaf. It
/// bounds the ordered traversal's stack (`STACK` in traverse_ordered.wgsl: an inner node at
/// depth d has at most d entries below it, so at most MAX_DEPTH - 1 are ever held), so no
/// scene can overflow it. The scenes measured stay well inside (depth test below).
pub const MAX_DEPTH: usize = 32;

/// How the kernels find a ray's hit (chosen by measurement: docs/benchmarks.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Traversal {
    Stackless,
    Ordered,
    /// Closest hits ordered, any hits (shadow rays, which stop at the first hit and gain
    /// nothing from the order) stackless; the device holds both layouts.
    Hybrid,
}

impl Traversal {
    pub const ALL: [Traversal; 3] = [Traversal::Stackless, Traversal::Ordered, Traversal::Hybrid];

    pub fn name(self) -> &'static str {
        match self {
            Traversal::Stackless => "stackless",
            Traversal::Ordered => "ordered",
            Traversal::Hybrid => "hybrid",
        }
    }

    pub fn from_name(name: &str) -> Option<Traversal> {
        Traversal::ALL.into_iter().find(|t| t.name() == name)
    }

    /// The nodes the kernels read, as 16-byte words, and the word where the ordered layout's
    /// begin among them (the kernels' PAIR_ROOT).
    pub fn device_nodes(self, nodes: &[Node]) -> (Vec<[f32; 4]>, u32) {
        let words = |b: &[u8]| bytemuck::cast_slice::<u8, [f32; 4]>(b).to_vec();
        let stackless = || words(bytemuck::cast_slice(nodes));
        let ordered = || words(bytemuck::cast_slice(&pair_nodes(nodes)));
        match self {
            Traversal::Stackless => (stackless(), 0),
            Traversal::Ordered => (ordered(), 0),
            Traversal::Hybrid => {
                let mut all = stackless();
                let root = all.len() as u32;
                all.extend(ordered());
                (all, root)
            }
        }
    }

    /// The WGSL `traverse` the kernels call.
    pub fn dispatcher(self) -> &'static str {
        match self {
            Traversal::Stackless => {
                "fn traverse(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, first_hit: bool) -> Hit {\n    \
                 return traverse_stackless(o, d, t_min, t_max, first_hit);\n}\n"
            }
            Traversal::Ordered => {
                "fn traverse(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, first_hit: bool) -> Hit {\n    \
                 return traverse_ordered(o, d, t_min, t_max, first_hit);\n}\n"
            }
            Traversal::Hybrid => {
                "fn traverse(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, first_hit: bool) -> Hit {\n    \
                 if (first_hit) {\n        return traverse_stackless(o, d, t_min, t_max, true);\n    }\n    \
                 return traverse_ordered(o, d, t_min, t_max, false);\n}\n"
            }
        }
    }
}

/// Bins per axis of the surface-area heuristic's split search.
const SAH_BINS: usize = 16;

/// A binary BVH over `tris` (leaves of at most 4 triangles, or more at depth
/// [`MAX_DEPTH`] - 1), each split the best of
/// [`SAH_BINS`] planes per axis by the surface-area heuristic (binned, as Wald 2007), or the
/// median along the longest axis where all centroids share one bin; flattened depth-first: a
/// node's left child follows it, and `miss` is the node after its subtree. Returns the nodes
/// and the triangle order. On an H200 the SAH tree traced incoherent rays 2.2–2.5× faster
/// than median splits alone (the first version) and doubled pt and ibpt (docs/benchmarks.md).
pub(crate) fn build_bvh(tris: &[Tri]) -> (Vec<Node>, Vec<u32>) {
    build_bvh_within(tris, MAX_DEPTH)
}

/// [`build_bvh`] with at most `max_depth` levels.
fn build_bvh_within(tris: &[Tri], max_depth: usize) -> (Vec<Node>, Vec<u32>) {
    let centroid = |t: &Tri| [0, 1, 2].map(|k| (t.v0[k] + t.v1[k] + t.v2[k]) / 3.0);
    let mut order: Vec<u32> = (0..tris.len() as u32).collect();
    let mut nodes = Vec::new();
    fn bounds(tris: &[Tri], ids: &[u32]) -> ([f32; 3], [f32; 3]) {
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for &i in ids {
            let t = &tris[i as usize];
            for v in [t.v0, t.v1, t.v2] {
                for k in 0..3 {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
        }
        (lo, hi)
    }
    fn build(
        tris: &[Tri],
        ids: &mut [u32],
        first: u32,
        levels_left: usize,
        nodes: &mut Vec<Node>,
        centroid: &dyn Fn(&Tri) -> [f32; 3],
    ) {
        let (lo, hi) = bounds(tris, ids);
        let me = nodes.len();
        nodes.push(Node { lo, hi, first: 0, count: 0, miss: NONE, pad: [0; 3] });
        if ids.len() <= 4 || levels_left <= 1 {
            nodes[me].first = first;
            nodes[me].count = ids.len() as u32;
            return;
        }
        let (mut clo, mut chi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for &i in ids.iter() {
            let c = centroid(&tris[i as usize]);
            for k in 0..3 {
                clo[k] = clo[k].min(c[k]);
                chi[k] = chi[k].max(c[k]);
            }
        }
        // Partition in place by the SAH's plane (centroids below it first), unless rounding
        // at the plane left one side empty.
        let sah = sah_split(tris, ids, clo, chi, centroid).map(|(axis, plane)| {
            let mut m = 0;
            for k in 0..ids.len() {
                if centroid(&tris[ids[k] as usize])[axis] < plane {
                    ids.swap(k, m);
                    m += 1;
                }
            }
            m
        });
        let mid = match sah.filter(|&m| m > 0 && m < ids.len()) {
            Some(m) => m,
            None => {
                let axis = (0..3).max_by(|&a, &b| (chi[a] - clo[a]).total_cmp(&(chi[b] - clo[b]))).unwrap_or(0);
                let mid = ids.len() / 2;
                ids.select_nth_unstable_by(mid, |&a, &b| {
                    centroid(&tris[a as usize])[axis].total_cmp(&centroid(&tris[b as usize])[axis])
                });
                mid
            }
        };
        let (left, right) = ids.split_at_mut(mid);
        build(tris, left, first, levels_left - 1, nodes, centroid);
        // The left subtree's nodes that end it (its root and the last node of every right
        // spine) continue with the right child; the right subtree's keep NONE until an
        // ancestor links them (the whole tree's end stays NONE).
        let right_start = nodes.len();
        link(nodes, me + 1, right_start as u32);
        build(tris, right, first + mid as u32, levels_left - 1, nodes, centroid);
    }
    /// The cheapest SAH plane (axis, position) over the bin boundaries of the centroids' box
    /// `clo`–`chi`, leaving triangles on both sides; `None` where no plane does.
    fn sah_split(
        tris: &[Tri],
        ids: &[u32],
        clo: [f32; 3],
        chi: [f32; 3],
        centroid: &dyn Fn(&Tri) -> [f32; 3],
    ) -> Option<(usize, f32)> {
        let area = |lo: [f32; 3], hi: [f32; 3]| {
            let e = [0, 1, 2].map(|k| (hi[k] - lo[k]).max(0.0));
            e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
        };
        let grow = |b: &mut ([f32; 3], [f32; 3]), o: &([f32; 3], [f32; 3])| {
            for k in 0..3 {
                b.0[k] = b.0[k].min(o.0[k]);
                b.1[k] = b.1[k].max(o.1[k]);
            }
        };
        let empty = ([f32::MAX; 3], [f32::MIN; 3]);
        let extent = [0, 1, 2].map(|k| chi[k] - clo[k]);
        let usable = extent.map(|e| e > 0.0 && e.is_finite());
        // One pass over the triangles bins each into the three axes' bins (its box and
        // centroid computed once).
        let mut counts = [[0usize; SAH_BINS]; 3];
        let mut boxes = [[empty; SAH_BINS]; 3];
        for &i in ids {
            let (c, b) = (centroid(&tris[i as usize]), bounds(tris, &[i]));
            for axis in (0..3).filter(|&a| usable[a]) {
                let bin = (((c[axis] - clo[axis]) / extent[axis] * SAH_BINS as f32) as usize).min(SAH_BINS - 1);
                counts[axis][bin] += 1;
                grow(&mut boxes[axis][bin], &b);
            }
        }
        let mut best: Option<(f32, usize, f32)> = None;
        for axis in (0..3).filter(|&a| usable[a]) {
            let (counts, boxes, extent) = (&counts[axis], &boxes[axis], extent[axis]);
            // Right-to-left sweep: the cost of the right side of each plane.
            let mut right_cost = [0f32; SAH_BINS];
            let (mut acc, mut n) = (empty, 0usize);
            for b in (1..SAH_BINS).rev() {
                grow(&mut acc, &boxes[b]);
                n += counts[b];
                right_cost[b] = if n > 0 { area(acc.0, acc.1) * n as f32 } else { 0.0 };
            }
            let (mut acc, mut n) = (empty, 0usize);
            for b in 1..SAH_BINS {
                grow(&mut acc, &boxes[b - 1]);
                n += counts[b - 1];
                if n == 0 || n == ids.len() {
                    continue;
                }
                let cost = area(acc.0, acc.1) * n as f32 + right_cost[b];
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, clo[axis] + extent * b as f32 / SAH_BINS as f32));
                }
            }
        }
        best.map(|(_, axis, plane)| (axis, plane))
    }
    /// Sets the miss link of the subtree rooted at `root` to `next`: the root's, and that
    /// of every node whose miss pointed past the subtree (NONE while building).
    fn link(nodes: &mut [Node], root: usize, next: u32) {
        let end = nodes.len();
        for n in &mut nodes[root..end] {
            if n.miss == NONE {
                n.miss = next;
            }
        }
    }
    build(tris, &mut order, 0, max_depth, &mut nodes, &centroid);
    (nodes, order)
}

/// The ordered layout of a stackless tree: its inner nodes in the same depth-first order,
/// each holding its two children (the left follows it, the right is the left's miss link).
/// A tree that is one leaf gets a root whose second child is a missing one.
pub fn pair_nodes(nodes: &[Node]) -> Vec<PairNode> {
    let mut index = vec![NONE; nodes.len()];
    let mut inner = 0u32;
    for (i, n) in nodes.iter().enumerate() {
        if n.count == 0 && i + 1 < nodes.len() {
            index[i] = inner;
            inner += 1;
        }
    }
    let child = |i: usize| -> ([f32; 3], [f32; 3], u32, u32) {
        let n = &nodes[i];
        if index[i] == NONE {
            (n.lo, n.hi, n.first, LEAF | n.count)
        } else {
            (n.lo, n.hi, index[i], 0)
        }
    };
    let pair = |a: ([f32; 3], [f32; 3], u32, u32), b: ([f32; 3], [f32; 3], u32, u32)| PairNode {
        lo_a: a.0,
        index_a: a.2,
        hi_a: a.1,
        count_a: a.3,
        lo_b: b.0,
        index_b: b.2,
        hi_b: b.1,
        count_b: b.3,
    };
    if inner == 0 {
        let missing = ([0.0; 3], [0.0; 3], 0, LEAF);
        return vec![pair(nodes.first().map_or(missing, |_| child(0)), missing)];
    }
    (0..nodes.len())
        .filter(|&i| index[i] != NONE)
        .map(|i| pair(child(i + 1), child(nodes[i + 1].miss as usize)))
        .collect()
}

/// What a ray cost a traversal: nodes fetched (48 bytes each stackless, 64 ordered), boxes
/// and triangles (48 bytes each) tested.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    pub fetches: u64,
    pub boxes: u64,
    pub triangles: u64,
}

impl std::ops::AddAssign for Work {
    fn add_assign(&mut self, o: Work) {
        self.fetches += o.fetches;
        self.boxes += o.boxes;
        self.triangles += o.triangles;
    }
}

/// The slab test of the kernels' `slab`: the entry and exit distances, clipped to [0, t_max]
/// (a hit when entry <= exit).
fn slab(lo: [f32; 3], hi: [f32; 3], o: [f32; 3], inv_d: [f32; 3], t_max: f32) -> (f32, f32) {
    let (mut t0, mut t1) = (0.0f32, t_max);
    for k in 0..3 {
        let (a, b) = ((lo[k] - o[k]) * inv_d[k], (hi[k] - o[k]) * inv_d[k]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0, t1)
}

/// The CPU's mirror of a traversal kernel: the closest hit (t, triangle) before `t_max` of a
/// ray through `tris` (in the tree's order), and the work it took. `stackless` and `pairs`
/// are the two layouts of one tree.
pub fn reference_traverse(
    traversal: Traversal,
    stackless: &[Node],
    pairs: &[PairNode],
    tris: &[Tri],
    o: [f32; 3],
    d: [f32; 3],
    t_max: f32,
) -> (Option<(f32, u32)>, Work) {
    let ray = Ray::new(vec3(o[0], o[1], o[2]), vec3(d[0], d[1], d[2]));
    let pre = RayPrecomp::new(&ray);
    let inv_d = [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]];
    let mut work = Work::default();
    let mut best: Option<(f32, u32)> = None;
    let leaf = |first: u32, count: u32, best: &mut Option<(f32, u32)>, work: &mut Work| {
        for k in first..first + count {
            work.triangles += 1;
            let t = &tris[k as usize];
            let v = [t.v0, t.v1, t.v2].map(|p| vec3(p[0], p[1], p[2]));
            let limit = best.map_or(t_max, |b| b.0);
            if let Some((h, _, _)) = intersect_triangle(&ray, &pre, &v, limit) {
                *best = Some((h, k));
            }
        }
    };
    let limit = |best: &Option<(f32, u32)>| best.map_or(t_max, |b| b.0);
    // The mirror follows closest-hit rays, which the hybrid traversal orders.
    match traversal {
        Traversal::Stackless => {
            let mut i = if stackless.is_empty() { NONE } else { 0 };
            while i != NONE {
                let n = &stackless[i as usize];
                work.fetches += 1;
                work.boxes += 1;
                let (t0, t1) = slab(n.lo, n.hi, o, inv_d, limit(&best));
                if t0 > t1 {
                    i = n.miss;
                } else if n.count == 0 {
                    i += 1;
                } else {
                    leaf(n.first, n.count, &mut best, &mut work);
                    i = n.miss;
                }
            }
        }
        Traversal::Ordered | Traversal::Hybrid => {
            let mut stack: Vec<(u32, f32)> = Vec::with_capacity(MAX_DEPTH);
            let mut i = 0u32;
            loop {
                let n = &pairs[i as usize];
                work.fetches += 1;
                work.boxes += 2;
                let ea = slab(n.lo_a, n.hi_a, o, inv_d, limit(&best));
                let eb = slab(n.lo_b, n.hi_b, o, inv_d, limit(&best));
                let (mut a, mut b) = (ea.0 <= ea.1, eb.0 <= eb.1);
                if a && n.count_a & LEAF != 0 {
                    leaf(n.index_a, n.count_a & !LEAF, &mut best, &mut work);
                    a = false;
                }
                if b && n.count_b & LEAF != 0 {
                    leaf(n.index_b, n.count_b & !LEAF, &mut best, &mut work);
                    b = false;
                }
                a = a && ea.0 <= limit(&best);
                b = b && eb.0 <= limit(&best);
                if a && b {
                    let (near, far) =
                        if ea.0 <= eb.0 { (n.index_a, (n.index_b, eb.0)) } else { (n.index_b, (n.index_a, ea.0)) };
                    stack.push(far);
                    assert!(stack.len() < MAX_DEPTH, "the ordered traversal's stack overflowed");
                    i = near;
                } else if a {
                    i = n.index_a;
                } else if b {
                    i = n.index_b;
                } else {
                    // Entries whose box begins past the closest hit found since are dropped.
                    loop {
                        match stack.pop() {
                            None => return (best, work),
                            Some((next, entry)) if entry <= limit(&best) => {
                                i = next;
                                break;
                            }
                            Some(_) => {}
                        }
                    }
                }
            }
        }
    }
    (best, work)
}

/// The tree's depth: levels from the root to its deepest leaf, both counted.
pub fn tree_depth(nodes: &[Node]) -> usize {
    let mut deepest = 0;
    let mut todo = if nodes.is_empty() { vec![] } else { vec![(0usize, 1usize)] };
    while let Some((i, d)) = todo.pop() {
        deepest = deepest.max(d);
        if nodes[i].count == 0 && i + 1 < nodes.len() {
            todo.push((i + 1, d + 1));
            todo.push((nodes[i + 1].miss as usize, d + 1));
        }
    }
    deepest
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stackless traversal visits every leaf once, in depth-first order.
    #[test]
    fn miss_links_walk_every_leaf_once() {
        let tris: Vec<Tri> = (0..37)
            .map(|i| {
                let x = (i * 7 % 13) as f32;
                let y = (i * 5 % 11) as f32;
                Tri {
                    v0: [x, y, 0.0],
                    v1: [x + 1.0, y, 0.0],
                    v2: [x, y + 1.0, 0.0],
                    material: 0,
                    emitter: NONE,
                    flags: 0,
                }
            })
            .collect();
        let (nodes, order) = build_bvh(&tris);
        let mut seen = vec![0; tris.len()];
        let mut i = 0u32;
        while i != NONE {
            let n = nodes[i as usize];
            if n.count > 0 {
                for k in n.first..n.first + n.count {
                    seen[order[k as usize] as usize] += 1;
                }
                i = n.miss;
            } else {
                i += 1;
            }
        }
        assert!(seen.iter().all(|&c| c == 1), "{seen:?}");
        assert_eq!(nodes[0].miss, NONE);
    }

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Tri {
        Tri { v0: a, v1: b, v2: c, material: 0, emitter: NONE, flags: 0 }
    }

    /// A soup of overlapping triangles of many sizes (a numbers-only stand-in for a scene:
    /// deterministic, no files).
    fn soup(n: usize) -> Vec<Tri> {
        let mut s = 0x9e3779b9u32;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        };
        (0..n)
            .map(|_| {
                let c = [rnd() * 10.0, rnd() * 10.0, rnd() * 10.0];
                let size = 0.3 + 3.0 * rnd() * rnd();
                let mut corner = || [0, 1, 2].map(|k| c[k] + size * (rnd() - 0.5));
                tri(corner(), corner(), corner())
            })
            .collect()
    }

    /// Both kernels' traversals, mirrored on the CPU, find the closest hit that testing every
    /// triangle finds (same t, hits and misses alike) for rays from inside and outside the
    /// soup, with and without a t_max that cuts them short.
    #[test]
    fn both_traversals_find_the_closest_hit() {
        let soup = soup(3000);
        let (nodes, order) = build_bvh(&soup);
        let tris: Vec<Tri> = order.iter().map(|&i| soup[i as usize]).collect();
        let pairs = pair_nodes(&nodes);
        let mut s = 7u32;
        let mut rnd = move || {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            (s >> 8) as f32 / 16777216.0
        };
        let (mut hits, mut work) = (0, [Work::default(); 2]);
        for i in 0..2000 {
            let o = [rnd() * 14.0 - 2.0, rnd() * 14.0 - 2.0, rnd() * 14.0 - 2.0];
            let (z, phi) = (1.0 - 2.0 * rnd(), std::f32::consts::TAU * rnd());
            let r = (1.0 - z * z).max(0.0).sqrt();
            let d = [r * phi.cos(), r * phi.sin(), z];
            let t_max = if i % 3 == 0 { 1.5 } else { f32::MAX };
            let ray = Ray::new(vec3(o[0], o[1], o[2]), vec3(d[0], d[1], d[2]));
            let pre = RayPrecomp::new(&ray);
            let mut truth: Option<f32> = None;
            for t in &tris {
                let v = [t.v0, t.v1, t.v2].map(|p| vec3(p[0], p[1], p[2]));
                if let Some((h, _, _)) = intersect_triangle(&ray, &pre, &v, truth.unwrap_or(t_max)) {
                    truth = Some(h);
                }
            }
            hits += truth.is_some() as usize;
            for (k, traversal) in [Traversal::Stackless, Traversal::Ordered].into_iter().enumerate() {
                let (found, w) = reference_traverse(traversal, &nodes, &pairs, &tris, o, d, t_max);
                assert_eq!(found.map(|f| f.0), truth, "{traversal:?}, ray {i}");
                work[k] += w;
            }
        }
        println!("{hits} of 2000 rays hit; stackless {:?}, ordered {:?}", work[0], work[1]);
        assert!(hits > 500 && hits < 2000, "the rays test both hits and misses: {hits}");
    }

    /// The depth bound holds (deeper subtrees become one leaf, so the ordered traversal's
    /// stack cannot overflow) and both traversals still find every closest hit in a tree cut
    /// short. The soup's own tree is deeper than the bound tried here.
    #[test]
    fn the_tree_depth_is_bounded() {
        let soup = soup(3000);
        let free = tree_depth(&build_bvh_within(&soup, usize::MAX).0);
        let (nodes, order) = build_bvh_within(&soup, 8);
        let depth = tree_depth(&nodes);
        println!("depth {free} unbounded, {depth} within 8");
        assert!(depth <= 8 && free > 8, "depth {depth}, unbounded {free}");
        let tris: Vec<Tri> = order.iter().map(|&i| soup[i as usize]).collect();
        let pairs = pair_nodes(&nodes);
        for (k, t) in tris.iter().enumerate().step_by(97) {
            // A ray down onto the triangle's centroid from above the soup.
            let c = [0, 1, 2].map(|a| (t.v0[a] + t.v1[a] + t.v2[a]) / 3.0);
            let o = [c[0], c[1], 20.0];
            for traversal in [Traversal::Stackless, Traversal::Ordered] {
                let (hit, _) = reference_traverse(traversal, &nodes, &pairs, &tris, o, [0.0, 0.0, -1.0], f32::MAX);
                let truth = (0..tris.len())
                    .filter_map(|j| {
                        let ray = Ray::new(vec3(o[0], o[1], o[2]), vec3(0.0, 0.0, -1.0));
                        let u = &tris[j];
                        let v = [u.v0, u.v1, u.v2].map(|p| vec3(p[0], p[1], p[2]));
                        intersect_triangle(&ray, &RayPrecomp::new(&ray), &v, f32::MAX).map(|h| h.0)
                    })
                    .min_by(f32::total_cmp);
                assert_eq!(hit.map(|h| h.0), truth, "{traversal:?}, triangle {k}");
            }
        }
    }

    /// The ordered kernel's stack holds what the depth bound lets a traversal push.
    #[test]
    fn the_kernels_stack_matches_the_depth_bound() {
        let wgsl = include_str!("traverse_ordered.wgsl");
        assert!(wgsl.contains(&format!("const STACK: u32 = {MAX_DEPTH}u;")), "STACK in traverse_ordered.wgsl");
    }

    /// A tree that is one leaf (or none) still gives the ordered layout a root.
    #[test]
    fn small_trees_have_a_paired_root() {
        let one = vec![tri([0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0])];
        let (nodes, _) = build_bvh(&one);
        let pairs = pair_nodes(&nodes);
        assert_eq!(pairs.len(), 1);
        let (hit, _) =
            reference_traverse(Traversal::Ordered, &nodes, &pairs, &one, [0.2, 0.2, 0.0], [0.0, 0.0, 1.0], 9.0);
        assert_eq!(hit.map(|h| h.0), Some(1.0));
        let (nodes, _) = build_bvh(&[]);
        let pairs = pair_nodes(&nodes);
        let (hit, _) = reference_traverse(Traversal::Ordered, &nodes, &pairs, &[], [0.0; 3], [0.0, 0.0, 1.0], 9.0);
        assert_eq!(hit, None);
    }
}
