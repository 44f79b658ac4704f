//! Dense 3D voxel grids over an axis-aligned box of the scene.

use std::mem::MaybeUninit;

/// Where a grid sits in the world: origin of voxel (0,0,0)'s lower corner, cubic voxel size
/// and dimensions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    pub origin: [f64; 3],
    pub voxel: f64,
    pub dims: [usize; 3],
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    #[error("the bounding box is empty or not finite")]
    EmptyBounds,
    #[error("resolution must be at least 1 on each side")]
    ZeroResolution,
    #[error("a {0}×{1}×{2} grid needs about {3} MiB, more than the {4} MiB allowed; choose a lower resolution")]
    TooLarge(usize, usize, usize, u64, u64),
}

/// Memory cap for one grid of one byte per voxel (the analysis keeps several).
pub const MAX_GRID_BYTES: u64 = 4 << 30;

impl GridSpec {
    /// Grid whose longest side has `resolution` voxels, over `min`–`max` grown by `margin`
    /// (a fraction of the longest side on each end; the seeds use 10 % in all).
    pub fn from_bounds(min: [f64; 3], max: [f64; 3], resolution: usize, margin: f64) -> Result<GridSpec, GridError> {
        if resolution == 0 {
            return Err(GridError::ZeroResolution);
        }
        let ext: Vec<f64> = (0..3).map(|i| max[i] - min[i]).collect();
        if ext.iter().any(|e| !(e.is_finite() && *e >= 0.0)) || ext.iter().all(|e| *e == 0.0) {
            return Err(GridError::EmptyBounds);
        }
        let longest = ext.iter().cloned().fold(0.0, f64::max);
        let grow = longest * margin;
        let voxel = (longest + 2.0 * grow) / resolution as f64;
        let dims = [0, 1, 2].map(|i| (((ext[i] + 2.0 * grow) / voxel).ceil() as usize).max(1));
        let origin = [0, 1, 2].map(|i| min[i] - grow - (dims[i] as f64 * voxel - ext[i] - 2.0 * grow) * 0.5);
        let spec = GridSpec { origin, voxel, dims };
        spec.check_memory(1)?;
        Ok(spec)
    }

    /// Grid of exactly `dims` cubic voxels over `min`–`max` grown by `margin`, the voxel as
    /// small as lets the box fit, the box centred in the grid.
    pub fn from_bounds_dims(
        min: [f64; 3],
        max: [f64; 3],
        dims: [usize; 3],
        margin: f64,
    ) -> Result<GridSpec, GridError> {
        if dims.contains(&0) {
            return Err(GridError::ZeroResolution);
        }
        let ext: Vec<f64> = (0..3).map(|i| max[i] - min[i]).collect();
        if ext.iter().any(|e| !(e.is_finite() && *e >= 0.0)) || ext.iter().all(|e| *e == 0.0) {
            return Err(GridError::EmptyBounds);
        }
        let grow = ext.iter().cloned().fold(0.0, f64::max) * margin;
        let voxel = (0..3).map(|i| (ext[i] + 2.0 * grow) / dims[i] as f64).fold(0.0, f64::max);
        let origin = [0, 1, 2].map(|i| min[i] - grow - (dims[i] as f64 * voxel - ext[i] - 2.0 * grow) * 0.5);
        let spec = GridSpec { origin, voxel, dims };
        spec.check_memory(1)?;
        Ok(spec)
    }

