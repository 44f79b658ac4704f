//! Bounding volume hierarchy: a binary binned-SAH build with spatial splits where objects
//! overlap (parallel over subtrees), collapsed by dynamic programming (least SAH cost)
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
/// Most triangle references in a leaf of the wide tree.
const MAX_LEAF: usize = 8;
/// Most references in a leaf of the binary build: it stops at one block where the SAH
/// says so, and the collapse merges small subtrees back into leaves of up to [`MAX_LEAF`]
/// where that is cheaper in the wide tree.
const MAX_BINARY_LEAF: usize = 4;
/// SAH costs, in units of one four-triangle block test: visiting a wide node.
const TRAVERSAL_COST: f32 = 1.0;
/// What a node of the binary build costs once three binary levels are collapsed into one
/// wide node: about a third of a visit. (0.4 instead of 1: closest-hit +1 % sibenik, +2 %
/// sponza, +2–10 % veach-ajar, any-hit ajar +8 %, build +7 %.)
const BINARY_TRAVERSAL_COST: f32 = 0.4;
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
    /// Triangle references in the leaves: more than the triangles where spatial splits cut some.
    pub references: usize,
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
    /// The triangles (indices into the build input) the leaf holds.
    Leaf {
        bounds: Aabb,
        prims: Box<[u32]>,
    },
    Interior {
        bounds: Aabb,
        children: Box<[BuildNode; 2]>,
    },
}

#[derive(Clone, Copy)]
struct PrimRef {
    bounds: Aabb,
    centroid: Vec3,
    index: u32,
}

impl Bvh {
    pub fn build(triangles: &[BuildTriangle]) -> Bvh {
        let root = binary_tree(triangles);
        let mut out = Flattened { nodes: Vec::new(), blocks: Vec::new(), prim_ids: Vec::new(), triangles };
        let plan = WidePlan::new(&root);
        let root_slot = out.slot(&plan);
        let depth = plan.depth();
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
        let references = self.prim_ids.iter().flatten().filter(|&&id| id != u32::MAX).count();
        let mut s = BvhStats { nodes: self.nodes.len(), references, ..Default::default() };
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
                    // Several: nearest first (slot order, largest box first, for any-hit), by insertion.
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
    fn describe(&self) -> Option<String> {
        let s = self.stats();
        Some(format!(
            "{} nodes, {} leaves, {} triangle references, depth {}, SAH cost {:.3}",
            s.nodes, s.leaves, s.references, s.max_depth, s.sah_cost
        ))
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

/// The binary SAH hierarchy the wide one is collapsed from.
fn binary_tree(triangles: &[BuildTriangle]) -> BuildNode {
    let refs: Vec<PrimRef> = triangles
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let b = t.bounds();
            PrimRef { bounds: b, centroid: b.center(), index: i as u32 }
        })
        .collect();
    if refs.is_empty() {
        return BuildNode::Leaf { bounds: Aabb::EMPTY, prims: Box::new([]) };
    }
    let builder = Builder { triangles, root_area: bounds_of(&refs).0.half_area() };
    let budget = (refs.len() as f32 * SPATIAL_BUDGET) as usize;
    builder.build(refs, budget)
}

fn bounds_of(refs: &[PrimRef]) -> (Aabb, Aabb) {
    let mut b = Aabb::EMPTY;
    let mut c = Aabb::EMPTY;
    for r in refs {
        grow_box(&mut b, &r.bounds);
        grow_box(&mut c, &Aabb { min: r.centroid, max: r.centroid });
    }
    (b, c)
}

/// Extra references spatial splits may add, as a fraction of the references they start from.
const SPATIAL_BUDGET: f32 = 0.5;
/// Spatial splits are tried only where the best object split's children overlap by more
/// than this fraction of the scene's surface (Stich et al. 2009's α): elsewhere they cannot
/// win, and skipping them keeps the build fast.
const SPATIAL_OVERLAP: f32 = 1e-5;

/// How a node's references are divided between its two children.
#[derive(Clone, Copy)]
enum Split {
    /// By centroid: references whose centroid falls in bins `..=bin` of `axis` go left.
    Object { axis: usize, bin: usize },
    /// By position: the plane at the end of bin `bin` along `axis` of the node's box;
    /// references straddling it are cut in two.
    Spatial { axis: usize, bin: usize },
}

/// The binary build: binned SAH over centroids, and spatial splits (SBVH, Stich et al. 2009,
/// binned) where object splits leave children overlapping. Spatial splits cut the references
/// of large triangles at the planes that pay, within [`SPATIAL_BUDGET`].
struct Builder<'a> {
    triangles: &'a [BuildTriangle],
    /// Half surface of the whole scene, the unit of [`SPATIAL_OVERLAP`].
    root_area: f32,
}

