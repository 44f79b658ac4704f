//! Bounding volume hierarchy: a binary binned-SAH build (parallel over subtrees), collapsed
//! into 8-wide nodes whose child boxes are stored axis by axis (structure of arrays), so one
//! node visit tests eight boxes in a few AVX instructions (two SSE halves without AVX) and
//! the tree has a third of the levels of a binary one. Leaf triangles are packed four to a
//! block in leaf order and tested four at once, so a leaf is one or two contiguous reads.
//! Incoherent rays spend most of their time waiting on memory; the traversal therefore
//! prefetches every child it will visit and avoids unpredictable branches (hit children
//! come out of the box test as a bit mask).

use super::triangle::{intersect4, Triangle4};
use super::{Accelerator, BuildTriangle, Hit, HitFilter, Ray, RayPrecomp};
use crate::math::{Aabb, Vec3};
use std::mem::MaybeUninit;

const BINS: usize = 16;
const MAX_LEAF: usize = 8;
/// SAH costs, in units of one four-triangle block test.
const TRAVERSAL_COST: f32 = 1.0;
const BLOCK_COST: f32 = 1.0;
const PARALLEL_THRESHOLD: usize = 4096;
const MASKED_BIT: u32 = 1 << 31;

/// A child slot that holds nothing.
const EMPTY: u32 = 0;
/// A child slot that holds an interior node (other values are a leaf's number of
/// four-triangle blocks).
const INTERIOR: u32 = u32::MAX;

/// Children per node.
const WIDTH: usize = 8;

/// Eight children: their boxes axis by axis, then what each is. 256 bytes, four cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node {
    min: [[f32; WIDTH]; 3],
    max: [[f32; WIDTH]; 3],
    /// Interior child: node index. Leaf child: its first block of four triangles.
    child: [u32; WIDTH],
    /// [`EMPTY`], [`INTERIOR`], or the leaf's number of blocks.
    kind: [u32; WIDTH],
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
    nodes: Vec<Node>,
    /// What the root is: (child, kind) as in a node's slot.
    root: (u32, u32),
    /// Leaf triangles in blocks of four, each leaf a run of blocks.
    blocks: Vec<Triangle4>,
    /// Global triangle index per block lane; the top bit marks alpha-masked triangles.
    prim_ids: Vec<[u32; 4]>,
    bounds: Aabb,
    /// Traversal stack entries the deepest path can need.
    stack_need: usize,
    /// Whether this CPU has AVX: the eight boxes of a node are then tested in one go.
    #[cfg(target_arch = "x86_64")]
    avx: bool,
}

/// Traversal stack kept on the program stack; deeper trees get one on the heap.
const STACK: usize = 256;