    /// Refuses grids whose `bytes_per_voxel` storage would exceed [`MAX_GRID_BYTES`], before
    /// anything is allocated.
    pub fn check_memory(&self, bytes_per_voxel: u64) -> Result<(), GridError> {
        let [x, y, z] = self.dims;
        let n = (x as u64).saturating_mul(y as u64).saturating_mul(z as u64).saturating_mul(bytes_per_voxel);
        if n > MAX_GRID_BYTES {
            return Err(GridError::TooLarge(x, y, z, n >> 20, MAX_GRID_BYTES >> 20));
        }
        Ok(())
    }

    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        (z * self.dims[1] + y) * self.dims[0] + x
    }
    /// Grid coordinates of the voxel with linear index `i`.
    #[inline]
    pub fn coords(&self, i: usize) -> [usize; 3] {
        let [nx, ny, _] = self.dims;
        [i % nx, (i / nx) % ny, i / (nx * ny)]
    }
    /// The voxel `d` steps from `v`, if it lies inside the grid.
    #[inline]
    pub fn offset(&self, v: [usize; 3], d: [i64; 3]) -> Option<[usize; 3]> {
        let mut u = [0; 3];
        for a in 0..3 {
            let c = v[a] as i64 + d[a];
            if c < 0 || c >= self.dims[a] as i64 {
                return None;
            }
            u[a] = c as usize;
        }
        Some(u)
    }
    /// World position of a voxel's centre.
    pub fn center(&self, x: usize, y: usize, z: usize) -> [f64; 3] {
        let c = [x, y, z];
        [0, 1, 2].map(|i| self.origin[i] + (c[i] as f64 + 0.5) * self.voxel)
    }
}

/// Values on a grid, x fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid<T> {
    pub spec: GridSpec,
    pub data: Vec<T>,
}

impl<T: Clone> Grid<T> {
    pub fn new(spec: GridSpec, value: T) -> Grid<T> {
        Grid { spec, data: vec![value; spec.len()] }
    }
    #[inline]
    pub fn get(&self, x: usize, y: usize, z: usize) -> &T {
        &self.data[self.spec.index(x, y, z)]
    }
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, z: usize, v: T) {
        let i = self.spec.index(x, y, z);
        self.data[i] = v;
    }
    /// The voxels of row (y, z), x from 0.
    #[inline]
    pub fn row(&self, y: usize, z: usize) -> &[T] {
        let w = self.spec.dims[0];
        &self.data[self.spec.index(0, y, z)..][..w]
    }
    /// Row (y, z) if it lies inside the grid.
    #[inline]
    pub fn row_at(&self, y: isize, z: isize) -> Option<&[T]> {
        let [_, h, d] = self.spec.dims;
        ((0..h as isize).contains(&y) && (0..d as isize).contains(&z)).then(|| self.row(y as usize, z as usize))
    }
}

/// The positions i where `flags[i]` and `pred(i)` hold, in increasing order, found in
/// parallel by blocks (rayon's own `filter().collect()` costs about ten times more over
/// millions of cells), passing over runs of 64 false flags with one vectorised test. For
/// the few faces left in a large complex after thinning (door: 58 850 of 15.6 M cells,
/// 10.8 ms testing every cell, 1.4 ms eight flags at a time, 0.5 ms 64 at a time).
pub(crate) fn par_flagged_positions(flags: &[bool], pred: impl Fn(usize) -> bool + Sync) -> Vec<usize> {
    use rayon::prelude::*;
    flags
        .par_chunks(FLAG_BLOCK)
        .enumerate()
        .flat_map_iter(|(b, block)| {
            let mut found = Vec::new();
            extend_with_flagged(&mut found, b * FLAG_BLOCK, block, &pred);
            found
        })
        .collect()
}

/// The cells a task of [`par_flagged_positions`] scans.
pub(crate) const FLAG_BLOCK: usize = 1 << 16;

/// Appends to `found` the positions `start + i` where `flags[i]` and `pred(start + i)`
/// hold, in increasing order, passing over runs of 64 false flags with one vectorised test.
pub(crate) fn extend_with_flagged(found: &mut Vec<usize>, start: usize, flags: &[bool], pred: impl Fn(usize) -> bool) {
    const RUN: usize = 64;
    for (r, run) in flags.chunks(RUN).enumerate() {
        if run.iter().fold(false, |any, &f| any | f) {
            let set = run.iter().enumerate().filter(|(_, &f)| f).map(|(i, _)| start + r * RUN + i);
            found.extend(set.filter(|&i| pred(i)));
        }
    }
}

/// Bytes at positions below a bound, all 0 until written, held in pages made on the first
/// write to each: for the states of a few faces scattered over a large complex. A whole
/// `vec![0; n]` of them is no cheaper to set up than to fill, as the allocator reuses the
/// analysis' freed memory and must clear it (door replay: 5.7 ms for a zone of 13 k faces).
pub(crate) struct SparseBytes {
    pages: Vec<Option<Box<[u8; SparseBytes::PAGE]>>>,
}