impl Builder<'_> {
    /// Builds the subtree of `refs`, which may add `budget` references by spatial splits.
    fn build(&self, mut refs: Vec<PrimRef>, budget: usize) -> BuildNode {
        let (bounds, cbounds) = bounds_of(&refs);
        let n = refs.len();
        if n <= 2 {
            return self.leaf(bounds, &refs);
        }
        let mut best = best_object_split(&refs, &bounds, &cbounds);
        if budget > 0 && best.is_none_or(|(_, _, overlap)| overlap > SPATIAL_OVERLAP * self.root_area) {
            if let Some((split, cost)) = self.best_spatial_split(&refs, &bounds, budget) {
                if best.is_none_or(|b| cost < b.1) {
                    best = Some((split, cost, 0.0));
                }
            }
        }
        let Some((split, cost, _)) = best else {
            return if n <= MAX_LEAF { self.leaf(bounds, &refs) } else { self.median_split(refs, &cbounds, budget) };
        };
        if cost >= leaf_cost(n) && n <= MAX_BINARY_LEAF {
            return self.leaf(bounds, &refs);
        }
        let (left, right) = match split {
            Split::Object { axis, bin } => {
                let axes = BinAxes::new(&cbounds);
                let mid = partition(&mut refs, |r| axes.bin(axis, r.centroid[axis]) <= bin);
                if mid == 0 || mid == n {
                    return self.median_split(refs, &cbounds, budget);
                }
                let right = refs.split_off(mid);
                (refs, right)
            }
            Split::Spatial { axis, bin } => self.cut(refs, axis, spatial_plane(&bounds, axis, bin)),
        };
        if left.is_empty() || right.is_empty() {
            let mut all = left;
            all.extend(right);
            return self.median_split(all, &cbounds, budget);
        }
        let added = (left.len() + right.len()).saturating_sub(n);
        self.join(bounds, left, right, budget.saturating_sub(added))
    }

    /// Builds both children, in parallel when large, sharing `budget` by size.
    fn join(&self, bounds: Aabb, left: Vec<PrimRef>, right: Vec<PrimRef>, budget: usize) -> BuildNode {
        let n = left.len() + right.len();
        let left_budget = (budget as u64 * left.len() as u64 / n as u64) as usize;
        let right_budget = budget - left_budget;
        let (l, r) = if n > PARALLEL_THRESHOLD {
            rayon::join(|| self.build(left, left_budget), || self.build(right, right_budget))
        } else {
            (self.build(left, left_budget), self.build(right, right_budget))
        };
        BuildNode::Interior { bounds, children: Box::new([l, r]) }
    }

    fn median_split(&self, mut refs: Vec<PrimRef>, cbounds: &Aabb, budget: usize) -> BuildNode {
        let bounds = bounds_of(&refs).0;
        let axis = cbounds.extent().max_axis();
        let mid = refs.len() / 2;
        refs.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
        let right = refs.split_off(mid);
        self.join(bounds, refs, right, budget)
    }

    fn leaf(&self, bounds: Aabb, refs: &[PrimRef]) -> BuildNode {
        BuildNode::Leaf { bounds, prims: refs.iter().map(|r| r.index).collect() }
    }

    /// Best spatial split of `refs` (node box `bounds`) that cuts at most `budget` references,
    /// and its SAH cost. For the estimate, a reference spanning several bins adds its box
    /// clipped to each bin's slab to that bin (larger than the triangle's piece where the
    /// triangle is diagonal); exact clipping here took 1.5x the build time for no measurable
    /// gain in ray throughput on sibenik and sponza. The split itself clips exactly.
    fn best_spatial_split(&self, refs: &[PrimRef], bounds: &Aabb, budget: usize) -> Option<(Split, f32)> {
        let parent_area = bounds.half_area().max(1e-30);
        let mut best: Option<(Split, f32)> = None;
        let axes = BinAxes::new(bounds);
        let mut bin_bounds = [[Aabb::EMPTY; BINS]; 3];
        let mut enter = [[0usize; BINS]; 3];
        let mut exit = [[0usize; BINS]; 3];
        for axis in 0..3 {
            for r in refs {
                let first = axes.bin(axis, r.bounds.min[axis]);
                let last = axes.bin(axis, r.bounds.max[axis]).max(first);
                enter[axis][first] += 1;
                exit[axis][last] += 1;
                for (b, bin) in bin_bounds[axis].iter_mut().enumerate().take(last + 1).skip(first) {
                    let mut piece = r.bounds;
                    if b > first {
                        piece.min[axis] = spatial_plane(bounds, axis, b - 1);
                    }
                    if b < last {
                        piece.max[axis] = spatial_plane(bounds, axis, b);
                    }
                    grow_box(bin, &piece);
                }
            }
        }
        let fits = |left: usize, right: usize| left + right <= refs.len() + budget;
        for axis in 0..3 {
            if let Some(plane) = sah_sweep(&bin_bounds[axis], &enter[axis], &exit[axis], parent_area, fits) {
                if best.is_none_or(|b| plane.cost < b.1) {
                    best = Some((Split::Spatial { axis, bin: plane.bin }, plane.cost));
                }
            }
        }
        best
    }

    /// Divides `refs` at `plane` on `axis`: references on one side go there, those
    /// straddling it are cut into a piece for each side.
    fn cut(&self, refs: Vec<PrimRef>, axis: usize, plane: f32) -> (Vec<PrimRef>, Vec<PrimRef>) {
        let (mut left, mut right) = (Vec::with_capacity(refs.len()), Vec::with_capacity(refs.len()));
        for r in refs {
            if r.bounds.max[axis] <= plane {
                left.push(r);
            } else if r.bounds.min[axis] >= plane {
                right.push(r);
            } else {
                let (l, h) = split_reference(&self.triangles[r.index as usize].v, &r.bounds, axis, plane);
                for (piece, side) in [(l, &mut left), (h, &mut right)] {
                    if !piece.is_empty() {
                        side.push(PrimRef { bounds: piece, centroid: piece.center(), index: r.index });
                    }
                }
            }
        }
        (left, right)
    }
}