/// A pending subtree: (child, kind) as in a node's slot, and the ray's entry distance.
type StackEntry = (u32, u32, f32);

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
        let mut refs = split_large_references(triangles);
        let root = if refs.is_empty() {
            BuildNode::Leaf { bounds: Aabb::EMPTY, start: 0, count: 0 }
        } else {
            build_recursive(&mut refs, 0)
        };
        let mut out = Flattened { nodes: Vec::new(), blocks: Vec::new(), prim_ids: Vec::new(), triangles, refs: &refs };
        let root_slot = out.slot(&root);
        let depth = max_depth(&root);
        let bounds = node_bounds(&root);
        let Flattened { nodes, blocks, prim_ids, .. } = out;
        // Each level leaves at most WIDTH - 1 siblings pending.
        #[cfg(target_arch = "x86_64")]
        let avx = std::arch::is_x86_feature_detected!("avx");
        Bvh {
            nodes,
            root: root_slot,
            blocks,
            prim_ids,
            bounds,
            stack_need: (WIDTH - 1) * depth + 1,
            #[cfg(target_arch = "x86_64")]
            avx,
        }
    }

    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats { nodes: self.nodes.len(), ..Default::default() };
        let root_area = self.bounds.half_area().max(1e-30);
        if self.root.1 != INTERIOR {
            s.leaves = 1;
            s.sah_cost = self.root.1 as f32 * BLOCK_COST;
            return s;
        }
        s.sah_cost = TRAVERSAL_COST;
        let mut stack = vec![(self.root.0 as usize, 1usize)];
        while let Some((i, depth)) = stack.pop() {
            let n = &self.nodes[i];
            s.max_depth = s.max_depth.max(depth);
            for k in 0..WIDTH {
                let b = Aabb {
                    min: crate::math::vec3(n.min[0][k], n.min[1][k], n.min[2][k]),
                    max: crate::math::vec3(n.max[0][k], n.max[1][k], n.max[2][k]),
                };
                match n.kind[k] {
                    EMPTY => {}
                    INTERIOR => {
                        s.sah_cost += b.half_area() / root_area * TRAVERSAL_COST;
                        stack.push((n.child[k] as usize, depth + 1));
                    }
                    count => {
                        s.leaves += 1;
                        s.sah_cost += b.half_area() / root_area * count as f32 * BLOCK_COST;
                    }
                }
            }
        }
        s
    }

    /// Starts loading a child the ray will visit, so that the memory latency overlaps with
    /// the work on its nearer siblings.
    #[inline(always)]
    fn prefetch(&self, child: u32, kind: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let (p, bytes): (*const i8, usize) = if kind == INTERIOR {
                (self.nodes.as_ptr().wrapping_add(child as usize).cast(), size_of::<Node>())
            } else {
                (self.blocks.as_ptr().wrapping_add(child as usize).cast(), size_of::<Triangle4>())
            };
            for line in (0..bytes).step_by(64) {
                // SAFETY: prefetching never faults, whatever the address.
                unsafe { _mm_prefetch(p.wrapping_add(line), _MM_HINT_T0) };
            }
        }
    }

    #[inline]
    fn traverse<const ANY: bool>(&self, ray: &Ray, filter: &dyn HitFilter) -> Option<Hit> {
        if self.blocks.is_empty() {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: the CPU was found to support AVX when the hierarchy was built.
            return unsafe { self.traverse_avx::<ANY>(ray, filter) };
        }
        self.traverse_on_stack::<ANY, false>(ray, filter)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn traverse_avx<const ANY: bool>(&self, ray: &Ray, filter: &dyn HitFilter) -> Option<Hit> {
        self.traverse_on_stack::<ANY, true>(ray, filter)
    }

    #[inline(always)]
    fn traverse_on_stack<const ANY: bool, const AVX: bool>(&self, ray: &Ray, filter: &dyn HitFilter) -> Option<Hit> {
        // Left uninitialised: zeroing 2 KB per ray costs more than a shallow traversal.
        if self.stack_need <= STACK {
            self.traverse_with::<ANY, AVX>(ray, filter, &mut [MaybeUninit::uninit(); STACK])
        } else {
            self.traverse_with::<ANY, AVX>(ray, filter, &mut vec![MaybeUninit::uninit(); self.stack_need])
        }
    }

    #[inline(always)]
    fn traverse_with<const ANY: bool, const AVX: bool>(
        &self,
        ray: &Ray,
        filter: &dyn HitFilter,
        stack: &mut [MaybeUninit<StackEntry>],
    ) -> Option<Hit> {
        let pre = RayPrecomp::new(ray);
        let origin = [ray.o.x, ray.o.y, ray.o.z];
        let inv_d = [pre.inv_d.x, pre.inv_d.y, pre.inv_d.z];
        let mut best: Option<Hit> = None;
        let mut tmax = ray.tmax;
        let mut sp = 0usize;
        let (mut child, mut kind) = self.root;
        loop {
            if kind == INTERIOR {
                let node = &self.nodes[child as usize];
                let (tnear, mut mask) = slab(node, origin, inv_d, tmax, AVX);
                if mask != 0 {
                    let k = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if mask == 0 {
                        // One child hit, the common case: straight down, nothing to sort.
                        (child, kind) = (node.child[k], node.kind[k]);
                        continue;
                    }
                    // Several: nearest first (any order for any-hit), by insertion.
                    let mut order = [(node.child[k], node.kind[k], tnear[k]); WIDTH];
                    self.prefetch(node.child[k], node.kind[k]);
                    let mut hits = 1;
                    while mask != 0 {
                        let k = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let entry = (node.child[k], node.kind[k], tnear[k]);
                        self.prefetch(entry.0, entry.1);
                        let mut j = hits;
                        while !ANY && j > 0 && order[j - 1].2 > entry.2 {
                            order[j] = order[j - 1];
                            j -= 1;
                        }
                        order[j] = entry;
                        hits += 1;
                    }
                    for &entry in order[1..hits].iter().rev() {
                        stack[sp].write(entry);
                        sp += 1;
                    }
                    (child, kind) = (order[0].0, order[0].1);
                    continue;
                }
            } else {
                let start = child as usize;
                for i in start..start + kind as usize {
                    let mut hits = intersect4(ray, &pre, &self.blocks[i], tmax);
                    // Nearest lane first; a masked lane the filter rejects gives way to the next.
                    while let Some(k) = hits.nearest() {
                        hits.valid &= !(1 << k);
                        let id = self.prim_ids[i][k];
                        let prim = id & !MASKED_BIT;
                        let (t, b1, b2) = (hits.t[k], hits.b1[k], hits.b2[k]);
                        if id & MASKED_BIT != 0 && !filter.accept(ray, prim, b1, b2) {
                            continue;
                        }
                        let hit = Hit { t, prim, b1, b2 };
                        if ANY {
                            return Some(hit);
                        }
                        tmax = t;
                        best = Some(hit);
                        break;
                    }
                }
            }
            // Next: the nearest pending subtree the ray still enters before tmax.
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                // SAFETY: entries below the stack pointer were written before it moved past them.
                let (c, k, t) = unsafe { stack[sp].assume_init() };
                if t <= tmax {
                    (child, kind) = (c, k);
                    break;
                }
            }
        }
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

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// Entry distances of the ray into the child boxes of `n`, and a mask with bit `k` set when
/// the ray enters box `k` before `tmax`. Boxes are widened by a few ulps so that flat ones
/// (axis-aligned walls) are not missed; empty slots hold boxes at infinity, never entered.
/// `avx` may be true only on a CPU with AVX.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn slab(n: &Node, o: [f32; 3], inv_d: [f32; 3], tmax: f32, avx: bool) -> ([f32; WIDTH], u32) {
    if avx {
        // SAFETY: the caller has checked that the CPU supports AVX.
        unsafe { slab8_avx(n, o, inv_d, tmax) }
    } else {
        let ((lo, lo_mask), (hi, hi_mask)) = (slab4_sse(n, 0, o, inv_d, tmax), slab4_sse(n, 4, o, inv_d, tmax));
        (std::array::from_fn(|k| if k < 4 { lo[k] } else { hi[k - 4] }), lo_mask | hi_mask << 4)
    }
}

