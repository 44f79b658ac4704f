//! Distance maps of a binary grid: for every voxel of the set, the distance to the nearest
//! voxel outside it, in L1 (6-connected), chessboard (26-connected) and exact Euclidean
//! metrics, each in time linear in the number of voxels. Outside the grid counts as outside
//! the set when `border_is_outside` (the empty space of a scene is closed by its grid).

use std::sync::OnceLock;

use rayon::prelude::*;

use crate::grid::{Grid, GridSpec, Padded};
use crate::simd::lower_to_next;

const INF: u32 = u32::MAX / 4;

/// Calls `f` on every line of the grid along `axis` (dimensions `dims`, x fastest), each
/// as a contiguous slice from its low end, lines in parallel. Lines along y and z are
/// copied into a buffer and back, so that each task owns its lines as slices: a task takes
/// the lines of one plane (y) or of one y across the planes (z), all the rows they cross.
pub(crate) fn par_lines<T: Copy + Send + Sync>(
    data: &mut [T],
    dims: [usize; 3],
    axis: usize,
    f: impl Fn(&mut [T]) + Sync,
) {
    let [nx, ny, nz] = dims;
    if data.is_empty() {
        return;
    }
    // The lines crossing `rows` (voxel rows in order along the axis), one per x: copied
    // out into one buffer line after line, handed to `f` there and copied back. Whole rows
    // are read and written in order; one line at a time cost a value and a row pointer per
    // voxel, each row in a plane of its own (door opening, one thread: 45.5 -> 39 ms).
    let columns = |rows: &mut [&mut [T]], buffer: &mut Vec<T>| {
        let n = rows.len();
        buffer.clear();
        buffer.resize(nx * n, rows[0][0]);
        for (k, row) in rows.iter().enumerate() {
            for (x, &v) in row.iter().enumerate() {
                buffer[x * n + k] = v;
            }
        }
        buffer.chunks_exact_mut(n).for_each(&f);
        for (k, row) in rows.iter_mut().enumerate() {
            for (x, v) in row.iter_mut().enumerate() {
                *v = buffer[x * n + k];
            }
        }
    };
    match axis {
        0 => data.par_chunks_mut(nx).for_each(&f),
        1 => data.par_chunks_mut(nx * ny).for_each(|plane| {
            let mut rows: Vec<&mut [T]> = plane.chunks_mut(nx).collect();
            columns(&mut rows, &mut Vec::with_capacity(nx * ny));
        }),
        _ => rows_by_y(data, dims)
            .into_par_iter()
            .for_each(|mut rows| columns(&mut rows, &mut Vec::with_capacity(nx * nz))),
    }
}

/// The rows of the grid grouped by y, each group in order along z: the lines along z of
/// one group cross its rows.
fn rows_by_y<T>(data: &mut [T], [nx, ny, nz]: [usize; 3]) -> Vec<Vec<&mut [T]>> {
    let mut by_y: Vec<Vec<&mut [T]>> = (0..ny).map(|_| Vec::with_capacity(nz)).collect();
    for plane in data.chunks_mut(nx * ny) {
        for (y, row) in plane.chunks_mut(nx).enumerate() {
            by_y[y].push(row);
        }
    }
    by_y
}

fn init(set: &Grid<bool>) -> Vec<u32> {
    set.data.iter().map(|&inside| if inside { INF } else { 0 }).collect()
}

/// L1 distance: separable, one forward and one backward pass per axis. Along y and z the
/// passes step whole rows at a time, each row the minimum of itself and the row before plus
/// one, which vectorises over x (door: 11–17 → 4–6 ms, against copying every column out and
/// back).
pub fn l1(set: &Grid<bool>, border_is_outside: bool) -> Grid<u32> {
    let [nx, ny, _] = set.spec.dims;
    let mut d = init(set);
    let border = if border_is_outside { 0 } else { INF };
    if d.is_empty() {
        return Grid { spec: set.spec, data: d };
    }
    par_lines(&mut d, set.spec.dims, 0, |line| {
        let mut prev = border;
        for v in line.iter_mut() {
            prev = (*v).min(prev.saturating_add(1));
            *v = prev;
        }
        let mut prev = border;
        for v in line.iter_mut().rev() {
            prev = (*v).min(prev.saturating_add(1));
            *v = prev;
        }
    });
    // Rows of one plane (y) or of one y across the planes (z), in order along the axis.
    let sweep = |rows: &mut [&mut [u32]]| {
        let n = rows.len();
        let step = |rows: &mut [&mut [u32]], from: usize, to: usize| {
            let (from, to) = if from < to {
                let (a, b) = rows.split_at_mut(to);
                (&*a[from], &mut *b[0])
            } else {
                let (a, b) = rows.split_at_mut(from);
                (&*b[0], &mut *a[to])
            };
            lower_to_next(to, from);
        };
        // The border lies before the first row and after the last.
        for end in [0, n - 1] {
            for v in rows[end].iter_mut() {
                *v = (*v).min(border.saturating_add(1));
            }
        }
        for i in 1..n {
            step(rows, i - 1, i);
        }
        for i in (0..n - 1).rev() {
            step(rows, i + 1, i);
        }
    };
    d.par_chunks_mut(nx * ny).for_each(|plane| sweep(&mut plane.chunks_mut(nx).collect::<Vec<_>>()));
    rows_by_y(&mut d, set.spec.dims).into_par_iter().for_each(|mut rows| sweep(&mut rows));
    Grid { spec: set.spec, data: d }
}