impl SparseBytes {
    const PAGE: usize = 4096;

    pub(crate) fn new(len: usize) -> SparseBytes {
        SparseBytes { pages: (0..len.div_ceil(Self::PAGE)).map(|_| None).collect() }
    }
}

impl std::ops::Index<usize> for SparseBytes {
    type Output = u8;

    #[inline]
    fn index(&self, i: usize) -> &u8 {
        self.pages[i / Self::PAGE].as_ref().map_or(&0, |page| &page[i % Self::PAGE])
    }
}

impl std::ops::IndexMut<usize> for SparseBytes {
    #[inline]
    fn index_mut(&mut self, i: usize) -> &mut u8 {
        let page = self.pages[i / Self::PAGE].get_or_insert_with(|| Box::new([0; Self::PAGE]));
        &mut page[i % Self::PAGE]
    }
}

/// A set of positions below a bound, one bit each: walks over a few faces of a large
/// complex mark what they have seen here (the zeroed pages cost nothing until touched),
/// faster than hashing and eight times smaller than a `Vec<bool>`.
pub(crate) struct BitSet {
    words: Vec<u64>,
}

impl BitSet {
    pub(crate) fn new(len: usize) -> BitSet {
        BitSet { words: vec![0; len.div_ceil(64)] }
    }

    /// Adds `i`; whether it was not there yet.
    #[inline]
    pub(crate) fn insert(&mut self, i: usize) -> bool {
        let (word, bit) = (&mut self.words[i / 64], 1u64 << (i % 64));
        let new = *word & bit == 0;
        *word |= bit;
        new
    }

    #[inline]
    pub(crate) fn contains(&self, i: usize) -> bool {
        self.words[i / 64] >> (i % 64) & 1 == 1
    }
}

/// Scanline flood fill of a grid of dimensions `dims` (x fastest): sets `marks[i] = mark`
/// for every voxel joined to one of `seeds` by 6-paths of voxels that are `open` and still
/// `unmarked` (seeds that are not are passed over). Each voxel taken grows to its whole run
/// along x, and the rows beside the run (±y, ±z) are scanned for runs still to take, one
/// seed each: rows are read in order and few seeds are stacked (classroom box at 430: the
/// air reached from the border 0.50 → 0.10 s against a voxel-by-voxel search with a
/// division per neighbour).
pub(crate) fn scanline_fill<T: Copy + PartialEq>(
    dims: [usize; 3],
    marks: &mut [T],
    [unmarked, mark]: [T; 2],
    open: impl Fn(usize) -> bool,
    mut seeds: Vec<usize>,
) {
    let [w, h, d] = dims;
    let fresh = |marks: &[T], j: usize| marks[j] == unmarked && open(j);
    while let Some(i) = seeds.pop() {
        if !fresh(marks, i) {
            continue;
        }
        let row = i - i % w;
        let (mut a, mut b) = (i, i + 1);
        while a > row && fresh(marks, a - 1) {
            a -= 1;
        }
        while b < row + w && fresh(marks, b) {
            b += 1;
        }
        marks[a..b].fill(mark);
        let (y, z) = ((i / w) % h, i / (w * h));
        let beside = [
            (y > 0, -(w as isize)),
            (y + 1 < h, w as isize),
            (z > 0, -((w * h) as isize)),
            (z + 1 < d, (w * h) as isize),
        ];
        for (_, step) in beside.into_iter().filter(|&(inside, _)| inside) {
            let mut in_run = false;
            for j in (a..b).map(|j| j.wrapping_add_signed(step)) {
                let take = fresh(marks, j);
                if take && !in_run {
                    seeds.push(j);
                }
                in_run = take;
            }
        }
    }
}

/// The six axis neighbours of cell `i` of an array with strides `[1, sy, sz]`, in the order
/// −x, +x, −y, +y, −z, +z (as [`neighbours6`]); the array's padding keeps them inside it.
#[inline]
pub(crate) fn axis_neighbours(i: usize, [_, sy, sz]: [usize; 3]) -> [usize; 6] {
    [i - 1, i + 1, i - sy, i + sy, i - sz, i + sz]
}