/// The box sides a ray crosses first and last along `axis`, by the sign of its direction.
/// (A NaN distance, from a ray in a box's plane, is ignored: the accumulated bound is the
/// second operand of the min/max, which x86 returns when either is NaN.)
#[inline(always)]
fn near_far(n: &Node, axis: usize, inv_d: f32) -> (&[f32; WIDTH], &[f32; WIDTH]) {
    if inv_d >= 0.0 {
        (&n.min[axis], &n.max[axis])
    } else {
        (&n.max[axis], &n.min[axis])
    }
}

/// All eight boxes with 256-bit instructions.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
fn slab8_avx(n: &Node, o: [f32; 3], inv_d: [f32; 3], tmax: f32) -> ([f32; WIDTH], u32) {
    use std::arch::x86_64::*;
    let mut tnear = _mm256_setzero_ps();
    let mut tfar = _mm256_set1_ps(tmax);
    for a in 0..3 {
        let (oa, ia) = (_mm256_set1_ps(o[a]), _mm256_set1_ps(inv_d[a]));
        // SAFETY: `Node` is 64-byte aligned and each row is 32 bytes: aligned and in bounds.
        let (near, far) = near_far(n, a, inv_d[a]);
        let (lo, hi) = unsafe { (_mm256_load_ps(near.as_ptr()), _mm256_load_ps(far.as_ptr())) };
        let t1 = _mm256_mul_ps(_mm256_sub_ps(lo, oa), ia);
        let t2 = _mm256_mul_ps(_mm256_sub_ps(hi, oa), ia);
        tnear = _mm256_max_ps(t1, tnear);
        tfar = _mm256_min_ps(t2, tfar);
    }
    let widened = _mm256_mul_ps(tfar, _mm256_set1_ps(1.000_000_4));
    let hit = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_LE_OQ>(tnear, widened),
        _mm256_cmp_ps::<_CMP_LT_OQ>(tnear, _mm256_set1_ps(f32::INFINITY)),
    );
    let mut r = [0.0f32; WIDTH];
    // SAFETY: `r` holds eight floats.
    unsafe { _mm256_storeu_ps(r.as_mut_ptr(), tnear) };
    (r, _mm256_movemask_ps(hit) as u32)
}

