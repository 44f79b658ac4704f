//! Learning a guide's parameters pass by pass, shared by the guided path tracers: per key
//! (a skeleton node, a cell of space) the estimated second moment of the one-sample
//! estimator under each candidate setting, ∫ h²/p_θ ≈ mean of h²/(p_θ·p_used) over
//! directions drawn with p_used (h = f·|cos|·L); the candidate with the least is taken for
//! the next pass, fixed within it, so every pass stays unbiased (a pass's sampling depends
//! only on earlier passes' samples). And [`SelectionCells`]: keys for a guide that has no
//! structure of its own to learn on (user-named portals), cells of a grid over the scene
//! per orientation of the surface, with the learned value interpolated between cell
//! centres so that it varies continuously over surfaces (no seams in the variance).

use crate::math::{Aabb, Vec3};

/// Directions a key must have seen before its own choice replaces the defaults.
pub const MIN_OBSERVATIONS: u64 = 64;

/// Per key, Σ h²/(p_θ·p_used) for each of `N` candidates, and how many directions it rests
/// on: everything the passes so far observed.
#[derive(Clone, Default)]
pub struct Moments<const N: usize> {
    pub sums: Vec<[f64; N]>,
    pub counts: Vec<u64>,
}

impl<const N: usize> Moments<N> {
    pub fn new(keys: usize) -> Moments<N> {
        Moments { sums: vec![[0.0; N]; keys], counts: vec![0; keys] }
    }

    /// Adds what one tile observed.
    pub fn add(&mut self, tile: &TileMoments<N>) {
        for (&key, (count, sums)) in &tile.entries {
            let Some(mine) = self.sums.get_mut(key as usize) else { continue };
            for (x, y) in mine.iter_mut().zip(sums) {
                *x += y;
            }
            self.counts[key as usize] = self.counts[key as usize].saturating_add(*count);
        }
    }

    /// The candidate with the least estimated second moment at `key`, once it has seen
    /// [`MIN_OBSERVATIONS`] directions.
    pub fn best(&self, key: usize) -> Option<usize> {
        if self.counts[key] < MIN_OBSERVATIONS {
            return None;
        }
        let sums = &self.sums[key];
        (0..N).min_by(|&a, &b| sums[a].total_cmp(&sums[b]))
    }
}

/// What one tile of a pass observed, for the few keys it met (a dense table per tile would
/// cost keys × tiles of memory).
#[derive(Clone, Default)]
pub struct TileMoments<const N: usize> {
    entries: std::collections::HashMap<u32, (u64, [f64; N]), std::hash::BuildHasherDefault<KeyHasher>>,
}