/// Chessboard distance: two raster passes of the 26-neighbour chamfer mask with unit
/// weights (Rosenfeld & Pfaltz), exact for this metric. The grid is padded with the border's
/// value, and each row first takes the minimum of the four rows before it that the mask
/// reads (three x neighbours each) in one vectorisable sweep; only the x neighbour inside
/// the row is a running minimum.
///
/// Each pass runs on slabs of planes in parallel, each slab starting as if the plane before
/// it held no outside voxel, which can only leave its values too large. Then, slab after
/// slab in the pass's order, its planes are swept again from the true plane before, until
/// one comes out unchanged: every plane after it then saw the same values as the first
/// time. A second sweep keeps the smaller of the two values, which is the true one, since
/// the mask's minimum can only fall. On two threads the second sweeps cover 4 and 25 of
/// the door's 117-plane slabs, 32 and 24 of the classroom's 215.
pub fn chessboard(set: &Grid<bool>, border_is_outside: bool) -> Grid<u32> {
    // Slabs of at least 8 planes: a thinner one would be swept twice over most of its depth.
    chessboard_in_slabs(set, border_is_outside, rayon::current_num_threads().min(set.spec.dims[2] / 8))
}

/// [`chessboard`] with its passes cut into `slabs` slabs (at least one, at most one per plane).
fn chessboard_in_slabs(set: &Grid<bool>, border_is_outside: bool, slabs: usize) -> Grid<u32> {
    let [nx, ny, nz] = set.spec.dims;
    let layout = Padded::new(set.spec.dims);
    let [_, px, plane] = layout.strides();
    let border = if border_is_outside { 0 } else { INF };
    let mut d = layout.pad(&set.data, border, |inside| if inside { INF } else { 0 });
    if d.is_empty() || nz == 0 {
        return Grid { spec: set.spec, data: layout.unpad(&d) };
    }
    let outer = vec![border; plane];
    let unknown = vec![INF; plane];
    let slabs = slabs.clamp(1, nz);
    for forward in [true, false] {
        // The grid's planes in the pass's order, cut into slabs.
        let mut planes: Vec<&mut [u32]> = d.chunks_mut(plane).skip(1).take(nz).collect();
        if !forward {
            planes.reverse();
        }
        let mut slabs: Vec<&mut [&mut [u32]]> = planes.chunks_mut(nz.div_ceil(slabs)).collect();
        slabs.par_iter_mut().enumerate().for_each(|(k, slab)| {
            let mut before = vec![0u32; px];
            let mut back: &[u32] = if k == 0 { &outer } else { &unknown };
            for p in slab.iter_mut() {
                chessboard_plane(p, back, [nx, ny], px, forward, &mut before);
                back = p;
            }
        });
        let mut before = vec![0u32; px];
        for k in 1..slabs.len() {
            let (done, rest) = slabs.split_at_mut(k);
            let mut back: &[u32] = done[k - 1].last().expect("slabs are not empty");
            for p in rest[0].iter_mut() {
                if !chessboard_plane(p, back, [nx, ny], px, forward, &mut before) {
                    break;
                }
                back = p;
            }
        }
    }
    Grid { spec: set.spec, data: layout.unpad(&d) }
}

crate::simd::avx2_dispatch! {
    /// One plane of a raster pass of [`chessboard`] (padded, rows `px` cells apart), given
    /// the plane before it in the pass's order; `before` is scratch of one row. Whether any
    /// value fell.
    fn chessboard_plane(cur: &mut [u32], back: &[u32], dims: [usize; 2], px: usize, forward: bool, before: &mut [u32]) -> bool
        => chessboard_plane_kernel
}

