//! Cubical complexes on a voxel grid (thesis §5.2). Faces are stored in the doubled
//! ("Khalimsky") grid of (2w+1)×(2h+1)×(2d+1) cells: a coordinate is odd where the face
//! spans an interval {a, a+1} along that axis and even where it is the point {a}, so a
//! face's dimension is its number of odd coordinates and voxel (x, y, z) is the 3-face
//! at (2x+1, 2y+1, 2z+1). The faces of a face differ from it by ±1 in one odd coordinate;
//! the faces containing it by ±1 in one even coordinate.
//!
//! The array holds one more cell on every side of the doubled grid, never in the complex,
//! so that every face has its six neighbours in the array: the thinning's inner loop then
//! steps by fixed strides with no bounds checks and no coordinates.

use std::collections::VecDeque;

use crate::grid::{par_planes_vec, Grid};

/// The voxels containing a face along one axis of `n` voxels, from the face's doubled
/// coordinate `c` on that axis: an odd coordinate 2a+1 lies in voxel a, an even one 2a in
/// voxels a−1 and a (those of them inside the grid).
#[inline]
pub fn voxel_span(c: usize, n: usize) -> std::ops::Range<usize> {
    if c & 1 == 1 {
        c / 2..c / 2 + 1
    } else {
        (c / 2).saturating_sub(1)..(c / 2 + 1).min(n)
    }
}

/// A set of faces of the doubled grid; [`Complex::from_voxels`] makes it closed (a complex).
#[derive(Clone, Debug, PartialEq)]
pub struct Complex {
    /// Doubled-grid dimensions (2·voxels + 1 on each axis).
    pub dims: [usize; 3],
    /// One flag per cell of the padded array (see the module doc); index with
    /// [`Complex::index`]. Padding cells are always false.
    pub cells: Vec<bool>,
}

impl Complex {
    /// The complex of a voxel set: the closure of its 3-faces. A face is in it when one of
    /// the voxels containing it is in the set, so each row of the doubled grid is the union
    /// of the closures of the (one to four) voxel rows it lies in; planes run in parallel.
    pub fn from_voxels(set: &Grid<bool>) -> Complex {
        let [w, h, d] = set.spec.dims;
        let dims = [2 * w + 1, 2 * h + 1, 2 * d + 1];
        let mut c = Complex { dims, cells: Vec::new() };
        let sy = c.strides()[1];
        c.cells = c.par_planes_new(false, |z, plane| {
            let zs = voxel_span(z, d);
            // Whether each voxel column of the row is in one of the voxel rows it lies in.
            let mut merged = vec![false; w];
            for py in 0..dims[1] {
                merged.fill(false);
                for z in zs.clone() {
                    for y in voxel_span(py, h) {
                        for (m, &inside) in merged.iter_mut().zip(set.row(y, z)) {
                            *m |= inside;
                        }
                    }
                }
                // A cell at odd x lies in voxel column x/2 alone, one at even x in the columns
                // on both sides of it.
                let row = &mut plane[(py + 1) * sy + 1..][..dims[0]];
                let mut before = false;
                for (pair, &m) in row.chunks_exact_mut(2).zip(&merged) {
                    pair[0] = before | m;
                    pair[1] = m;
                    before = m;
                }
                row[2 * w] = before;
            }
        });
        c
    }

    /// A new array of one value per cell of the padded array (padding rows and columns
    /// included), built plane by plane in parallel: each plane is set to `fill`, then
    /// `f(z, plane)` writes what it wants into the planes of the doubled grid (`z` its
    /// doubled coordinate). A plane is filled and written while it sits in the cache; a
    /// zeroed allocation cleared the whole array first, on one thread (the allocator reuses
    /// the analysis' freed memory: 1.6 ms for the door's 15.6 M cells).
    pub fn par_planes_new<T: Copy + Send + Sync>(&self, fill: T, f: impl Fn(usize, &mut [T]) + Sync) -> Vec<T> {
        let sz = self.strides()[2];
        par_planes_vec(sz * (self.dims[2] + 2), sz, |pz, plane| {
            plane.fill(std::mem::MaybeUninit::new(fill));
            // SAFETY: every element of the plane was just written.
            let plane = unsafe { std::slice::from_raw_parts_mut(plane.as_mut_ptr().cast::<T>(), plane.len()) };
            if (1..=self.dims[2]).contains(&pz) {
                f(pz - 1, plane);
            }
        })
    }

    /// Strides of the padded array along x, y and z.
    #[inline]
    pub fn strides(&self) -> [usize; 3] {
        [1, self.dims[0] + 2, (self.dims[0] + 2) * (self.dims[1] + 2)]
    }

