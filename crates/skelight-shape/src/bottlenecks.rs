//! Bottleneck portals (issue 68, item 2): the opening-forest regions (§10.3.3) cut one room
//! into several, one per local maximum of the opening map, and most of their portals are
//! faces in mid-air between two parts of the same room (§10.4.1's portals "perpendicular to
//! walls"). A portal is a bottleneck — a door, a window, a gap — when the largest ball that
//! passes through it is much smaller than the balls of the regions it joins. This module
//! measures both widths and joins regions across the portals that are not bottlenecks.
//!
//! Widths are chessboard radii in voxels, read from the opening map: a region's **peak** is
//! the largest π(x) over its voxels (its root's radius, Def. 10.9); a portal's **opening** is
//! the largest min(π(a), π(b)) over its faces (a, b the voxels on its two sides): the radius
//! of the largest maximal ball that reaches the face from both sides, the saddle between the
//! two peaks.

use crate::labeling::{Labelling, NO_LABEL};
use crate::opening::Opening;
use crate::portals::Portal;

/// The widths the merge reads: per region (index 0 unused) and per portal, in voxels.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Widths {
    pub peaks: Vec<u32>,
    pub openings: Vec<u32>,
}

/// Each region's peak and each portal's opening (see the module's doc).
pub fn widths(l: &Labelling, o: &Opening, portals: &[Portal]) -> Widths {
    let mut peaks = vec![0u32; l.count as usize + 1];
    for (i, &label) in l.labels.data.iter().enumerate() {
        if label != NO_LABEL {
            let p = &mut peaks[label as usize];
            *p = (*p).max(o.radius(i));
        }
    }
    let [nx, ny, _] = l.labels.spec.dims;
    let steps = [1, nx, nx * ny];
    let openings = portals
        .iter()
        .map(|p| {
            p.squares.iter().map(|&(i, axis)| o.radius(i).min(o.radius(i + steps[axis as usize]))).max().unwrap_or(0)
        })
        .collect();
    Widths { peaks, openings }
}