/// A hasher for small integer keys of our own making (no adversary): one multiplication,
/// where SipHash cost a tenth of a learning guide's time per step.
#[derive(Default)]
pub struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }
    #[inline]
    fn write_u32(&mut self, k: u32) {
        self.0 = (self.0 ^ k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

impl<const N: usize> TileMoments<N> {
    /// Adds one direction of integrand `h`, drawn with density `p_used`, whose densities
    /// under the candidates `p_candidates` gives (asked only where h ≠ 0).
    #[inline]
    pub fn observe(&mut self, key: u32, h: f64, p_used: f64, p_candidates: impl FnOnce() -> [f64; N]) {
        let (count, sums) = self.entries.entry(key).or_insert((0, [0.0; N]));
        *count += 1;
        if h == 0.0 || !h.is_finite() || !(p_used > 0.0) {
            return;
        }
        for (sum, p) in sums.iter_mut().zip(p_candidates()) {
            *sum += if p > 0.0 { h * h / (p * p_used) } else { f64::INFINITY };
        }
    }
}

/// A grid of cubic cells over a box, six keys per cell (the dominant axis and sign of the
/// side a surface reflects into: a wall's two faces and the floor under it learn apart).
#[derive(Clone, Debug)]
pub struct SelectionCells {
    origin: Vec3,
    cell: f32,
    dims: [usize; 3],
}

impl SelectionCells {
    /// `cells` cells along the box's longest side (at least one along each).
    pub fn new(bounds: Aabb, cells: usize) -> SelectionCells {
        let extent = bounds.extent();
        let longest = extent.x.max(extent.y).max(extent.z);
        let cell = if longest > 0.0 && longest.is_finite() { longest / cells.max(1) as f32 } else { 1.0 };
        let dims = [0, 1, 2].map(|a| ((extent[a] / cell).ceil() as usize).clamp(1, cells.max(1)));
        let origin = if bounds.is_empty() { Vec3::ZERO } else { bounds.min };
        SelectionCells { origin, cell, dims }
    }

    pub fn keys(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2] * 6
    }

    fn class(side: Vec3) -> usize {
        let a = side.abs();
        let axis = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        axis * 2 + usize::from(side[axis] < 0.0)
    }

    fn index(&self, c: [usize; 3], class: usize) -> usize {
        ((c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]) * 6 + class
    }

    /// The key of the cell holding `p`, for a surface reflecting towards `side`.
    pub fn key(&self, p: Vec3, side: Vec3) -> u32 {
        let g = (p - self.origin) * (1.0 / self.cell);
        let c = [0, 1, 2].map(|a| (g[a].floor().max(0.0) as usize).min(self.dims[a] - 1));
        self.index(c, Self::class(side)) as u32
    }

    /// `table` (one value per key) interpolated trilinearly between the centres of the
    /// cells around `p`, for the same side: continuous in `p`.
    pub fn interpolate(&self, table: &[f32], p: Vec3, side: Vec3) -> f32 {
        let class = Self::class(side);
        let g = (p - self.origin) * (1.0 / self.cell) - Vec3::splat(0.5);
        // Per axis, the two cells' offsets into the table (equal at the border) and the
        // weight of the upper one.
        let mut offsets = [[0usize; 2]; 3];
        let mut frac = [0.0f32; 3];
        let mut stride = 6;
        for a in 0..3 {
            let top = (self.dims[a] - 1) as f32;
            let x = g[a].clamp(0.0, top);
            let b = (x as usize).min(self.dims[a] - 1);
            frac[a] = x - b as f32;
            offsets[a] = [b * stride, (b + 1).min(self.dims[a] - 1) * stride];
            stride *= self.dims[a];
        }
        let mut sum = 0.0;
        for (z, wz) in [(offsets[2][0], 1.0 - frac[2]), (offsets[2][1], frac[2])] {
            for (y, wy) in [(offsets[1][0], 1.0 - frac[1]), (offsets[1][1], frac[1])] {
                let row = z + y + class;
                sum += wz * wy * ((1.0 - frac[0]) * table[row + offsets[0][0]] + frac[0] * table[row + offsets[0][1]]);
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::vec3;

    /// Interpolation reproduces a cell's value at its centre and varies continuously
    /// between centres (no step larger than the values' difference times the distance).
    #[test]
    fn interpolation_is_continuous() {
        let cells = SelectionCells::new(Aabb { min: Vec3::ZERO, max: vec3(4.0, 2.0, 1.0) }, 4);
        let mut table = vec![0.0f32; cells.keys()];
        let up = vec3(0.0, 0.0, 1.0);
        let k = cells.key(vec3(1.5, 0.5, 0.5), up) as usize;
        table[k] = 0.5;
        assert!((cells.interpolate(&table, vec3(1.5, 0.5, 0.5), up) - 0.5).abs() < 1e-6);
        assert_eq!(cells.interpolate(&table, vec3(1.5, 0.5, 0.5), -up), 0.0, "another side");
        let mut last = cells.interpolate(&table, vec3(0.0, 0.5, 0.5), up);
        for i in 1..=400 {
            let v = cells.interpolate(&table, vec3(i as f32 * 0.01, 0.5, 0.5), up);
            assert!((v - last).abs() <= 0.5 * 0.01 + 1e-5, "a step at x = {}", i as f32 * 0.01);
            last = v;
        }
    }
}
