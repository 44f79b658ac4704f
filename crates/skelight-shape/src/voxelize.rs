//! Conservative voxelisation: a voxel is full when any triangle touches it (separating-axis
//! triangle/box test), so a wall thinner than a voxel still blocks. The digital empty space
//! is the complement inside the grid (thesis §6.1.2).

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::grid::{Grid, GridSpec};

type V = [f64; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: V, b: V) -> V {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Whether triangle `t` overlaps the box of half-size `h` centred at `c` (Akenine-Möller's
/// 13-axis separating-axis test; touching counts as overlapping).
pub fn triangle_overlaps_box(t: &[V; 3], c: V, h: V) -> bool {
    let v = [sub(t[0], c), sub(t[1], c), sub(t[2], c)];
    let e = [sub(v[1], v[0]), sub(v[2], v[1]), sub(v[0], v[2])];
    let separated = |axis: V| -> bool {
        if axis == [0.0; 3] {
            return false;
        }
        let p = [dot(v[0], axis), dot(v[1], axis), dot(v[2], axis)];
        let r = h[0] * axis[0].abs() + h[1] * axis[1].abs() + h[2] * axis[2].abs();
        p.iter().cloned().fold(f64::INFINITY, f64::min) > r || p.iter().cloned().fold(f64::NEG_INFINITY, f64::max) < -r
    };
    let units = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for u in units {
        for ed in e {
            if separated(cross(u, ed)) {
                return false;
            }
        }
        if separated(u) {
            return false;
        }
    }
    !separated(cross(e[0], e[1]))
}

/// Full voxels of the triangles; degenerate or non-finite triangles are skipped.
pub fn voxelize(spec: &GridSpec, triangles: &[[V; 3]]) -> Grid<bool> {
    let full: Vec<AtomicBool> = (0..spec.len()).map(|_| AtomicBool::new(false)).collect();
    let h = spec.voxel * 0.5;
    triangles.par_iter().for_each(|t| {
        if t.iter().flatten().any(|v| !v.is_finite()) {
            return;
        }
        let mut lo = [usize::MAX; 3];
        let mut hi = [0usize; 3];
        for i in 0..3 {
            let (mn, mx) =
                t.iter().map(|p| p[i]).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
            let a = ((mn - spec.origin[i]) / spec.voxel).floor() - 1.0;
            let b = ((mx - spec.origin[i]) / spec.voxel).floor() + 1.0;
            if b < 0.0 || a >= spec.dims[i] as f64 {
                return;
            }
            lo[i] = a.max(0.0) as usize;
            hi[i] = (b as usize).min(spec.dims[i] - 1);
        }
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let i = spec.index(x, y, z);
                    if !full[i].load(Ordering::Relaxed) && triangle_overlaps_box(t, spec.center(x, y, z), [h; 3]) {
                        full[i].store(true, Ordering::Relaxed);
                    }
                }
            }
        }
    });
    Grid { spec: *spec, data: full.into_iter().map(AtomicBool::into_inner).collect() }
}

/// The digital empty space: voxels no triangle touches.
pub fn empty_space(full: &Grid<bool>) -> Grid<bool> {
    Grid { spec: full.spec, data: full.data.iter().map(|f| !f).collect() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_test_cases() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(triangle_overlaps_box(&t, [0.2, 0.2, 0.0], [0.1; 3]));
        assert!(!triangle_overlaps_box(&t, [0.2, 0.2, 0.5], [0.1; 3]));
        // Beyond the hypotenuse: only the edge-cross-axis tests separate it.
        assert!(!triangle_overlaps_box(&t, [0.7, 0.7, 0.0], [0.1; 3]));
        assert!(triangle_overlaps_box(&t, [0.55, 0.55, 0.0], [0.1; 3]));
    }

    /// A wall far thinner than a voxel still separates the two halves of the grid.
    #[test]
    fn thin_wall_blocks() {
        let spec = GridSpec { origin: [0.0; 3], voxel: 1.0, dims: [8, 4, 4] };
        let x = 3.37;
        let wall = [[[x, -1.0, -1.0], [x, 9.0, -1.0], [x, -1.0, 9.0]], [[x, 9.0, -1.0], [x, 9.0, 9.0], [x, -1.0, 9.0]]];
        let g = voxelize(&spec, &wall);
        for z in 0..4 {
            for y in 0..4 {
                assert!(*g.get(3, y, z), "hole at {y},{z}");
                assert!(!*g.get(2, y, z) && !*g.get(4, y, z));
            }
        }
        assert_eq!(empty_space(&g).data.iter().filter(|e| **e).count(), 8 * 4 * 4 - 16);
    }
}
