//! Voxel sets the unit tests share: built from a predicate, random, and the two rooms
//! joined by a door gap that several stages are checked on.

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