/// Four boxes, from lane `first`, with SSE (part of the x86_64 baseline).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn slab4_sse(n: &Node, first: usize, o: [f32; 3], inv_d: [f32; 3], tmax: f32) -> ([f32; 4], u32) {
    use std::arch::x86_64::*;
    // SAFETY: SSE is part of the x86_64 baseline; `Node` is 64-byte aligned, its rows are
    // 32 bytes and `first` is 0 or 4, so the aligned loads are in bounds and aligned.
    unsafe {
        let mut tnear = _mm_setzero_ps();
        let mut tfar = _mm_set1_ps(tmax);
        for a in 0..3 {
            let (oa, ia) = (_mm_set1_ps(o[a]), _mm_set1_ps(inv_d[a]));
            let (near, far) = near_far(n, a, inv_d[a]);
            let t1 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(near[first..].as_ptr()), oa), ia);
            let t2 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(far[first..].as_ptr()), oa), ia);
            tnear = _mm_max_ps(t1, tnear);
            tfar = _mm_min_ps(t2, tfar);
        }
        let widened = _mm_mul_ps(tfar, _mm_set1_ps(1.000_000_4));
        let hit = _mm_and_ps(_mm_cmple_ps(tnear, widened), _mm_cmplt_ps(tnear, _mm_set1_ps(f32::INFINITY)));
        let mut r = [0.0f32; 4];
        _mm_storeu_ps(r.as_mut_ptr(), tnear);
        (r, _mm_movemask_ps(hit) as u32)
    }
}

/// Portable form of the x86_64 versions above.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn slab(n: &Node, o: [f32; 3], inv_d: [f32; 3], tmax: f32, _avx: bool) -> ([f32; WIDTH], u32) {
    let mut tnear = [0.0f32; WIDTH];
    let mut tfar = [tmax; WIDTH];
    for a in 0..3 {
        let (near, far) = near_far(n, a, inv_d[a]);
        for k in 0..WIDTH {
            tnear[k] = fmax((near[k] - o[a]) * inv_d[a], tnear[k]);
            tfar[k] = fmin((far[k] - o[a]) * inv_d[a], tfar[k]);
        }
    }
    let mask = (0..WIDTH).filter(|&k| tnear[k] <= tfar[k] * 1.000_000_4 && tnear[k] < f32::INFINITY);
    (tnear, mask.fold(0, |m, k| m | 1 << k))
}

