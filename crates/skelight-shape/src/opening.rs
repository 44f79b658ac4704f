//! The 26-opening map and an opening forest of a set (thesis §10.3.1 and §10.3.3,
//! Alg. 6–7). With D the chessboard distance to the outside, the maximal ball of a voxel y is
//! the cube B(y) = {x : d∞(x, y) < D(y)}; the opening π(x) is the largest D(y) over the balls
//! that contain x, and the forest links x to the centre of one such ball (itself when its
//! own ball is the largest). Cubes are products of intervals, so the dilation is separable:
//! each axis line is dilated forwards and backwards with a queue of the balls still
//! covering the current voxel, in time linear in the number of voxels.

use std::collections::VecDeque;

use crate::distance::par_lines;
use rayon::prelude::*;

use crate::grid::{axis_neighbours, Grid, GridSpec, Padded};
use crate::simd::raise_to;

/// The opening map and an opening forest.
pub struct Opening {
    pub spec: GridSpec,
    /// (π(x), centre) of every voxel x, side by side as the dilation leaves them: the
    /// labelling reads both, and parting them took a serial pass and twice the memory.
    balls: Vec<(u32, u32)>,
}

impl Opening {
    /// π(x) of voxel `x` (linear index): the radius of the largest maximal ball containing
    /// it, 0 outside the set.
    #[inline]
    pub fn radius(&self, x: usize) -> u32 {
        self.balls[x].0
    }

    /// The linear index of the centre of a maximal ball of radius π(x) containing voxel
    /// `x`: x itself exactly when π(x) = D(x) (Def. 10.7).
    #[inline]
    pub fn centre(&self, x: usize) -> usize {
        self.balls[x].1 as usize
    }
}

/// Computes the opening map and forest from the chessboard distance map `distance`
/// (see [`crate::distance::chessboard`]).
pub fn opening(distance: &Grid<u32>) -> Opening {
    let spec = distance.spec;
    assert!(spec.len() <= u32::MAX as usize, "grid too large for 32-bit voxel indices");
    // Radius and centre side by side, so that a line is one slice.
    let mut balls: Vec<(u32, u32)> = distance.data.par_iter().enumerate().map(|(c, &r)| (r, c as u32)).collect();
    for axis in 0..3 {
        par_lines(&mut balls, spec.dims, axis, |line| {
            let mut rest = VecDeque::new();
            dilate_line(line.iter_mut(), &mut rest);
            dilate_line(line.iter_mut().rev(), &mut rest);
        });
    }
    Opening { spec, balls }
}

/// A ball seen along one line: its radius, its centre and the first position (counted in
/// the scan's direction) it no longer covers.
#[derive(Clone, Copy)]
struct LineBall {
    radius: u32,
    centre: u32,
    end: u64,
}

/// Alg. 7 on one line of (radius, centre) pairs, in the order given (forwards or
/// backwards): every voxel takes the largest ball, among those met so far, that still
/// covers it. The candidates are held by decreasing radius and increasing reach: the
/// largest, the one each voxel takes, in `front`, and those behind it in `rest`; at equal
/// radius the voxel's own entry wins, so a voxel whose own ball is the largest stays a
/// root. Holding the front apart keeps the common cases (a voxel starting a new front, or
/// taking the one held) in registers: with the whole queue in a `VecDeque`, each voxel
/// read its answer back from the queue's memory (door opening, one thread: 39 -> 24.5 ms).
/// A radius-0 voxel (outside the set) ends every ball, as balls lie inside the set; it is
/// taken as its own front all the same, so the lines need not come from a distance map.
fn dilate_line<'a>(line: impl Iterator<Item = &'a mut (u32, u32)>, rest: &mut VecDeque<LineBall>) {
    // Radius 0: no ball (any voxel's ball replaces it).
    const NONE: LineBall = LineBall { radius: 0, centre: 0, end: 0 };
    let mut front = NONE;
    rest.clear();
    for (step, ball) in line.enumerate() {
        let current = LineBall { radius: ball.0, centre: ball.1, end: step as u64 + ball.0 as u64 };
        if front.end == step as u64 {
            front = rest.pop_front().unwrap_or(NONE);
        }
        if current.radius != 0 && current.radius < front.radius {
            while rest.back().is_some_and(|b| current.radius >= b.radius) {
                rest.pop_back();
            }
            if rest.back().unwrap_or(&front).end < current.end {
                rest.push_back(current);
            }
        } else {
            rest.clear();
            front = current;
        }
        *ball = (front.radius, front.centre);
    }
}

