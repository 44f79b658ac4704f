//! Voxel sets and scenes the unit tests share: built from a predicate, random, the two rooms
//! joined by a door gap that several stages are checked on, closed boxes.

use crate::grid::{Grid, GridSpec};

/// The set of voxels where `inside(x, y, z)` holds (called in raster order, x fastest).
pub fn set_from(dims: [usize; 3], voxel: f64, mut inside: impl FnMut(usize, usize, usize) -> bool) -> Grid<bool> {
    let mut g = Grid::new(GridSpec { origin: [0.0; 3], voxel, dims }, false);
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                g.set(x, y, z, inside(x, y, z));
            }
        }
    }
    g
}

/// A reproducible stream of uniform numbers in [0, 1) (a 64-bit LCG's high bits).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 33) as f64 / (1u64 << 31) as f64
    }
}

/// Every voxel inside except a random fraction `outside` of them.
pub fn random_set(dims: [usize; 3], seed: u64, outside: f64) -> Grid<bool> {
    let mut r = Lcg(seed);
    set_from(dims, 1.0, |_, _, _| r.next() > outside)
}

/// Two rooms (25×12×10 grid) separated by a wall at x = 12 with a gap at y ∈ 8..10,
/// z ∈ 1..8: the door left ajar.
pub fn two_rooms_and_a_gap(voxel: f64) -> Grid<bool> {
    set_from([25, 12, 10], voxel, |x, y, z| {
        let inside = (1..24).contains(&x) && (1..11).contains(&y) && (1..9).contains(&z);
        let gap = (8..10).contains(&y) && (1..8).contains(&z);
        inside && (x != 12 || gap)
    })
}

/// The 12 triangles of the closed box `[lo, hi]` (corners on each axis): a room, or a solid
/// whose inside surface voxelisation leaves empty.
pub fn closed_box(lo: [f64; 3], hi: [f64; 3]) -> Vec<[[f64; 3]; 3]> {
    let c = |i: usize| [0, 1, 2].map(|a| if i >> a & 1 == 1 { hi[a] } else { lo[a] });
    let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    quads.iter().flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]]).collect()
}
