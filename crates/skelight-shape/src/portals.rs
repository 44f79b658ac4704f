//! Opening portals (thesis §10.3.4, Def. 10.11–10.12): the set of 2-faces between
//! 6-adjacent voxels of two opening-forest regions. Rays sampled through a portal go from
//! one region to the other.

use std::collections::BTreeMap;

use crate::labeling::{Labelling, NO_LABEL};

/// The portal between regions `from` < `to` (Def. 10.12).
#[derive(Clone, Debug, PartialEq)]
pub struct Portal {
    pub from: u32,
    pub to: u32,
    /// Its 2-faces, each as the linear index of the voxel on its lower side and the axis
    /// it faces along (the other voxel is one step up that axis).
    pub squares: Vec<(usize, u8)>,
    /// Number of 2-faces.
    pub faces: usize,
    /// World-space area.
    pub area: f64,
    /// Area-weighted centre of its faces (world space).
    pub centroid: [f64; 3],
    /// Mean of the faces' unit normals oriented from `from` to `to`, normalised (zero if
    /// they cancel, as for a portal that wraps around a region).
    pub normal: [f64; 3],
}

/// Running sums over one portal's faces.
#[derive(Default)]
struct FaceSums {
    squares: Vec<(usize, u8)>,
    faces: usize,
    centres: [f64; 3],
    normals: [f64; 3],
}