/// The L1 opening function π₁ (thesis §6.2.2): for every voxel, the largest D₁(y) over the
/// maximal L1 balls {x : d₁(x, y) < D₁(y)} that contain it; 0 outside the set. Balls are
/// spread in decreasing order of radius by a breadth-first walk with a step budget, so a
/// voxel keeps the first (largest) radius that reaches it. `l1` is the L1 distance map.
///
/// A walk stops at a voxel that an earlier walk (a ball at least as large) reached with at
/// least the budget it has left: a ball lies inside the set and is 6-connected by monotone
/// paths, so everything it could still reach from there lies in the earlier ball and has
/// its radius already. Each voxel is thus entered only when its best budget rises.
pub fn l1_opening(l1: &Grid<u32>) -> Grid<u32> {
    let spec = l1.spec;
    let max_radius = l1.data.iter().copied().max().unwrap_or(0) as usize;
    assert!(
        max_radius <= spec.dims.iter().sum::<usize>(),
        "l1_opening wants an L1 distance map with a finite border (from `l1(set, true)`)"
    );
    // A radius is at most half the grid's shortest side, far below 2¹⁶ for any grid that
    // fits in memory: 16-bit maps halve the walks' memory traffic.
    assert!(max_radius < u16::MAX as usize, "an L1 radius of {max_radius} voxels does not fit in 16 bits");
    // Radius 0 around the grid: walks stop there as they do outside the set.
    let layout = Padded::new(spec.dims);
    let d: Vec<u16> = layout.pad(&l1.data, 0, |r| r as u16);
    let strides = layout.strides();
    let ridges: Vec<usize> = ridges(l1).into_iter().map(|([x, y, z], _)| layout.index(x, y, z)).collect();
    // Centres by radius (a counting sort: radii are small), largest first. first[r]: where
    // radius r starts among the centres.
    let mut first = vec![0u32; max_radius + 2];
    ridges.iter().for_each(|&i| first[d[i] as usize + 1] += 1);
    for r in 1..first.len() {
        first[r] += first[r - 1];
    }
    let mut centres = vec![0u32; ridges.len()];
    let mut fill = first.clone();
    for i in ridges {
        let r = d[i] as usize;
        centres[fill[r] as usize] = i as u32;
        fill[r] += 1;
    }
    let mut opening = vec![0u16; d.len()];
    // Largest budget left (+1) with which any walk so far reached a voxel; 0 = never.
    let mut reached = vec![0u16; d.len()];
    let mut frontier: Vec<u32> = Vec::new();
    let mut next: Vec<u32> = Vec::new();
    let mut enter = |j: usize, budget: u16, r: u16, list: &mut Vec<u32>| {
        if reached[j] < budget {
            reached[j] = budget;
            if opening[j] == 0 {
                opening[j] = r;
            }
            list.push(j as u32);
        }
    };
    for r in (1..=max_radius).rev() {
        let r = r as u16;
        for &i in &centres[first[r as usize] as usize..first[r as usize + 1] as usize] {
            enter(i as usize, r, r, &mut frontier);
        }
        // Budget b = r − steps; a voxel at L1 distance < r from a centre gets b ≥ 1.
        let mut budget = r;
        while budget > 1 && !frontier.is_empty() {
            budget -= 1;
            for &i in &frontier {
                let i = i as usize;
                for j in axis_neighbours(i, strides) {
                    if d[j] > 0 {
                        enter(j, budget, r, &mut next);
                    }
                }
            }
            std::mem::swap(&mut frontier, &mut next);
            next.clear();
        }
        frontier.clear();
    }
    Grid { spec, data: layout.unpad(&opening).into_iter().map(u32::from).collect() }
}