#[inline(always)]
fn chessboard_plane_kernel(
    cur: &mut [u32],
    back: &[u32],
    [nx, ny]: [usize; 2],
    px: usize,
    forward: bool,
    before: &mut [u32],
) -> bool {
    let mut fell = false;
    for yi in 1..=ny {
        let y = if forward { yi } else { ny + 1 - yi };
        let row = y * px;
        // The row before in this plane and the three around it in the plane before.
        let same = if forward { row - px } else { row + px };
        for (x, b) in before.iter_mut().enumerate() {
            *b = cur[same + x].min(back[row - px + x]).min(back[row + x]).min(back[row + px + x]);
        }
        // Each voxel takes the least of its twelve neighbours before it outside its row,
        // plus one, in a loop that vectorises; then its neighbour before it in the row, a
        // running minimum whose chain is two operations a voxel, not five as when the two
        // went together (door chessboard, one thread: 8.7 -> 7.9 ms).
        let here = &mut cur[row..row + px];
        for (h, b) in here[1..=nx].iter_mut().zip(before.windows(3)) {
            fell |= lower_to(h, b[0].min(b[1]).min(b[2]) + 1);
        }
        let run = |prev: u32, h: &mut u32| {
            fell |= lower_to(h, prev + 1);
            *h
        };
        let (first, last) = (here[0], here[nx + 1]);
        if forward {
            here[1..=nx].iter_mut().fold(first, run);
        } else {
            here[1..=nx].iter_mut().rev().fold(last, run);
        }
    }
    fell
}

/// Lowers `h` to `v` if `v` is less; whether it fell. Branch-free, so that the loops over a
/// row vectorise.
#[inline(always)]
fn lower_to(h: &mut u32, v: u32) -> bool {
    let new = (*h).min(v);
    let fell = new < *h;
    *h = new;
    fell
}

/// Squared distances too far to be reached: sums of a few of these and of squared grid
/// sizes stay far inside i64.
const FAR: i64 = 1 << 50;

/// Exact squared Euclidean distance, separable (Meijster, Roerdink & Hesselink): along x the
/// distance to the nearest outside voxel of the line, then along y and z the lower
/// envelope of the parabolas (x − i)² + f(i), all in integers.
pub fn euclidean_squared(set: &Grid<bool>, border_is_outside: bool) -> Grid<u64> {
    let spec = set.spec;
    let mut d: Vec<i64> = row_gaps(set, border_is_outside).into_iter().map(gap_squared).collect();
    for axis in [1, 2] {
        par_lines(&mut d, spec.dims, axis, |line| {
            ENVELOPE.with_borrow_mut(|scratch| scratch.transform(line, border_is_outside));
        });
    }
    Grid { spec, data: d.into_iter().map(|v| if v >= FAR { u64::MAX } else { v as u64 }).collect() }
}

/// A row gap of [`row_gaps`] for a line with no outside voxel.
const NO_GAP: u32 = u32::MAX;

/// For every voxel, how many steps along its x line lead to the nearest voxel outside the
/// set (0 outside it; the border counts as outside at −1 and at nx when
/// `border_is_outside`), [`NO_GAP`] if the line has none.
fn row_gaps(set: &Grid<bool>, border_is_outside: bool) -> Vec<u32> {
    let mut gaps: Vec<u32> = set.data.iter().map(|&inside| if inside { NO_GAP } else { 0 }).collect();
    let beyond = if border_is_outside { 0 } else { NO_GAP };
    par_lines(&mut gaps, set.spec.dims, 0, |line| {
        // Steps from the last 0 before each voxel, then from the next 0 after it.
        let mut gap = beyond;
        for v in line.iter_mut() {
            gap = if *v == 0 { 0 } else { gap.saturating_add(1) };
            *v = gap;
        }
        gap = beyond;
        for v in line.iter_mut().rev() {
            gap = if *v == 0 { 0 } else { gap.saturating_add(1) };
            *v = gap.min(*v);
        }
    });
    gaps
}

/// A row gap squared, [`FAR`] for none.
fn gap_squared(gap: u32) -> i64 {
    if gap == NO_GAP {
        FAR
    } else {
        i64::from(gap).pow(2)
    }
}