/// The plane at the end of spatial bin `bin` along `axis` of `bounds`.
fn spatial_plane(bounds: &Aabb, axis: usize, bin: usize) -> f32 {
    let lo = bounds.min[axis];
    lo + (bounds.max[axis] - lo) * ((bin + 1) as f32 / BINS as f32)
}

/// The boxes of the parts of triangle `v` below and above `plane` on `axis`, each within
/// `bounds` (the reference being cut). Edge crossings are padded in their other coordinates
/// by 4ε times the larger endpoint coordinate, above the few-ulp error of a + (b − a)·t, so
/// the pieces never lose a sliver of the triangle.
fn split_reference(v: &[Vec3; 3], bounds: &Aabb, axis: usize, plane: f32) -> (Aabb, Aabb) {
    let (mut below, mut above) = (Aabb::EMPTY, Aabb::EMPTY);
    for k in 0..3 {
        let (a, b) = (v[k], v[(k + 1) % 3]);
        if a[axis] <= plane {
            below.grow(a);
        }
        if a[axis] >= plane {
            above.grow(a);
        }
        if (a[axis] < plane && b[axis] > plane) || (a[axis] > plane && b[axis] < plane) {
            let t = (plane - a[axis]) / (b[axis] - a[axis]);
            let mut p = a + (b - a) * t;
            p[axis] = plane;
            let mut pad = Vec3::ZERO;
            for o in 0..3 {
                if o != axis {
                    pad[o] = 4.0 * f32::EPSILON * a[o].abs().max(b[o].abs());
                }
            }
            for box_ in [&mut below, &mut above] {
                box_.grow(p - pad);
                box_.grow(p + pad);
            }
        }
    }
    below.max[axis] = below.max[axis].min(plane);
    above.min[axis] = above.min[axis].max(plane);
    (below.intersection(*bounds), above.intersection(*bounds))
}