/// π₁ (see [`l1_opening`]) at the given voxels only (linear indices), for when few are
/// wanted: Alg. 3 needs it around the few hundred edges whose lifespan could pass its test
/// (door: 383 of 5.8 M edges), and walking every ball would cost the whole map.
///
/// Each ridge centre (as in [`l1_opening`], the only balls that matter) raises the wanted
/// voxels its ball contains; the wanted voxels are bucketed in cubes of `BUCKET` voxels,
/// so a centre looks only at the buckets its ball's bounding box meets, and a centre whose
/// box holds no wanted voxel at all (door: most of its 96 k ridges) is passed over after
/// one look at the buckets' running counts.
pub fn l1_opening_at(l1: &Grid<u32>, voxels: &[usize]) -> Vec<u32> {
    let spec = l1.spec;
    let buckets_dims = spec.dims.map(|n| n.div_ceil(BUCKET));
    let bucket_of = |p: [usize; 3]| (p[2] / BUCKET * buckets_dims[1] + p[1] / BUCKET) * buckets_dims[0] + p[0] / BUCKET;
    // The wanted voxels by bucket, as a compressed list: bucket b holds
    // wanted[start[b]..start[b + 1]], each a position and its place in `voxels`.
    let mut start = vec![0usize; buckets_dims.iter().product::<usize>() + 1];
    let positions: Vec<[usize; 3]> = voxels.iter().map(|&v| spec.coords(v)).collect();
    positions.iter().for_each(|&p| start[bucket_of(p) + 1] += 1);
    for b in 1..start.len() {
        start[b] += start[b - 1];
    }
    // Coordinates apart, one array per axis, so that a run of wanted voxels is tested as
    // one vectorised loop ([`raise_covered`]); `place[j]` is where the j-th lies in `voxels`.
    let mut coords = [vec![0i32; voxels.len()], vec![0i32; voxels.len()], vec![0i32; voxels.len()]];
    let mut place = vec![0usize; voxels.len()];
    let mut fill = start.clone();
    for (k, &p) in positions.iter().enumerate() {
        let b = bucket_of(p);
        for a in 0..3 {
            coords[a][fill[b]] = p[a] as i32;
        }
        place[fill[b]] = k;
        fill[b] += 1;
    }
    let held = BoxCounts::new(buckets_dims, |b| start[b + 1] - start[b]);
    let raise = |mut best: Vec<u32>, &(y, r): &([usize; 3], u32)| {
        // The ball {x : d₁(x, y) < r} lies in the box y ± (r − 1).
        let reach = r as usize - 1;
        let lo = y.map(|c| c.saturating_sub(reach) / BUCKET);
        let hi = [0, 1, 2].map(|a| (y[a] + reach).min(spec.dims[a] - 1) / BUCKET);
        if !held.any(lo, hi) {
            return best;
        }
        // Buckets follow one another along x, so each row of the box is one run.
        for bz in lo[2]..=hi[2] {
            for by in lo[1]..=hi[1] {
                let row = (bz * buckets_dims[1] + by) * buckets_dims[0];
                let run = start[row + lo[0]]..start[row + hi[0] + 1];
                let [xs, ys, zs] = [0, 1, 2].map(|a| &coords[a][run.clone()]);
                raise_covered(&mut best[run.clone()], [xs, ys, zs], y.map(|c| c as i32), r);
            }
        }
        best
    };
    let zero = || vec![0u32; voxels.len()];
    let by_bucket = ridges(l1).par_iter().fold(zero, raise).reduce(zero, |mut a, b| {
        raise_to(&mut a, &b);
        a
    });
    let mut opening = vec![0; voxels.len()];
    for (j, &k) in place.iter().enumerate() {
        opening[k] = by_bucket[j];
    }
    opening
}