    /// Array index of the face at doubled-grid coordinates `p`.
    #[inline]
    pub fn index(&self, p: [usize; 3]) -> usize {
        let s = self.strides();
        (p[2] + 1) * s[2] + (p[1] + 1) * s[1] + p[0] + 1
    }

    /// Doubled-grid coordinates of the face at array index `i` (meaningless for padding).
    #[inline]
    pub fn coords(&self, i: usize) -> [usize; 3] {
        let [_, py, pz] = self.strides();
        [(i % py).wrapping_sub(1), (i % pz / py).wrapping_sub(1), (i / pz).wrapping_sub(1)]
    }

    /// Whether array index `i` is a face of the doubled grid rather than padding.
    #[inline]
    pub fn in_grid(&self, i: usize) -> bool {
        let p = self.coords(i);
        (0..3).all(|a| p[a] < self.dims[a])
    }

    /// Dimension of the face at `i`: how many of its coordinates are odd.
    #[inline]
    pub fn dim(&self, i: usize) -> usize {
        self.face_type(i).count_ones() as usize
    }

    /// Type of the face at `i`: bit a set where its coordinate along axis a is odd (the
    /// axes it spans).
    #[inline]
    pub fn face_type(&self, i: usize) -> u8 {
        let p = self.coords(i);
        (p[0] & 1 | (p[1] & 1) << 1 | (p[2] & 1) << 2) as u8
    }

    #[inline]
    pub fn contains(&self, i: usize) -> bool {
        self.cells[i]
    }

    /// Faces of dimension one more that contain face `i` (inside the grid), with the axis
    /// and sign of the step: `(index, axis, +1 / −1)`.
    pub fn cofaces(&self, i: usize) -> Few<Step, 6> {
        self.steps(i, 0)
    }

    /// Faces of dimension one less contained in face `i`, as `(index, axis, sign)`.
    pub fn facets(&self, i: usize) -> Few<Step, 6> {
        self.steps(i, 1)
    }

    /// Neighbours at ±1 along the axes where face `i`'s coordinate has the given parity,
    /// gathered in a fixed array (this sits in the innermost loop of the thinning).
    #[inline]
    fn steps(&self, i: usize, parity: usize) -> Few<Step, 6> {
        let p = self.coords(i);
        let stride = self.strides();
        let mut out = Few::new((0, 0, 0));
        for a in 0..3 {
            if p[a] & 1 != parity {
                continue;
            }
            if p[a] > 0 {
                out.push((i - stride[a], a, -1));
            }
            if p[a] + 1 < self.dims[a] {
                out.push((i + stride[a], a, 1));
            }
        }
        out
    }

    /// Number of faces of the complex that contain face `i` and have one dimension more.
    #[inline]
    pub fn coface_count(&self, i: usize) -> usize {
        self.cofaces(i).filter(|&(j, _, _)| self.cells[j]).count()
    }

    /// How many faces of each dimension the complex has.
    pub fn face_counts(&self) -> [usize; 4] {
        let mut n = [0; 4];
        for (i, &inside) in self.cells.iter().enumerate() {
            if inside {
                n[self.dim(i)] += 1;
            }
        }
        n
    }

    /// Euler characteristic: vertices − edges + squares − cubes.
    pub fn euler_characteristic(&self) -> i64 {
        let n = self.face_counts();
        n[0] as i64 - n[1] as i64 + n[2] as i64 - n[3] as i64
    }

    /// Number of connected components (vertices joined by the complex's edges).
    pub fn components(&self) -> usize {
        let mut seen = vec![false; self.cells.len()];
        let mut queue = VecDeque::new();
        let mut count = 0;
        for start in 0..self.cells.len() {
            if !self.cells[start] || seen[start] || self.dim(start) != 0 {
                continue;
            }
            count += 1;
            seen[start] = true;
            queue.push_back(start);
            while let Some(v) = queue.pop_front() {
                for (e, _, _) in self.cofaces(v) {
                    if !self.cells[e] {
                        continue;
                    }
                    for (w, _, _) in self.facets(e) {
                        if self.cells[w] && !seen[w] {
                            seen[w] = true;
                            queue.push_back(w);
                        }
                    }
                }
            }
        }
        count
    }

    /// Linear indices, in the voxel grid, of the voxels (3-faces) that contain face `i`
    /// (at most eight; no allocation, as the constraint set asks this of every edge).
    pub fn voxels_around(&self, i: usize) -> Few<usize, 8> {
        self.voxels_around_at(self.coords(i))
    }

