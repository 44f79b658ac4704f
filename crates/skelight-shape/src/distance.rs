//! Distance maps of a binary grid: for every voxel of the set, the distance to the nearest
//! voxel outside it, in L1 (6-connected), chessboard (26-connected) and exact Euclidean
//! metrics, each in time linear in the number of voxels. Outside the grid counts as outside
//! the set when `border_is_outside` (the empty space of a scene is closed by its grid).

use rayon::prelude::*;

use crate::grid::{Grid, Padded};

const INF: u32 = u32::MAX / 4;

/// Calls `f` on every line of the grid along `axis` (dimensions `dims`, x fastest), each
/// as a contiguous slice from its low end, lines in parallel. Lines along y and z are
/// copied into a buffer and back, so that each task owns its lines as slices (on one
/// thread this costs no more than stepping through them in place). Lines along z are
/// grouped by y: the rows a group copies from stay in the cache from one column to the next.
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
    // The lines crossing `rows` (voxel rows in order along the axis), one per x.
    let columns = |rows: &mut [&mut [T]], buffer: &mut Vec<T>| {
        for x in 0..nx {
            buffer.clear();
            buffer.extend(rows.iter().map(|row| row[x]));
            f(buffer);
            for (row, &v) in rows.iter_mut().zip(buffer.iter()) {
                row[x] = v;
            }
        }
    };
    match axis {
        0 => data.par_chunks_mut(nx).for_each(&f),
        1 => data.par_chunks_mut(nx * ny).for_each(|plane| {
            let mut rows: Vec<&mut [T]> = plane.chunks_mut(nx).collect();
            columns(&mut rows, &mut Vec::with_capacity(ny));
        }),
        _ => {
            let mut by_y: Vec<Vec<&mut [T]>> = (0..ny).map(|_| Vec::with_capacity(nz)).collect();
            for plane in data.chunks_mut(nx * ny) {
                for (y, row) in plane.chunks_mut(nx).enumerate() {
                    by_y[y].push(row);
                }
            }
            by_y.into_par_iter().for_each(|mut rows| columns(&mut rows, &mut Vec::with_capacity(nz)));
        }
    }
}

fn init(set: &Grid<bool>) -> Vec<u32> {
    set.data.iter().map(|&inside| if inside { INF } else { 0 }).collect()
}

/// L1 distance: separable, one forward and one backward pass per axis.
pub fn l1(set: &Grid<bool>, border_is_outside: bool) -> Grid<u32> {
    let mut d = init(set);
    let border = if border_is_outside { 0 } else { INF };
    for axis in 0..3 {
        par_lines(&mut d, set.spec.dims, axis, |line| {
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
    }
    Grid { spec: set.spec, data: d }
}

/// Chessboard distance: two raster passes of the 26-neighbour chamfer mask with unit
/// weights (Rosenfeld & Pfaltz), exact for this metric. The grid is padded with the border's
/// value, and each row first takes the minimum of the four rows before it that the mask
/// reads (three x neighbours each) in one vectorisable sweep; only the x neighbour inside
/// the row is a running minimum.
pub fn chessboard(set: &Grid<bool>, border_is_outside: bool) -> Grid<u32> {
    let [nx, ny, nz] = set.spec.dims;
    let layout = Padded::new(set.spec.dims);
    let [_, px, plane] = layout.strides();
    let border = if border_is_outside { 0 } else { INF };
    let mut d = layout.pad(&set.data, border, |inside| if inside { INF } else { 0 });
    // Per x, the least value among the rows before the current one (see above).
    let mut before = vec![0u32; px];
    for forward in [true, false] {
        for zi in 1..=nz {
            let z = if forward { zi } else { nz + 1 - zi };
            for yi in 1..=ny {
                let y = if forward { yi } else { ny + 1 - yi };
                let row = z * plane + y * px;
                // The row before in this plane and the three around it in the plane before.
                let (same, back) = if forward { (row - px, row - plane) } else { (row + px, row + plane) };
                for (x, b) in before.iter_mut().enumerate() {
                    *b = d[same + x].min(d[back - px + x]).min(d[back + x]).min(d[back + px + x]);
                }
                let mut scan = |x: usize, prev: usize| {
                    let m = before[x - 1].min(before[x]).min(before[x + 1]).min(d[row + prev]);
                    d[row + x] = d[row + x].min(m + 1);
                };
                if forward {
                    (1..=nx).for_each(|x| scan(x, x - 1));
                } else {
                    (1..=nx).rev().for_each(|x| scan(x, x + 1));
                }
            }
        }
    }
    Grid { spec: set.spec, data: layout.unpad(&d) }
}

/// Exact squared Euclidean distance (Felzenszwalb & Huttenlocher's lower envelope of
/// parabolas along each axis in turn).
pub fn euclidean_squared(set: &Grid<bool>, border_is_outside: bool) -> Grid<u64> {
    let dims = set.spec.dims;
    const BIG: f64 = 1e18;
    let mut d: Vec<f64> = set.data.iter().map(|&inside| if inside { BIG } else { 0.0 }).collect();
    // With an outside border, each line is padded with outside voxels at −1 and n.
    let pad = usize::from(border_is_outside);
    // Along the first axis the values are 0 or BIG, so the envelope of parabolas is the
    // squared distance to the nearest 0 on the line: two running scans.
    par_lines(&mut d, dims, 0, |line| {
        // Steps to the last 0 before each voxel, then to the next one after it; infinite
        // where there is none (the border counts as a 0 when it is outside).
        let beyond = if border_is_outside { 0.0 } else { f64::INFINITY };
        let mut gap = beyond;
        let before: Vec<f64> = line
            .iter()
            .map(|&v| {
                gap = if v == 0.0 { 0.0 } else { gap + 1.0 };
                gap
            })
            .collect();
        gap = beyond;
        for (v, &before) in line.iter_mut().zip(&before).rev() {
            gap = if *v == 0.0 { 0.0 } else { gap + 1.0 };
            let nearest = gap.min(before);
            if nearest.is_finite() {
                *v = nearest * nearest;
            }
        }
    });
    for axis in 1..3 {
        par_lines(&mut d, dims, axis, |line| {
            let n = line.len();
            let f: Vec<f64> =
                (0..n + 2 * pad).map(|k| if k < pad || k >= n + pad { 0.0 } else { line[k - pad] }).collect();
            line.copy_from_slice(&lower_envelope(&f)[pad..n + pad]);
        });
    }
    Grid { spec: set.spec, data: d.into_iter().map(|v| if v >= BIG { u64::MAX } else { v as u64 }).collect() }
}

/// 1D squared distance transform: out[q] = min_p (q − p)² + f[p].
fn lower_envelope(f: &[f64]) -> Vec<f64> {
    let n = f.len();
    let mut v = vec![0usize; n];
    let mut z = vec![0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let inter =
        |q: usize, p: usize| ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * q as f64 - 2.0 * p as f64);
    for q in 1..n {
        let mut s = inter(q, v[k]);
        while s <= z[k] {
            if k == 0 {
                break;
            }
            k -= 1;
            s = inter(q, v[k]);
        }
        if s <= z[k] {
            // k == 0 and the new parabola dominates everywhere.
            v[0] = q;
            z[0] = f64::NEG_INFINITY;
            z[1] = f64::INFINITY;
            continue;
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    let mut out = vec![0f64; n];
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let dq = q as f64 - v[k] as f64;
        *o = dq * dq + f[v[k]];
    }
    out
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
                }
            }
        }
    }
}