crate::simd::avx2_dispatch! {
    /// Raises `best` to `r` at the points (coordinates by axis) that lie in the L1 ball
    /// {x : d₁(x, centre) < r}.
    fn raise_covered(best: &mut [u32], coords: [&[i32]; 3], centre: [i32; 3], r: u32) => raise_covered_kernel
}

/// No branch, so the loop vectorises: a row of buckets holds tens of points, most of them
/// outside the ball (door: 2.2 M tests; the pass over the ridges, one thread, 4.0 -> 2.0 ms
/// against a test per point with its position and place side by side).
#[inline(always)]
fn raise_covered_kernel(best: &mut [u32], [xs, ys, zs]: [&[i32]; 3], [cx, cy, cz]: [i32; 3], r: u32) {
    let n = best.len();
    let (xs, ys, zs) = (&xs[..n], &ys[..n], &zs[..n]);
    for j in 0..n {
        let distance = ((xs[j] - cx).abs() + (ys[j] - cy).abs() + (zs[j] - cz).abs()) as u32;
        best[j] = if distance < r { best[j].max(r) } else { best[j] };
    }
}

/// Running counts over a small 3-D grid of cells (the buckets of [`l1_opening_at`]), to
/// tell in eight reads whether a box of cells holds anything.
struct BoxCounts {
    dims: [usize; 3],
    /// `sums[(z·(ny+1) + y)·(nx+1) + x]`: the total over the cells below (x, y, z) on
    /// every axis.
    sums: Vec<usize>,
}

impl BoxCounts {
    fn new(dims: [usize; 3], count: impl Fn(usize) -> usize) -> BoxCounts {
        let [nx, ny, nz] = dims;
        let at = |x: usize, y: usize, z: usize| (z * (ny + 1) + y) * (nx + 1) + x;
        let mut sums = vec![0; (nx + 1) * (ny + 1) * (nz + 1)];
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let own = count((z * ny + y) * nx + x);
                    sums[at(x + 1, y + 1, z + 1)] =
                        own + sums[at(x, y + 1, z + 1)] + sums[at(x + 1, y, z + 1)] + sums[at(x + 1, y + 1, z)]
                            - sums[at(x, y, z + 1)]
                            - sums[at(x, y + 1, z)]
                            - sums[at(x + 1, y, z)]
                            + sums[at(x, y, z)];
                }
            }
        }
        BoxCounts { dims, sums }
    }

    /// Whether the cells from `lo` to `hi` (inclusive) hold anything.
    fn any(&self, lo: [usize; 3], hi: [usize; 3]) -> bool {
        let [nx, ny, _] = self.dims;
        let at = |x: usize, y: usize, z: usize| self.sums[(z * (ny + 1) + y) * (nx + 1) + x];
        let [x0, y0, z0] = lo;
        let [x1, y1, z1] = hi.map(|c| c + 1);
        let inside = at(x1, y1, z1) + at(x0, y0, z1) + at(x0, y1, z0) + at(x1, y0, z0);
        let outside = at(x0, y1, z1) + at(x1, y0, z1) + at(x1, y1, z0) + at(x0, y0, z0);
        inside > outside
    }
}

/// Side, in voxels, of the cubes in which [`l1_opening_at`] buckets the wanted voxels.
const BUCKET: usize = 16;