/// A grid's layout with one cell of padding on every side: every voxel then has its 26
/// neighbours in the array at fixed offsets, so inner loops need no bounds checks and no
/// division to find coordinates.
pub(crate) struct Padded {
    dims: [usize; 3],
    row: usize,
    plane: usize,
}

impl Padded {
    pub(crate) fn new(dims: [usize; 3]) -> Padded {
        let row = dims[0] + 2;
        Padded { dims, row, plane: row * (dims[1] + 2) }
    }

    pub(crate) fn len(&self) -> usize {
        self.plane * (self.dims[2] + 2)
    }

    /// Steps to the next cell along x, y and z.
    pub(crate) fn strides(&self) -> [usize; 3] {
        [1, self.row, self.plane]
    }

    /// Index of voxel (x, y, z) (grid coordinates).
    pub(crate) fn index(&self, x: usize, y: usize, z: usize) -> usize {
        self.row_start(y, z) + x
    }

    /// Index of the first voxel of row (y, z) (grid coordinates).
    fn row_start(&self, y: usize, z: usize) -> usize {
        (z + 1) * self.plane + (y + 1) * self.row + 1
    }

    /// The padded array of `map` over `data` (one value per voxel), padding set to `fill`,
    /// built plane by plane in parallel.
    pub(crate) fn pad<T: Copy + Sync, U: Copy + Send + Sync>(
        &self,
        data: &[T],
        fill: U,
        map: impl Fn(T) -> U + Sync,
    ) -> Vec<U> {
        let [nx, ny, nz] = self.dims;
        par_planes_vec(self.len(), self.plane, |pz, plane| {
            for (py, row) in plane.chunks_mut(self.row).enumerate() {
                if (1..=nz).contains(&pz) && (1..=ny).contains(&py) {
                    let voxels = &data[((pz - 1) * ny + py - 1) * nx..][..nx];
                    row[0].write(fill);
                    row[1..=nx].iter_mut().zip(voxels).for_each(|(o, &v)| {
                        o.write(map(v));
                    });
                    row[nx + 1].write(fill);
                } else {
                    row.iter_mut().for_each(|o| {
                        o.write(fill);
                    });
                }
            }
        })
    }

    /// The voxels' values of a padded array, in the grid's order, plane by plane in parallel.
    pub(crate) fn unpad<T: Copy + Send + Sync>(&self, padded: &[T]) -> Vec<T> {
        self.unpad_map(padded, |v| v)
    }

    /// [`Padded::unpad`] with each value passed through `f` on the way.
    pub(crate) fn unpad_map<T: Copy + Sync, U: Send>(&self, padded: &[T], f: impl Fn(T) -> U + Sync) -> Vec<U> {
        let [nx, ny, nz] = self.dims;
        par_planes_vec(nx * ny * nz, nx * ny, |z, plane| {
            for (y, row) in plane.chunks_mut(nx).enumerate() {
                let at = self.row_start(y, z);
                row.iter_mut().zip(&padded[at..at + nx]).for_each(|(o, &v)| {
                    o.write(f(v));
                });
            }
        })
    }
}

/// A vector of `len` values made by `fill(k, part)` for its parts of `plane` values (the
/// last may be shorter), in parallel. `fill` must write every value of its part. Written
/// straight into the fresh vector: filling it first, or collecting parts and joining them,
/// would be one more pass over memory, on one thread.
pub(crate) fn par_planes_vec<U: Send>(
    len: usize,
    plane: usize,
    fill: impl Fn(usize, &mut [MaybeUninit<U>]) + Sync,
) -> Vec<U> {
    use rayon::prelude::*;
    let mut out = Vec::with_capacity(len);
    if len > 0 {
        out.spare_capacity_mut()[..len].par_chunks_mut(plane).enumerate().for_each(|(k, part)| fill(k, part));
    }
    // SAFETY: the first `len` values were all written above (`fill`'s contract), and the
    // capacity is at least `len`.
    unsafe { out.set_len(len) };
    out
}