/// Groups of regions joined across every portal that is not a bottleneck: portal {A, B} joins
/// the groups holding A and B when its opening is at least `ratio` × the smaller of the two
/// groups' peaks (a group's peak is its largest region's). Portals are taken widest first, so
/// a group's peak is known when its narrower portals are judged, as in a merge tree of the
/// opening map; a ratio of 0 joins everything connected, one above 1 joins nothing.
///
/// Returns, per region (index 0 stays [`NO_LABEL`]), its group's label, numbered 1.. in the
/// order of each group's lowest region, and the number of groups.
pub fn join_wide_portals(count: u32, widths: &Widths, portals: &[Portal], ratio: f64) -> (Vec<u32>, u32) {
    let n = count as usize + 1;
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut peak = widths.peaks.clone();
    peak.resize(n, 0);
    fn root(parent: &mut [u32], mut r: u32) -> u32 {
        while parent[r as usize] != r {
            let up = parent[parent[r as usize] as usize];
            parent[r as usize] = up;
            r = up;
        }
        r
    }
    let mut order: Vec<usize> = (0..portals.len()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(widths.openings[k]));
    for k in order {
        let (a, b) = (root(&mut parent, portals[k].from), root(&mut parent, portals[k].to));
        if a == b || a as usize >= n || b as usize >= n {
            continue;
        }
        let narrower = peak[a as usize].min(peak[b as usize]);
        if f64::from(widths.openings[k]) >= ratio * f64::from(narrower) {
            let (keep, gone) = (a.min(b), a.max(b));
            parent[gone as usize] = keep;
            peak[keep as usize] = peak[keep as usize].max(peak[gone as usize]);
        }
    }
    let mut group = vec![NO_LABEL; n];
    let mut groups = 0;
    for r in 1..n as u32 {
        let top = root(&mut parent, r);
        if group[top as usize] == NO_LABEL {
            groups += 1;
            group[top as usize] = groups;
        }
        group[r as usize] = group[top as usize];
    }
    (group, groups)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::chessboard;
    use crate::labeling::opening_forest_labelling;
    use crate::opening::opening;
    use crate::portals::portals;
    use crate::testing::set_from;

    /// Two rooms, each an L of a wide wing (19 × 12 × 19 voxels) and a narrow one (7 × 11),
    /// so that the opening forest cuts each into several regions, joined by a one-voxel gap
    /// in the wall between them.
    fn two_l_rooms() -> crate::Grid<bool> {
        set_from([41, 25, 21], 1.0, |x, y, z| {
            let inside = (1..40).contains(&x) && (1..24).contains(&y) && (1..20).contains(&z);
            // Each room an L: its upper far quarter walled off.
            let cut = (y >= 13) && ((8..20).contains(&x) || (28..40).contains(&x));
            let wall = x == 20 && !(y == 4 && z == 4);
            inside && !cut && !wall
        })
    }

    /// The two L rooms' opening, regions, portals and widths.
    fn analysed() -> (crate::Grid<bool>, Opening, Labelling, Vec<Portal>, Widths) {
        let set = two_l_rooms();
        let o = opening(&chessboard(&set, true));
        let l = opening_forest_labelling(&o);
        let ps = portals(&l);
        let w = widths(&l, &o, &ps);
        (set, o, l, ps, w)
    }

    /// Each room is one group and the gap is the only portal left: across the gap the
    /// opening is 1 voxel against rooms of peaks ≥ 4; inside a room the wings meet wide.
    #[test]
    fn rooms_stay_apart_and_their_parts_join() {
        let (set, _, l, ps, w) = analysed();
        println!("{} regions, peaks {:?}, openings {:?}", l.count, w.peaks, w.openings);
        assert!(l.count > 2, "the rooms are not cut into parts ({} regions): nothing to join", l.count);
        let (group, groups) = join_wide_portals(l.count, &w, &ps, 0.5);
        assert_eq!(groups, 2, "groups {group:?}");
        let (left, right) = (group[*l.labels.get(4, 4, 4) as usize], group[*l.labels.get(30, 4, 4) as usize]);
        assert_ne!(left, right);
        for i in 0..set.data.len() {
            let label = l.labels.data[i];
            if label == NO_LABEL {
                continue;
            }
            let [x, ..] = l.labels.spec.coords(i);
            // The gap's voxel may go with either room.
            if x != 20 {
                assert_eq!(
                    group[label as usize],
                    if x < 20 { left } else { right },
                    "voxel {:?}",
                    l.labels.spec.coords(i)
                );
            }
        }
        // Every portal left between groups is at the gap, with an opening of 1.
        let kept: Vec<usize> =
            (0..ps.len()).filter(|&k| group[ps[k].from as usize] != group[ps[k].to as usize]).collect();
        assert!(!kept.is_empty());
        for k in kept {
            assert_eq!(w.openings[k], 1, "portal {:?}", ps[k].centroid);
            assert!((ps[k].centroid[0] - 20.0).abs() <= 1.0, "portal {:?}", ps[k].centroid);
        }
        // The ratio's ends: 0 joins all, above 1 (here 100) nothing.
        assert_eq!(join_wide_portals(l.count, &w, &ps, 0.0).1, 1);
        assert_eq!(join_wide_portals(l.count, &w, &ps, 100.0).1, l.count);
    }

    /// The widths by their definitions, voxel by voxel.
    #[test]
    fn widths_are_the_peaks_and_saddles() {
        let (set, o, l, ps, w) = analysed();
        for r in 1..=l.count {
            let peak = (0..set.data.len()).filter(|&i| l.labels.data[i] == r).map(|i| o.radius(i)).max();
            assert_eq!(Some(w.peaks[r as usize]), peak);
        }
        let [nx, ny, _] = set.spec.dims;
        for (k, p) in ps.iter().enumerate() {
            let saddle = p.squares.iter().map(|&(i, a)| {
                let j = i + [1, nx, nx * ny][a as usize];
                o.radius(i).min(o.radius(j))
            });
            assert_eq!(Some(w.openings[k]), saddle.max());
            assert!(w.openings[k] <= w.peaks[p.from as usize].min(w.peaks[p.to as usize]));
        }
    }
}