/// Cost of testing `n` triangles: they are tested four at a time.
#[inline]
fn leaf_cost(n: usize) -> f32 {
    n.div_ceil(4) as f32 * BLOCK_COST
}

/// Where [`BINS`] bins lie along each axis of a range: its start and bins per unit length
/// (0 along an axis without extent, whose values then all fall in bin 0 and give no plane).
struct BinAxes {
    lo: [f32; 3],
    scale: [f32; 3],
}

impl BinAxes {
    fn new(range: &Aabb) -> BinAxes {
        let extent = range.extent();
        BinAxes {
            lo: [range.min.x, range.min.y, range.min.z],
            scale: [0, 1, 2].map(|a| if extent[a] > 0.0 { BINS as f32 / extent[a] } else { 0.0 }),
        }
    }

    /// The bin of coordinate `c` along `axis`, clamped to the bins.
    #[inline]
    fn bin(&self, axis: usize, c: f32) -> usize {
        (((c - self.lo[axis]) * self.scale[axis]) as i32).clamp(0, BINS as i32 - 1) as usize
    }
}

/// `b` grown to hold `piece`, with plain comparisons: build boxes hold no NaN, and the
/// NaN-aware `f32::min` costs a fifth of the build in the binning loops.
#[inline]
fn grow_box(b: &mut Aabb, piece: &Aabb) {
    for a in 0..3 {
        b.min[a] = if piece.min[a] < b.min[a] { piece.min[a] } else { b.min[a] };
        b.max[a] = if piece.max[a] > b.max[a] { piece.max[a] } else { b.max[a] };
    }
}

/// The cheapest plane between bins: the last bin on its left, its SAH cost, the boxes of
/// the two sides.
struct Plane {
    bin: usize,
    cost: f32,
    left: Aabb,
    right: Aabb,
}

/// Sweeps the planes between `bins`: `enter[i]` references start in bin i, `exit[i]` end
/// there (the same counts for object splits), so a plane after bin i has the references
/// entered up to i on its left and those leaving after i on its right. Planes whose
/// (left, right) counts `fits` rejects are skipped.
fn sah_sweep(
    bins: &[Aabb; BINS],
    enter: &[usize; BINS],
    exit: &[usize; BINS],
    parent_area: f32,
    fits: impl Fn(usize, usize) -> bool,
) -> Option<Plane> {
    let mut right_box = [Aabb::EMPTY; BINS];
    let mut right_count = [0usize; BINS];
    let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
    for i in (1..BINS).rev() {
        acc = acc.union(bins[i]);
        cnt += exit[i];
        right_box[i] = acc;
        right_count[i] = cnt;
    }
    let mut best: Option<Plane> = None;
    let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
    for i in 0..BINS - 1 {
        acc = acc.union(bins[i]);
        cnt += enter[i];
        let right_n = right_count[i + 1];
        if cnt == 0 || right_n == 0 || !fits(cnt, right_n) {
            continue;
        }
        let left = acc;
        let cost = BINARY_TRAVERSAL_COST
            + (left.half_area() * leaf_cost(cnt) + right_box[i + 1].half_area() * leaf_cost(right_n)) / parent_area;
        if best.as_ref().is_none_or(|b| cost < b.cost) {
            best = Some(Plane { bin: i, cost, left, right: right_box[i + 1] });
        }
    }
    best
}