/// Extra references the pre-split may add, as a fraction of the triangle count.
const SPLIT_BUDGET: f32 = 0.5;
/// A reference is split while its box is larger than this many times the mean box...
const SPLIT_THRESHOLD: f32 = 4.0;
/// ... and its box's half surface is more than this many times the area of the triangle
/// part inside it: boxes mostly empty, not flat walls (whose ratio is 1 to 2), which split
/// into many flat boxes of the same total area for nothing.
const SPLIT_EMPTINESS: f32 = 3.0;

/// One reference per triangle, then the largest boxes split in two at the middle of their
/// longest side, each half bounding exactly the part of the triangle inside it ("early split
/// clipping", Ernst & Greiner 2007), largest first, within [`SPLIT_BUDGET`], while they are
/// mostly empty. Long thin or
/// large diagonal triangles (a cathedral's vaults, a door frame) otherwise have boxes full
/// of empty space that overlap everything around them. A triangle may then sit in several
/// leaves; each finds the same hit.
fn split_large_references(triangles: &[BuildTriangle]) -> Vec<PrimRef> {
    let mut refs: Vec<PrimRef> = triangles
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let b = t.bounds();
            PrimRef { bounds: b, centroid: b.center(), index: i as u32 }
        })
        .collect();
    if refs.is_empty() {
        return refs;
    }
    let mean = refs.iter().map(|r| r.bounds.half_area() as f64).sum::<f64>() / refs.len() as f64;
    let threshold = (mean * SPLIT_THRESHOLD as f64) as f32;
    let budget = (triangles.len() as f32 * SPLIT_BUDGET) as usize;
    let worth_splitting = |b: &Aabb, area: f32| b.half_area() > threshold && b.half_area() > SPLIT_EMPTINESS * area;
    let mut heap: std::collections::BinaryHeap<(OrderedArea, usize)> = refs
        .iter()
        .enumerate()
        .filter(|(i, r)| worth_splitting(&r.bounds, triangle_area(&triangles[*i].v)))
        .map(|(i, r)| (OrderedArea(r.bounds.half_area()), i))
        .collect();
    // The cell of each reference: the split planes that cut it out of its triangle. Its box
    // is the triangle clipped to the cell; clipping against that rounded box again, rather
    // than against the exact planes, would shave slivers off nearly flat triangles.
    let everywhere = Aabb { min: Vec3::splat(f32::NEG_INFINITY), max: Vec3::splat(f32::INFINITY) };
    let mut cells = vec![everywhere; refs.len()];
    let mut added = 0;
    while let Some((_, i)) = heap.pop() {
        if added >= budget {
            break;
        }
        let r = refs[i];
        let axis = r.bounds.extent().max_axis();
        let mid = 0.5 * (r.bounds.min[axis] + r.bounds.max[axis]);
        let (mut lo, mut hi) = (cells[i], cells[i]);
        lo.max[axis] = mid;
        hi.min[axis] = mid;
        let v = &triangles[r.index as usize].v;
        let (Some((a, area_a)), Some((b, area_b))) = (clipped(v, &lo), clipped(v, &hi)) else { continue };
        refs[i] = PrimRef { bounds: a, centroid: a.center(), index: r.index };
        cells[i] = lo;
        refs.push(PrimRef { bounds: b, centroid: b.center(), index: r.index });
        cells.push(hi);
        added += 1;
        for (j, area) in [(i, area_a), (refs.len() - 1, area_b)] {
            if worth_splitting(&refs[j].bounds, area) {
                heap.push((OrderedArea(refs[j].bounds.half_area()), j));
            }
        }
    }
    refs
}

/// A box area ordered for the split heap.
#[derive(Clone, Copy, PartialEq)]
struct OrderedArea(f32);
impl Eq for OrderedArea {}
impl PartialOrd for OrderedArea {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for OrderedArea {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&o.0)
    }
}

fn triangle_area(v: &[Vec3; 3]) -> f32 {
    0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length()
}