/// [`euclidean_squared`] at one voxel at a time. The analysis wants the distance only at
/// its skeleton's node voxels (door: 3.2 k of 1.87 M), and the passes along y and z over
/// every line took 2 thirds of the map's time (door: 17.5 of 20 ms on one thread). So only
/// the pass along x is made in advance; a line's pass along y is made the first time a
/// voxel asks for it (door: 4 k of 34 k lines), and the pass along z is a search at the
/// voxel itself. A large skeleton in large rooms asks for most lines (classroom 430: 109 k
/// of 140 k for 160 k voxels), and the work moves from the maps to the graph (0.04 →
/// 0.13 s there). Making lines eight at a time, or into one array z fastest, was slower.
pub struct EuclideanRows {
    spec: GridSpec,
    /// [`row_gaps`] of the set.
    gaps: Vec<u32>,
    /// The squared distance to the nearest outside voxel in the same z plane along each
    /// line along y (x fastest, then z), made on demand.
    columns: Vec<OnceLock<Box<[i64]>>>,
    border_is_outside: bool,
}

impl EuclideanRows {
    pub fn new(set: &Grid<bool>, border_is_outside: bool) -> EuclideanRows {
        let [nx, _, nz] = set.spec.dims;
        EuclideanRows {
            spec: set.spec,
            gaps: row_gaps(set, border_is_outside),
            columns: (0..nx * nz).map(|_| OnceLock::new()).collect(),
            border_is_outside,
        }
    }

    /// The line along y at (x, z) after the pass along y: the squared distance of each of
    /// its voxels to the nearest outside voxel in its z plane.
    fn column(&self, x: usize, z: usize) -> &[i64] {
        let [nx, ny, _] = self.spec.dims;
        self.columns[z * nx + x].get_or_init(|| {
            let mut line: Vec<i64> = (0..ny).map(|y| gap_squared(self.gaps[(z * ny + y) * nx + x])).collect();
            ENVELOPE.with_borrow_mut(|scratch| scratch.transform(&mut line, self.border_is_outside));
            line.into_boxed_slice()
        })
    }

    /// The squared Euclidean distance of voxel `v` (linear index) to the nearest voxel
    /// outside the set, `u64::MAX` if none: the least of (z − z')² + the plane distance
    /// at z' along its z line, searched outwards from z while (z − z')² can still win.
    pub fn at(&self, v: usize) -> u64 {
        let [x, y, z] = self.spec.coords(v);
        let nz = self.spec.dims[2] as i64;
        let mut best = self.column(x, z)[y];
        let mut k = 1i64;
        // Past nz steps the line and its border are behind.
        while k * k < best && k <= nz {
            for zk in [z as i64 - k, z as i64 + k] {
                let here = if (0..nz).contains(&zk) {
                    self.column(x, zk as usize)[y]
                } else if self.border_is_outside && (zk == -1 || zk == nz) {
                    0
                } else {
                    FAR
                };
                best = best.min(k * k + here);
            }
            k += 1;
        }
        if best >= FAR {
            u64::MAX
        } else {
            best as u64
        }
    }
}

thread_local! {
    /// Each thread's buffers for [`Envelope::transform`], kept from line to line.
    static ENVELOPE: std::cell::RefCell<Envelope> = const { std::cell::RefCell::new(Envelope::new()) };
}

/// The lower envelope of parabolas along one line: the positions of the parabolas on it
/// and where each starts to be the lowest.
struct Envelope {
    f: Vec<i64>,
    owner: Vec<usize>,
    start: Vec<usize>,
}

impl Envelope {
    const fn new() -> Envelope {
        Envelope { f: Vec::new(), owner: Vec::new(), start: Vec::new() }
    }