/// The ridges of the L1 map `l1`, with their distances, in the grid's order: voxels of the
/// set with no 6-neighbour (inside the grid) of larger distance. A ball whose centre has a
/// 6-neighbour with a larger radius lies inside that one's ball, so only the balls of
/// ridges matter to the opening. Planes in parallel, each row compared whole with the
/// largest of its neighbours, so the loops vectorise (door: 2.0–2.6 ms, against 4.5 over a
/// padded copy voxel by voxel, which took 4.7 ms more to make). Taking a voxel that is not
/// a ridge only costs time: its ball is a ball of the set all the same.
fn ridges(l1: &Grid<u32>) -> Vec<([usize; 3], u32)> {
    let [w, h, d] = l1.spec.dims;
    let zeros = vec![0; w];
    (0..d)
        .into_par_iter()
        .flat_map_iter(|z| {
            let mut found = Vec::new();
            let mut around = vec![0; w];
            for y in 0..h {
                let here = l1.row(y, z);
                let (y, z) = (y as isize, z as isize);
                around.fill(0);
                for r in [l1.row_at(y - 1, z), l1.row_at(y + 1, z), l1.row_at(y, z - 1), l1.row_at(y, z + 1)] {
                    raise_to(&mut around, r.unwrap_or(&zeros));
                }
                // The x neighbours (none beyond the row's ends).
                raise_to(&mut around[1..], here);
                raise_to(&mut around[..w - 1], &here[1..]);
                // Few voxels are ridges (door: 1 in 20): blocks without one are passed over
                // by one vectorised test.
                for (b, (here, around)) in here.chunks(16).zip(around.chunks(16)).enumerate() {
                    let is_ridge = |(&r, &m): (&u32, &u32)| r > 0 && r >= m;
                    if here.iter().zip(around).fold(false, |any, pair| any | is_ridge(pair)) {
                        for (x, pair) in here.iter().zip(around).enumerate().filter(|&(_, pair)| is_ridge(pair)) {
                            found.push(([16 * b + x, y as usize, z as usize], *pair.0));
                        }
                    }
                }
            }
            found
        })
        .collect()
}