/// Best object split over all axes: (split, SAH cost, half surface of the overlap of the
/// two children's boxes).
fn best_object_split(refs: &[PrimRef], bounds: &Aabb, cbounds: &Aabb) -> Option<(Split, f32, f32)> {
    let parent_area = bounds.half_area().max(1e-30);
    let mut best: Option<(Split, f32, f32)> = None;
    let axes = BinAxes::new(cbounds);
    let mut bin_bounds = [[Aabb::EMPTY; BINS]; 3];
    let mut bin_counts = [[0usize; BINS]; 3];
    for axis in 0..3 {
        for r in refs {
            let b = axes.bin(axis, r.centroid[axis]);
            grow_box(&mut bin_bounds[axis][b], &r.bounds);
            bin_counts[axis][b] += 1;
        }
    }
    for axis in 0..3 {
        let counts = &bin_counts[axis];
        if let Some(plane) = sah_sweep(&bin_bounds[axis], counts, counts, parent_area, |_, _| true) {
            if best.is_none_or(|b| plane.cost < b.1) {
                let overlap = plane.left.intersection(plane.right).half_area();
                best = Some((Split::Object { axis, bin: plane.bin }, plane.cost, overlap));
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
}

impl Flattened<'_> {
    /// What a node slot holds for `node`: (child, kind).
    fn slot(&mut self, plan: &WidePlan) -> (u32, u32) {
        if plan.as_leaf {
            self.leaf(&plan.leaf_prims())
        } else {
            (self.collapse(plan), INTERIOR)
        }
    }

    /// Packs the leaf's triangles into blocks; returns (first block, block count).
    fn leaf(&mut self, prims: &[u32]) -> (u32, u32) {
        let first = self.blocks.len() as u32;
        for chunk in prims.chunks(4) {
            let tris: Vec<[Vec3; 3]> = chunk.iter().map(|&i| self.triangles[i as usize].v).collect();
            self.blocks.push(Triangle4::pack(&tris));
            let mut ids = [u32::MAX; 4];
            for (id, &i) in ids.iter_mut().zip(chunk) {
                *id = i | if self.triangles[i as usize].masked { MASKED_BIT } else { 0 };
            }
            self.prim_ids.push(ids);
        }
        (first, self.blocks.len() as u32 - first)
    }

    /// Writes the wide node for the binary interior node planned by `plan` (and its
    /// subtree); returns its index.
    fn collapse(&mut self, plan: &WidePlan) -> u32 {
        let mut slots = Vec::with_capacity(WIDTH);
        plan.children_slots(WIDTH, &mut slots);
        // Any-hit traversal takes hit children in slot order: largest first, as the likeliest
        // to hold an occluder (any-hit +5-8 % on sponza, +2 % on sibenik). Closest-hit
        // sorts by distance and does not care.
        slots.sort_by(|a, b| node_bounds(b.node).half_area().total_cmp(&node_bounds(a.node).half_area()));
        let index = self.nodes.len();
        self.nodes.push(Node {
            min: [[f32::INFINITY; WIDTH]; 3],
            max: [[f32::INFINITY; WIDTH]; 3],
            child: [0; WIDTH],
            kind: [EMPTY; WIDTH],
        });
        for (k, slot) in slots.into_iter().enumerate() {
            let b = node_bounds(slot.node);
            for a in 0..3 {
                self.nodes[index].min[a][k] = b.min[a];
                self.nodes[index].max[a][k] = b.max[a];
            }
            (self.nodes[index].child[k], self.nodes[index].kind[k]) = self.slot(slot);
        }
        index as u32
    }
}

/// How a binary subtree becomes slots of wide nodes, chosen for the least SAH cost by
/// dynamic programming over the binary tree (Ylitie, Karras and Laine 2017, §3.1): each
/// binary node is one slot (a wide node of its own, or a leaf of all its triangles when
/// they are few) or gives its slots to its two children, shared between them as costs say.
/// Greedy flattening (open the largest box until eight slots are filled) spends slots on
/// large boxes whose subtrees are cheap: against it, SAH cost −5 % on sibenik and sponza,
/// 35 % fewer nodes, closest-hit +4 % on sibenik (with binary leaves of one block).
struct WidePlan<'a> {
    node: &'a BuildNode,
    /// Triangle references in the subtree (repeats from spatial splits counted).
    refs: usize,
    /// `cost[k - 1]`: least SAH cost (in half-area × block tests) of the subtree as at most
    /// `k` slots.
    cost: [f32; WIDTH],
    /// `spread[k - 1]`: 0 when that least cost is one slot, else `j`, the number of slots
    /// the two children share (`cost[k - 1]` is then `shared[j - 1]`).
    spread: [u8; WIDTH],
    /// `left[j - 1]`: of `j` slots shared by the children, how many the left one takes.
    left: [u8; WIDTH],
    /// As one slot, the subtree is a leaf holding all its triangles (not a wide node).
    as_leaf: bool,
    children: Option<Box<[WidePlan<'a>; 2]>>,
}

impl<'a> WidePlan<'a> {
    fn new(node: &'a BuildNode) -> WidePlan<'a> {
        let area = node_bounds(node).half_area();
        let BuildNode::Interior { children, .. } = node else {
            let BuildNode::Leaf { prims, .. } = node else { unreachable!() };
            let cost = area * leaf_cost(prims.len());
            return WidePlan {
                node,
                refs: prims.len(),
                cost: [cost; WIDTH],
                spread: [0; WIDTH],
                left: [0; WIDTH],
                as_leaf: true,
                children: None,
            };
        };
        let (l, r) = (WidePlan::new(&children[0]), WidePlan::new(&children[1]));
        // shared[j - 1]: least cost of the two children as at most j slots together.
        let mut shared = [f32::INFINITY; WIDTH];
        let mut left = [0u8; WIDTH];
        for j in 2..=WIDTH {
            for i in 1..j {
                let c = l.cost[i - 1] + r.cost[j - i - 1];
                if c < shared[j - 1] {
                    shared[j - 1] = c;
                    left[j - 1] = i as u8;
                }
            }
        }
        let as_node = area * TRAVERSAL_COST + shared[WIDTH - 1];
        let refs = l.refs + r.refs;
        let as_leaf_cost = if refs <= MAX_LEAF { area * leaf_cost(refs) } else { f32::INFINITY };
        let one = as_node.min(as_leaf_cost);
        let mut cost = [one; WIDTH];
        let mut spread = [0u8; WIDTH];
        for k in 2..=WIDTH {
            cost[k - 1] = cost[k - 2];
            spread[k - 1] = spread[k - 2];
            if shared[k - 1] < cost[k - 1] {
                cost[k - 1] = shared[k - 1];
                spread[k - 1] = k as u8;
            }
        }
        WidePlan { node, refs, cost, spread, left, as_leaf: as_leaf_cost < as_node, children: Some(Box::new([l, r])) }
    }

    /// The slots of this subtree when it may take at most `k` of them.
    fn slots<'p>(&'p self, k: usize, out: &mut Vec<&'p WidePlan<'a>>) {
        match self.spread[k - 1] {
            0 => out.push(self),
            j => self.children_slots(j as usize, out),
        }
    }

    /// The slots of this interior subtree's children when they share at most `j`.
    fn children_slots<'p>(&'p self, j: usize, out: &mut Vec<&'p WidePlan<'a>>) {
        let children = self.children.as_ref().expect("only interior nodes share slots");
        let i = self.left[j - 1] as usize;
        children[0].slots(i, out);
        children[1].slots(j - i, out);
    }

    /// Levels of the wide tree below and including this slot.
    fn depth(&self) -> usize {
        if self.as_leaf {
            return 0;
        }
        let mut slots = Vec::with_capacity(WIDTH);
        self.children_slots(WIDTH, &mut slots);
        1 + slots.iter().map(|s| s.depth()).max().unwrap_or(0)
    }

    /// The triangles (with repeats from spatial splits removed) of a slot made a leaf.
    fn leaf_prims(&self) -> Vec<u32> {
        fn gather(node: &BuildNode, out: &mut Vec<u32>) {
            match node {
                BuildNode::Leaf { prims, .. } => out.extend_from_slice(prims),
                BuildNode::Interior { children, .. } => children.iter().for_each(|c| gather(c, out)),
            }
        }
        let mut prims = Vec::new();
        gather(self.node, &mut prims);
        prims.sort_unstable();
        prims.dedup();
        prims
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
    /// long slivers and large diagonal faces spatial splits cut up), half of those nearly
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
        assert!(stats.references >= tris.len() && stats.references <= tris.len() * 3 / 2 + 1, "{stats:?}");
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

    /// Spatial splits cut the references of large triangles; the pieces together must still
    /// cover every triangle, to the last ulp next to the cut planes. Rays aimed at random
    /// points of the large triangles must find them (or something nearer).
    #[test]
    fn split_triangles_stay_covered() {
        let mut rng = Rng::new(9, 0, 0);
        let tris = random_soup(5000, 12.0, &mut rng);
        let bvh = Bvh::build(&tris);
        assert!(bvh.stats().references > tris.len(), "no spatial split happened: {:?}", bvh.stats());
        let large: Vec<&BuildTriangle> = tris.iter().step_by(10).collect();
        let mut checked = 0;
        for _ in 0..20_000 {
            let t = large[(rng.next_f32() * large.len() as f32) as usize % large.len()];
            let (u, v) = (rng.next_f32(), rng.next_f32());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let target = t.v[0] + (t.v[1] - t.v[0]) * u + (t.v[2] - t.v[0]) * v;
            let o = target + uniform_sphere(rng.next_2d()) * 3.0;
            let ray = Ray { o, d: target - o, tmax: f32::INFINITY };
            let pre = RayPrecomp::new(&ray);
            let Some((t_exact, _, _)) = intersect_triangle(&ray, &pre, &t.v, f32::INFINITY) else { continue };
            checked += 1;
            let hit = bvh.intersect(&ray, &NoFilter).expect("a ray aimed at a triangle hits something");
            assert!(hit.t <= t_exact, "missed the triangle at t {t_exact}: found {}", hit.t);
        }
        // Only rays that graze an edge (rounding of the aimed point) may miss their triangle.
        assert!(checked > 19_000, "only {checked} rays met their triangle");
    }

    /// The wide tree written out has the cost the dynamic programme found for it, so the
    /// slots it recorded are the ones that reach its optimum.
    #[test]
    fn collapse_reaches_the_planned_cost() {
        let mut rng = Rng::new(7, 0, 0);
        for large in [0.0, 0.3] {
            let tris = random_soup(3000, large, &mut rng);
            let root = binary_tree(&tris);
            let plan = WidePlan::new(&root);
            let planned = plan.cost[0] / node_bounds(&root).half_area();
            let built = Bvh::build(&tris).stats().sah_cost;
            assert!((planned - built).abs() <= 1e-4 * built, "planned {planned}, built {built}");
        }
    }

    /// Least cost of `node` as one slot, by trying every set of at most eight descendants
    /// that covers each wide node's triangles, independently of the dynamic programme.
    fn brute_force_slot_cost(node: &BuildNode) -> f32 {
        fn refs(node: &BuildNode) -> usize {
            match node {
                BuildNode::Leaf { prims, .. } => prims.len(),
                BuildNode::Interior { children, .. } => children.iter().map(refs).sum(),
            }
        }
        /// Every antichain of at most `k` nodes at or below `node` that covers its leaves.
        fn covers(node: &BuildNode, k: usize) -> Vec<Vec<&BuildNode>> {
            let mut all = vec![vec![node]];
            if let (BuildNode::Interior { children, .. }, 2..) = (node, k) {
                for a in covers(&children[0], k - 1) {
                    for b in covers(&children[1], k - a.len()) {
                        all.push(a.iter().chain(&b).copied().collect());
                    }
                }
            }
            all
        }
        let area = node_bounds(node).half_area();
        let BuildNode::Interior { children, .. } = node else { return area * leaf_cost(refs(node)) };
        let as_leaf = if refs(node) <= MAX_LEAF { area * leaf_cost(refs(node)) } else { f32::INFINITY };
        let mut best_cover = f32::INFINITY;
        for a in covers(&children[0], WIDTH - 1) {
            for b in covers(&children[1], WIDTH - a.len()) {
                best_cover = best_cover.min(a.iter().chain(&b).map(|n| brute_force_slot_cost(n)).sum());
            }
        }
        as_leaf.min(area * TRAVERSAL_COST + best_cover)
    }

    /// On small trees, the dynamic programme finds the least cost that trying every
    /// grouping finds.
    #[test]
    fn collapse_plan_is_optimal() {
        let mut rng = Rng::new(11, 0, 0);
        for n in [12, 24, 40] {
            let tris = random_soup(n, 0.3, &mut rng);
            let root = binary_tree(&tris);
            let planned = WidePlan::new(&root).cost[0];
            let brute = brute_force_slot_cost(&root);
            assert!((planned - brute).abs() <= 1e-5 * brute, "{n} triangles: planned {planned}, brute force {brute}");
        }
    }

    #[test]
    fn empty_bvh_hits_nothing() {
        let bvh = Bvh::build(&[]);
        let ray = Ray::new(Vec3::ZERO, vec3(0.0, 0.0, 1.0));
        assert!(bvh.intersect(&ray, &NoFilter).is_none());
    }
}