    /// `line[q]` ← min over p of (q − p)² + line[p], with a 0 beyond each end when
    /// `padded` (an outside border).
    fn transform(&mut self, line: &mut [i64], padded: bool) {
        let pad = usize::from(padded);
        let n = line.len() + 2 * pad;
        self.f.clear();
        self.f.extend(std::iter::repeat_n(0, pad).chain(line.iter().copied()).chain(std::iter::repeat_n(0, pad)));
        let f = &self.f;
        let parabola = |x: usize, i: usize| (x as i64 - i as i64).pow(2) + f[i];
        // The first x where the parabola at u lies below the one at i < u.
        let sep = |i: usize, u: usize| {
            let (i, u) = (i as i64, u as i64);
            (u * u - i * i + f[u as usize] - f[i as usize]).div_euclid(2 * (u - i)) + 1
        };
        self.owner.clear();
        self.start.clear();
        self.owner.push(0);
        self.start.push(0);
        for u in 1..n {
            while let (Some(&i), Some(&x)) = (self.owner.last(), self.start.last()) {
                if parabola(x, i) <= parabola(x, u) {
                    break;
                }
                self.owner.pop();
                self.start.pop();
            }
            match self.owner.last() {
                None => {
                    self.owner.push(u);
                    self.start.push(0);
                }
                Some(&i) => {
                    let x = sep(i, u);
                    if x < n as i64 {
                        self.owner.push(u);
                        self.start.push(x as usize);
                    }
                }
            }
        }
        let mut k = self.owner.len() - 1;
        for x in (pad..n - pad).rev() {
            while self.start[k] > x {
                k -= 1;
            }
            line[x - pad] = parabola(x, self.owner[k]).min(FAR);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::random_set;

    /// Brute force over every outside voxel (and the virtual border ring when it counts).
    fn brute(set: &Grid<bool>, border: bool, metric: impl Fn([i64; 3]) -> u64) -> Vec<u64> {
        let [nx, ny, nz] = set.spec.dims.map(|d| d as i64);
        let mut outside = Vec::new();
        for z in -1..=nz {
            for y in -1..=ny {
                for x in -1..=nx {
                    let in_grid = x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz;
                    if (in_grid && !*set.get(x as usize, y as usize, z as usize)) || (!in_grid && border) {
                        outside.push([x, y, z]);
                    }
                }
            }
        }
        let mut out = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    out.push(outside.iter().map(|q| metric([x - q[0], y - q[1], z - q[2]])).min().unwrap_or(u64::MAX));
                }
            }
        }
        out
    }

    /// Cut into slabs, the chessboard passes sweep slabs again from the true plane before:
    /// deep into the next slab where the set is sparse, hardly at all where it is dense.
    #[test]
    fn chessboard_in_slabs_matches_brute_force() {
        for (i, dims) in [[9, 7, 40], [4, 3, 17]].into_iter().enumerate() {
            for density in [0.003, 0.05, 0.4] {
                for border in [true, false] {
                    let set = random_set(dims, 90 + i as u64, density);
                    let chb = brute(&set, border, |d| d.iter().map(|v| v.unsigned_abs()).max().unwrap());
                    for slabs in [1, 2, 3, 7, dims[2]] {
                        let ch = chessboard_in_slabs(&set, border, slabs).data;
                        let ch: Vec<u64> = ch.iter().map(|&v| if v >= INF { u64::MAX } else { v as u64 }).collect();
                        assert_eq!(ch, chb, "{dims:?} {density} {border} in {slabs} slabs");
                    }
                }
            }
        }
    }

    /// Longer lines than above, where the envelope holds many parabolas and drops some.
    #[test]
    fn euclidean_matches_brute_force_on_larger_grids() {
        for (i, dims) in [[23, 17, 9], [5, 31, 14]].into_iter().enumerate() {
            for density in [0.02, 0.15, 0.6] {
                for border in [true, false] {
                    let set = random_set(dims, 7 + i as u64, density);
                    let eub = brute(&set, border, |d| d.iter().map(|v| (v * v) as u64).sum());
                    assert_eq!(euclidean_squared(&set, border).data, eub, "{dims:?} {density} {border}");
                    let rows = EuclideanRows::new(&set, border);
                    let at: Vec<u64> = (0..set.spec.len()).map(|v| rows.at(v)).collect();
                    assert_eq!(at, eub, "{dims:?} {density} {border}: voxel by voxel");
                }
            }
        }
    }

    #[test]
    fn all_metrics_match_brute_force() {
        for (i, dims) in [[7, 5, 6], [1, 9, 4], [12, 3, 1]].into_iter().enumerate() {
            for density in [0.05, 0.3] {
                for border in [true, false] {
                    let set = random_set(dims, 31 + i as u64, density);
                    let l1b = brute(&set, border, |d| d.iter().map(|v| v.unsigned_abs()).sum());
                    let chb = brute(&set, border, |d| d.iter().map(|v| v.unsigned_abs()).max().unwrap());
                    let eub = brute(&set, border, |d| d.iter().map(|v| (v * v) as u64).sum());
                    let cap = |v: u64, inf: u64| if v >= inf { u64::MAX } else { v };
                    let l1 = l1(&set, border).data.iter().map(|&v| cap(v as u64, INF as u64)).collect::<Vec<_>>();
                    let ch =
                        chessboard(&set, border).data.iter().map(|&v| cap(v as u64, INF as u64)).collect::<Vec<_>>();
                    let eu = euclidean_squared(&set, border).data;
                    assert_eq!(l1, l1b, "L1 {dims:?} {density} {border}");
                    assert_eq!(ch, chb, "chessboard {dims:?} {density} {border}");
                    assert_eq!(eu, eub, "euclidean {dims:?} {density} {border}");
                    let rows = EuclideanRows::new(&set, border);
                    let at: Vec<u64> = (0..set.spec.len()).map(|v| rows.at(v)).collect();
                    assert_eq!(at, eub, "euclidean {dims:?} {density} {border}: voxel by voxel");
                }
            }
        }
    }
}