/// Linear indices of the 6-neighbours of voxel `i` inside the grid.
pub fn neighbours6(dims: [usize; 3], i: usize) -> impl Iterator<Item = usize> {
    let [nx, ny, nz] = dims;
    let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
    let plane = nx * ny;
    [
        (x > 0).then(|| i - 1),
        (x + 1 < nx).then(|| i + 1),
        (y > 0).then(|| i - nx),
        (y + 1 < ny).then(|| i + nx),
        (z > 0).then(|| i - plane),
        (z + 1 < nz).then(|| i + plane),
    ]
    .into_iter()
    .flatten()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sparse bytes read 0 until written, and each write lands at its own position: on a
    /// page's first and last byte, across pages, and where later writes share a page.
    #[test]
    fn sparse_bytes_hold_what_was_written() {
        let len = 5 * SparseBytes::PAGE + 17;
        let mut bytes = SparseBytes::new(len);
        let mut plain = vec![0u8; len];
        let mut r = crate::testing::Lcg(3);
        let edges = [0, SparseBytes::PAGE - 1, SparseBytes::PAGE, 3 * SparseBytes::PAGE + 1, len - 1];
        let random = (0..200).map(|_| (r.next() * len as f64) as usize);
        for (k, i) in edges.into_iter().chain(random).enumerate() {
            bytes[i] = bytes[i].wrapping_add(k as u8 | 1);
            plain[i] = plain[i].wrapping_add(k as u8 | 1);
        }
        assert!((0..len).all(|i| bytes[i] == plain[i]));
    }

    /// Flags read in runs of 64 give the positions a plain filter gives: sparse and dense
    /// flags, lengths off the word and block sizes, a predicate that drops some.
    #[test]
    fn flagged_positions_are_those_of_a_filter() {
        let mut r = crate::testing::Lcg(7);
        for (len, density) in [(0, 0.5), (13, 0.5), (1 << 16, 0.001), ((1 << 17) + 5, 0.3), (200_003, 0.0001)] {
            let flags: Vec<bool> = (0..len).map(|_| r.next() < density).collect();
            let pred = |i: usize| i % 3 != 1;
            let expected: Vec<usize> = (0..len).filter(|&i| flags[i] && pred(i)).collect();
            assert_eq!(par_flagged_positions(&flags, pred), expected, "{len} flags");
        }
    }

    #[test]
    fn bounds_become_a_centred_grid_with_the_requested_longest_side() {
        let s = GridSpec::from_bounds([0.0, 0.0, 0.0], [10.0, 5.0, 2.0], 128, 0.05).unwrap();
        assert_eq!(s.dims[0], 128);
        assert!(s.dims[1] >= 64 && s.dims[2] >= 26);
        // The box lies inside the grid with the margin on both ends.
        for i in 0..3 {
            assert!(s.origin[i] <= 0.0 && s.origin[i] + s.dims[i] as f64 * s.voxel >= [10.0, 5.0, 2.0][i]);
        }
        assert_eq!(GridSpec::from_bounds([0.0; 3], [0.0; 3], 8, 0.1), Err(GridError::EmptyBounds));
        assert_eq!(GridSpec::from_bounds([0.0; 3], [1.0; 3], 0, 0.1), Err(GridError::ZeroResolution));
        assert!(matches!(GridSpec::from_bounds([0.0; 3], [1.0; 3], 100_000, 0.1), Err(GridError::TooLarge(..))));
        // Explicit dimensions: the tightest axis sets the voxel, the others are centred.
        let s = GridSpec::from_bounds_dims([0.0; 3], [10.0, 5.0, 2.0], [40, 40, 40], 0.0).unwrap();
        assert_eq!((s.dims, s.voxel), ([40, 40, 40], 0.25));
        assert!((s.origin[1] + 2.5).abs() < 1e-12 && s.origin[0] == 0.0);
        assert_eq!(GridSpec::from_bounds_dims([0.0; 3], [1.0; 3], [4, 0, 4], 0.0), Err(GridError::ZeroResolution));
    }
}