/// Bounds and area of the part of triangle `v` inside `clip` (Sutherland–Hodgman against
/// the box's six planes), `None` if nothing of it is inside.
fn clipped(v: &[Vec3; 3], clip: &Aabb) -> Option<(Aabb, f32)> {
    let mut poly: Vec<Vec3> = v.to_vec();
    for axis in 0..3 {
        for (plane, keep_below) in [(clip.min[axis], false), (clip.max[axis], true)] {
            let inside = |p: &Vec3| if keep_below { p[axis] <= plane } else { p[axis] >= plane };
            let mut out = Vec::with_capacity(poly.len() + 2);
            for k in 0..poly.len() {
                let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
                if inside(&a) {
                    out.push(a);
                }
                if inside(&a) != inside(&b) {
                    let t = (plane - a[axis]) / (b[axis] - a[axis]);
                    let mut p = a + (b - a) * t;
                    p[axis] = plane;
                    out.push(p);
                }
            }
            poly = out;
            if poly.is_empty() {
                return None;
            }
        }
    }
    let mut b = Aabb::EMPTY;
    poly.iter().for_each(|&p| b.grow(p));
    // Never larger than the clip box (rounding in the intersection points).
    for a in 0..3 {
        b.min[a] = b.min[a].max(clip.min[a]);
        b.max[a] = b.max[a].min(clip.max[a]);
    }
    // A convex polygon's area: half the length of the sum of its edges' cross products.
    let mut twice = Vec3::ZERO;
    for k in 1..poly.len().saturating_sub(1) {
        twice += (poly[k] - poly[0]).cross(poly[k + 1] - poly[0]);
    }
    Some((b, 0.5 * twice.length()))
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
    if cost >= leaf_cost(n) && n <= MAX_LEAF {
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

/// Cost of testing `n` triangles: they are tested four at a time.
#[inline]
fn leaf_cost(n: usize) -> f32 {
    n.div_ceil(4) as f32 * BLOCK_COST
}

#[inline]
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// Best (axis, last bin of the left side, SAH cost) over all axes.
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
                + (acc.half_area() * leaf_cost(cnt) + right_area[i + 1] * leaf_cost(right_count[i + 1]))
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

/// The flat form being written: wide nodes, and leaf triangles packed in blocks of four.
struct Flattened<'a> {
    nodes: Vec<Node>,
    blocks: Vec<Triangle4>,
    prim_ids: Vec<[u32; 4]>,
    triangles: &'a [BuildTriangle],
    refs: &'a [PrimRef],
}

impl Flattened<'_> {
    /// What a node slot holds for `node`: (child, kind).
    fn slot(&mut self, node: &BuildNode) -> (u32, u32) {
        match node {
            BuildNode::Leaf { start, count, .. } => self.leaf(*start, *count),
            interior => (self.collapse(interior), INTERIOR),
        }
    }

    /// Packs the leaf's triangles into blocks; returns (first block, block count).
    fn leaf(&mut self, start: usize, count: usize) -> (u32, u32) {
        let first = self.blocks.len() as u32;
        for chunk in self.refs[start..start + count].chunks(4) {
            let tris: Vec<[Vec3; 3]> = chunk.iter().map(|r| self.triangles[r.index as usize].v).collect();
            self.blocks.push(Triangle4::pack(&tris));
            let mut ids = [u32::MAX; 4];
            for (id, r) in ids.iter_mut().zip(chunk) {
                *id = r.index | if self.triangles[r.index as usize].masked { MASKED_BIT } else { 0 };
            }
            self.prim_ids.push(ids);
        }
        (first, self.blocks.len() as u32 - first)
    }

    /// Writes the wide node for the binary interior node `node` (and its subtree); returns
    /// its index. The node takes up to [`WIDTH`] descendants: starting from the two children,
    /// the interior one with the largest surface is replaced by its own two children until
    /// there are enough, which is the SAH-greedy way to flatten three levels into one.
    fn collapse(&mut self, node: &BuildNode) -> u32 {
        let slots = wide_descendants(node);
        let index = self.nodes.len();
        self.nodes.push(Node {
            min: [[f32::INFINITY; WIDTH]; 3],
            max: [[f32::INFINITY; WIDTH]; 3],
            child: [0; WIDTH],
            kind: [EMPTY; WIDTH],
        });
        for (k, slot) in slots.into_iter().enumerate() {
            let b = node_bounds(slot);
            for a in 0..3 {
                self.nodes[index].min[a][k] = b.min[a];
                self.nodes[index].max[a][k] = b.max[a];
            }
            (self.nodes[index].child[k], self.nodes[index].kind[k]) = self.slot(slot);
        }
        index as u32
    }
}