/// Every opening portal: the faces between 6-adjacent voxels of different regions.
pub fn portals(l: &Labelling) -> Vec<Portal> {
    let spec = l.labels.spec;
    let [nx, ny, _] = spec.dims;
    let labels = &l.labels.data;
    let mut acc: BTreeMap<(u32, u32), FaceSums> = BTreeMap::new();
    let [_, _, nz] = spec.dims;
    // Voxel by voxel in index order; coordinates follow the loops, and a voxel's centre is
    // computed only where it has a portal face (few do).
    let mut visit = |x: usize, y: usize, z: usize| {
        let i = spec.index(x, y, z);
        let a = labels[i];
        if a == NO_LABEL {
            return;
        }
        // Each face once: towards +x, +y, +z.
        let ahead = [(x + 1 < nx, 1), (y + 1 < ny, nx), (z + 1 < nz, nx * ny)];
        for (axis, &(inside, step)) in ahead.iter().enumerate() {
            let b = if inside { labels[i + step] } else { NO_LABEL };
            if b == NO_LABEL || b == a {
                continue;
            }
            let c = spec.center(x, y, z);
            let (from, to, sign) = if a < b { (a, b, 1.0) } else { (b, a, -1.0) };
            let e = acc.entry((from, to)).or_default();
            e.faces += 1;
            e.squares.push((i, axis as u8));
            for (k, sum) in e.centres.iter_mut().enumerate() {
                *sum += c[k] + if k == axis { 0.5 * spec.voxel } else { 0.0 };
            }
            e.normals[axis] += sign;
        }
    };
    // Few voxels have a portal face ahead of them: blocks of a row without one are passed
    // over by one vectorised test (door: 4.2 ms voxel by voxel, 1.8 so).
    const BLOCK: usize = 16;
    let mut next = vec![NO_LABEL; nx];
    for z in 0..nz {
        for y in 0..ny {
            let here = l.labels.row(y, z);
            // Beyond the grid the labels are taken as equal: no face there is a portal's.
            let up = l.labels.row_at(y as isize + 1, z as isize).unwrap_or(here);
            let ahead = l.labels.row_at(y as isize, z as isize + 1).unwrap_or(here);
            next[..nx - 1].copy_from_slice(&here[1..]);
            next[nx - 1] = here[nx - 1];
            let blocks = here.chunks(BLOCK).zip(next.chunks(BLOCK)).zip(up.chunks(BLOCK).zip(ahead.chunks(BLOCK)));
            for (b, ((here, next), (up, ahead))) in blocks.enumerate() {
                let ahead_of = next.iter().zip(up).zip(ahead);
                // A face is a portal's where both labels are regions' and differ.
                let portal = |a: u32, b: u32| (a != b) & (a != NO_LABEL) & (b != NO_LABEL);
                let differs = here
                    .iter()
                    .zip(ahead_of)
                    .fold(false, |any, (&a, ((&n, &u), &f))| any | portal(a, n) | portal(a, u) | portal(a, f));
                if differs {
                    (b * BLOCK..b * BLOCK + here.len()).for_each(|x| visit(x, y, z));
                }
            }
        }
    }
    let face_area = spec.voxel * spec.voxel;
    acc.into_iter()
        .map(|((from, to), FaceSums { squares, faces, centres: sum_c, normals: sum_n })| {
            let len = (sum_n[0] * sum_n[0] + sum_n[1] * sum_n[1] + sum_n[2] * sum_n[2]).sqrt();
            let normal = if len > 0.0 { sum_n.map(|v| v / len) } else { [0.0; 3] };
            Portal {
                from,
                to,
                squares,
                faces,
                area: faces as f64 * face_area,
                centroid: sum_c.map(|v| v / faces as f64),
                normal,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::chessboard;
    use crate::labeling::opening_forest_labelling;
    use crate::opening::opening;
    use crate::testing::set_from;

    /// Two 7-wide rooms joined by a 1×3 gap in a wall: each room is one region and the
    /// only portal between them lies in the gap (or beside it), facing along x.
    #[test]
    fn two_rooms_meet_at_one_portal_in_the_door() {
        let set = set_from([17, 9, 9], 0.5, |x, y, z| {
            let inside = (1..16).contains(&x) && (1..8).contains(&y) && (1..8).contains(&z);
            // Wall at x = 8 with a gap at y = 4, z = 3..6.
            inside && (x != 8 || (y == 4 && (3..6).contains(&z)))
        });
        let o = opening(&chessboard(&set, true));
        let l = opening_forest_labelling(&o);
        let (left, right) = (*l.labels.get(4, 4, 4), *l.labels.get(12, 4, 4));
        assert!(left != NO_LABEL && right != NO_LABEL && left != right);
        // Every voxel of a room carries its room's label.
        for z in 1..8 {
            for y in 1..8 {
                for x in 1..8 {
                    assert_eq!(*l.labels.get(x, y, z), left, "({x},{y},{z})");
                    assert_eq!(*l.labels.get(x + 8, y, z), right, "({},{y},{z})", x + 8);
                }
            }
        }
        let ps = portals(&l);
        // The gap's voxels form their own thin region or join a room; either way the rooms
        // are connected only through portals at the wall.
        assert!(!ps.is_empty());
        for p in &ps {
            assert!((p.centroid[0] - 4.25).abs() <= 0.5 + 1e-9, "portal off the wall: {p:?}");
            assert!(p.normal[0].abs() > 0.99, "{p:?}");
            assert_eq!(p.area, p.faces as f64 * 0.25);
            assert_eq!(p.squares.len(), p.faces);
            // Each square separates a voxel of one region from a voxel of the other.
            for &(v, axis) in &p.squares {
                let step = [1, 17, 17 * 9][axis as usize];
                let pair = [l.labels.data[v], l.labels.data[v + step]];
                assert!(pair == [p.from, p.to] || pair == [p.to, p.from], "{pair:?}");
            }
        }
        assert_eq!(l.count as usize, 2 + ps.len() - 1);
    }

    /// Every face between 6-adjacent voxels of two regions, found by looking at every pair
    /// of neighbours, lies in the portal of those regions, and no other face does. Labels
    /// in slabs along each axis in turn (so portals face along every axis), with scattered
    /// voxels outside the set and rows whose length is no multiple of a block.
    #[test]
    fn portals_hold_exactly_the_faces_between_regions() {
        use crate::grid::{Grid, GridSpec};
        let spec = GridSpec { origin: [0.0; 3], voxel: 1.0, dims: [37, 11, 9] };
        let [nx, ny, nz] = spec.dims;
        let mut r = crate::testing::Lcg(5);
        for axis in 0..3 {
            let mut data = Vec::new();
            for z in 0..nz {
                for y in 0..ny {
                    for x in 0..nx {
                        let c = [x, y, z][axis];
                        data.push(if r.next() < 0.03 { NO_LABEL } else { 1 + (c / 4) as u32 % 3 });
                    }
                }
            }
            let l = Labelling { labels: Grid { spec, data }, count: 3 };
            let mut expected: BTreeMap<(u32, u32), Vec<(usize, u8)>> = BTreeMap::new();
            for i in 0..spec.len() {
                let p = spec.coords(i);
                for (a, step) in [1, nx, nx * ny].into_iter().enumerate() {
                    if p[a] + 1 == spec.dims[a] {
                        continue;
                    }
                    let (u, v) = (l.labels.data[i], l.labels.data[i + step]);
                    if u != NO_LABEL && v != NO_LABEL && u != v {
                        expected.entry((u.min(v), u.max(v))).or_default().push((i, a as u8));
                    }
                }
            }
            let found: BTreeMap<(u32, u32), Vec<(usize, u8)>> =
                portals(&l).into_iter().map(|p| ((p.from, p.to), p.squares)).collect();
            assert!(expected.values().map(Vec::len).sum::<usize>() > 100, "axis {axis}: too few faces to tell");
            assert_eq!(found, expected, "regions in slabs along axis {axis}");
        }
    }
}