    /// [`Complex::voxels_around`] the face at doubled-grid coordinates `p`.
    pub fn voxels_around_at(&self, p: [usize; 3]) -> Few<usize, 8> {
        let [w, h, d] = self.dims.map(|n| (n - 1) / 2);
        let [xs, ys, zs] = [voxel_span(p[0], w), voxel_span(p[1], h), voxel_span(p[2], d)];
        let mut out = Few::new(0);
        for z in zs {
            for y in ys.clone() {
                for x in xs.clone() {
                    out.push((z * h + y) * w + x);
                }
            }
        }
        out
    }

    /// Whether the complex has no face of dimension 2 or more.
    pub fn is_curvilinear(&self) -> bool {
        let n = self.face_counts();
        n[2] == 0 && n[3] == 0
    }
}

/// A neighbouring face one step away in the doubled grid: `(index, axis, sign)`.
pub type Step = (usize, usize, i8);

/// At most `N` values in a fixed array, iterated in order: the neighbour lists of the
/// thinning's inner loops, without a heap allocation each.
#[derive(Clone, Copy, Debug)]
pub struct Few<T: Copy, const N: usize> {
    items: [T; N],
    len: usize,
    next: usize,
}

impl<T: Copy, const N: usize> Few<T, N> {
    fn new(fill: T) -> Self {
        Few { items: [fill; N], len: 0, next: 0 }
    }
    #[inline]
    fn push(&mut self, v: T) {
        self.items[self.len] = v;
        self.len += 1;
    }
}

impl<T: Copy, const N: usize> Iterator for Few<T, N> {
    type Item = T;
    #[inline]
    fn next(&mut self) -> Option<T> {
        let item = self.items[..self.len].get(self.next).copied();
        self.next += 1;
        item
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;

    fn voxels(dims: [usize; 3], on: &[[usize; 3]]) -> Grid<bool> {
        let mut g = Grid::new(GridSpec { origin: [0.0; 3], voxel: 1.0, dims }, false);
        for &[x, y, z] in on {
            g.set(x, y, z, true);
        }
        g
    }

    /// Every face's voxels are those whose closed cube [2a, 2a + 2] contains it on each axis.
    #[test]
    fn voxels_around_every_face_match_brute_force() {
        let x = Complex::from_voxels(&voxels([3, 2, 4], &[]));
        let [w, h, d] = [3, 2, 4];
        for i in 0..x.cells.len() {
            if !x.in_grid(i) {
                continue;
            }
            let p = x.coords(i);
            let mut expected = Vec::new();
            for z in 0..d {
                for y in 0..h {
                    for vx in 0..w {
                        let v = [vx, y, z];
                        if (0..3).all(|a| p[a] >= 2 * v[a] && p[a] <= 2 * v[a] + 2) {
                            expected.push((z * h + y) * w + vx);
                        }
                    }
                }
            }
            assert_eq!(x.voxels_around(i).collect::<Vec<_>>(), expected, "face {p:?}");
        }
    }

    /// A face is in the complex of a voxel set iff one of the voxels around it is in the set;
    /// the padding never is.
    #[test]
    fn the_complex_of_random_sets_is_the_closure_of_their_voxels() {
        for (seed, dims) in [[1, 1, 1], [5, 3, 4], [8, 1, 6], [2, 7, 3]].into_iter().enumerate() {
            let mut r = crate::testing::Lcg(seed as u64);
            let set = crate::testing::set_from(dims, 1.0, |_, _, _| r.next() < 0.4);
            let x = Complex::from_voxels(&set);
            for i in 0..x.cells.len() {
                let expected = x.in_grid(i) && x.voxels_around(i).any(|v| set.data[v]);
                assert_eq!(x.cells[i], expected, "dims {dims:?}, cell {:?}", x.coords(i));
            }
        }
    }

    #[test]
    fn a_cube_and_a_ring_have_the_right_counts() {
        let cube = Complex::from_voxels(&voxels([3, 3, 3], &[[1, 1, 1]]));
        assert_eq!(cube.face_counts(), [8, 12, 6, 1]);
        assert_eq!(cube.euler_characteristic(), 1);
        assert_eq!(cube.components(), 1);
        // A ring of 8 voxels around a hole: χ = 0.
        let ring: Vec<[usize; 3]> =
            (0..3).flat_map(|x| (0..3).map(move |y| [x, y, 0])).filter(|p| *p != [1, 1, 0]).collect();
        let ring = Complex::from_voxels(&voxels([3, 3, 1], &ring));
        assert_eq!(ring.euler_characteristic(), 0);
        assert_eq!(ring.components(), 1);
        // Two voxels touching at a corner are one component.
        let two = Complex::from_voxels(&voxels([2, 2, 2], &[[0, 0, 0], [1, 1, 1]]));
        assert_eq!(two.components(), 1);
        assert_eq!(two.euler_characteristic(), 1);
    }
}