/// Decenterness DC₁ = π₁ − D₁ (Def. 6.4): 0 on the centres of the largest balls, growing
/// towards the border of thin parts that lie inside larger balls.
pub fn decenterness(l1: &Grid<u32>) -> Grid<u32> {
    let opening = l1_opening(l1);
    let data = opening.data.iter().zip(&l1.data).map(|(&o, &d)| o.saturating_sub(d)).collect();
    Grid { spec: l1.spec, data }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::chessboard;
    use crate::grid::GridSpec;
    use crate::testing::{random_set, set_from};

    fn coords(spec: &GridSpec, i: usize) -> [i64; 3] {
        let [nx, ny, _] = spec.dims;
        [(i % nx) as i64, ((i / nx) % ny) as i64, (i / (nx * ny)) as i64]
    }

    fn chebyshev(a: [i64; 3], b: [i64; 3]) -> u64 {
        (0..3).map(|k| (a[k] - b[k]).unsigned_abs()).max().unwrap()
    }

    /// Def. 10.4 by brute force, and Def. 10.7 checked for the forest.
    #[test]
    fn opening_and_forest_match_their_definitions() {
        for (i, dims) in [[9, 7, 6], [1, 12, 5], [14, 4, 3], [6, 6, 6]].into_iter().enumerate() {
            for density in [0.03, 0.15, 0.4] {
                for border in [true, false] {
                    let set = random_set(dims, 7 + i as u64, density);
                    let d = chessboard(&set, border);
                    if d.data.iter().any(|&v| v >= u32::MAX / 4) {
                        continue; // no outside at all: every ball is unbounded
                    }
                    let o = opening(&d);
                    let spec = set.spec;
                    for x in 0..spec.len() {
                        let cx = coords(&spec, x);
                        let expected = (0..spec.len())
                            .filter(|&y| chebyshev(cx, coords(&spec, y)) < d.data[y] as u64)
                            .map(|y| d.data[y])
                            .max()
                            .unwrap_or(0);
                        assert_eq!(o.radius(x), expected, "{dims:?} {density} {border}: opening at {cx:?}");
                        if expected == 0 {
                            continue;
                        }
                        let c = o.centre(x);
                        assert_eq!(d.data[c], expected, "the forest links to a ball of radius π(x)");
                        assert!(chebyshev(cx, coords(&spec, c)) < d.data[c] as u64, "x lies in its parent's ball");
                        assert_eq!(c == x, expected == d.data[x], "roots are exactly the voxels with π = D");
                    }
                }
            }
        }
    }

    /// π₁ by its definition, brute force.
    #[test]
    fn l1_opening_matches_its_definition() {
        use crate::distance::l1;
        for (i, dims) in [[9, 7, 6], [1, 12, 5], [11, 4, 3]].into_iter().enumerate() {
            for density in [0.03, 0.15, 0.4] {
                let set = random_set(dims, 5 + i as u64, density);
                let d = l1(&set, true);
                let o = l1_opening(&d);
                let dc = decenterness(&d);
                let spec = set.spec;
                for x in 0..spec.len() {
                    let cx = coords(&spec, x);
                    let expected = (0..spec.len())
                        .filter(|&y| {
                            let cy = coords(&spec, y);
                            (0..3).map(|k| (cx[k] - cy[k]).unsigned_abs()).sum::<u64>() < d.data[y] as u64
                        })
                        .map(|y| d.data[y])
                        .max()
                        .unwrap_or(0);
                    assert_eq!(o.data[x], expected, "{dims:?} {density}: π₁ at {cx:?}");
                    assert_eq!(dc.data[x], expected.saturating_sub(d.data[x]));
                }
                // At a few voxels only, in no particular order.
                let some: Vec<usize> = (0..spec.len()).rev().step_by(3).collect();
                let at = l1_opening_at(&d, &some);
                for (&x, &value) in some.iter().zip(&at) {
                    assert_eq!(value, o.data[x], "{dims:?} {density}: π₁ at voxel {x} alone");
                }
            }
        }
    }

    /// On a grid several buckets wide, with scattered outside voxels so that balls of many
    /// radii meet.
    #[test]
    fn l1_opening_at_a_few_voxels_agrees_with_the_map() {
        use crate::distance::l1;
        for seed in 0..3 {
            let set = random_set([70, 37, 45], 20 + seed, 0.003);
            let d = l1(&set, true);
            let o = l1_opening(&d);
            // Many voxels, every bucket holding some; then a few, most buckets empty and
            // some holding one alone.
            let many: Vec<usize> = (0..set.spec.len()).step_by(97 + seed as usize).collect();
            let few: Vec<usize> = (0..set.spec.len()).step_by(9001 + seed as usize).collect();
            for some in [many, few] {
                let at = l1_opening_at(&d, &some);
                assert!(at.iter().any(|&r| r >= 4), "seed {seed}: too thin to tell");
                for (&x, &value) in some.iter().zip(&at) {
                    assert_eq!(value, o.data[x], "seed {seed}: π₁ at voxel {x} of {}", some.len());
                }
            }
        }
    }

    /// A room of 9×9×9 empty voxels joined to a 3-wide corridor: the room's voxels open to
    /// the room's ball (radius 5, its centre the room's centre), the corridor's to 2.
    #[test]
    fn a_room_opens_wider_than_its_corridor() {
        let set = set_from([20, 11, 11], 1.0, |x, y, z| {
            let room = (1..10).contains(&x) && (1..10).contains(&y) && (1..10).contains(&z);
            let corridor = (10..19).contains(&x) && (4..7).contains(&y) && (4..7).contains(&z);
            room || corridor
        });
        let spec = set.spec;
        let o = opening(&chessboard(&set, true));
        assert_eq!(o.radius(spec.index(1, 1, 1)), 5);
        assert_eq!(o.centre(spec.index(1, 1, 1)), spec.index(5, 5, 5));
        assert_eq!(o.radius(spec.index(15, 5, 5)), 2);
        assert_eq!(o.radius(spec.index(0, 0, 0)), 0);
    }
}