/// The (up to [`WIDTH`]) descendants a wide node takes for the binary interior node `node`.
fn wide_descendants(node: &BuildNode) -> Vec<&BuildNode> {
    let BuildNode::Interior { children, .. } = node else { unreachable!("collapse starts at interior nodes") };
    let mut slots: Vec<&BuildNode> = vec![&children[0], &children[1]];
    while slots.len() < WIDTH {
        let widest = slots
            .iter()
            .enumerate()
            .filter(|(_, n)| matches!(n, BuildNode::Interior { .. }))
            .max_by(|a, b| node_bounds(a.1).half_area().total_cmp(&node_bounds(b.1).half_area()))
            .map(|(i, _)| i);
        let Some(i) = widest else { break };
        let BuildNode::Interior { children, .. } = slots.remove(i) else { unreachable!() };
        slots.insert(i, &children[1]);
        slots.insert(i, &children[0]);
    }
    slots
}

/// Levels of the wide tree that [`Flattened::collapse`] makes of `node`.
fn max_depth(node: &BuildNode) -> usize {
    match node {
        BuildNode::Leaf { .. } => 0,
        interior => 1 + wide_descendants(interior).into_iter().map(max_depth).max().unwrap_or(0),
    }
}

fn node_bounds(node: &BuildNode) -> Aabb {
    match node {
        BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => *bounds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{intersect_triangle, NoFilter};
    use crate::math::vec3;
    use crate::sampling::{uniform_sphere, Rng};

    /// Small triangles in a 10-unit box, and every tenth one up to `large` units across (the
    /// long slivers and large diagonal faces the pre-split cuts up), half of those nearly
    /// flat (a few ulps of z), as a slightly uneven floor or vault.
    fn random_soup(n: usize, large: f32, rng: &mut Rng) -> Vec<BuildTriangle> {
        (0..n)
            .map(|i| {
                let c = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                let size = if i % 10 == 0 { large } else { 1.0 };
                let flat = if i % 20 == 0 { 2e-7 } else { 1.0 };
                let v = [0, 1, 2].map(|_| {
                    c + vec3(rng.next_f32() - 0.5, rng.next_f32() - 0.5, (rng.next_f32() - 0.5) * flat) * size
                });
                BuildTriangle { v, masked: false }
            })
            .collect()
    }

    /// The BVH must find exactly what testing every triangle finds.
    #[test]
    fn matches_brute_force() {
        let mut rng = Rng::new(5, 0, 0);
        for large in [1.0, 12.0] {
            matches_brute_force_on(&random_soup(5000, large, &mut rng), &mut rng);
        }
    }

    fn matches_brute_force_on(tris: &[BuildTriangle], rng: &mut Rng) {
        let bvh = Bvh::build(tris);
        let stats = bvh.stats();
        assert!(stats.leaves > 100 && stats.max_depth < 64);
        matches_brute_force_with(&bvh, tris, rng);
        // The SSE box test, which CPUs without AVX run.
        #[cfg(target_arch = "x86_64")]
        if bvh.avx {
            matches_brute_force_with(&Bvh { avx: false, ..bvh }, tris, rng);
        }
    }

    fn matches_brute_force_with(bvh: &Bvh, tris: &[BuildTriangle], rng: &mut Rng) {
        for _ in 0..4000 {
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
