//! The opening-forest labelling of the empty space (thesis §10.3.3, Def. 10.8–10.10).
//! Region roots are 6-connected sets of forest roots of equal opening; every other voxel
//! takes the label of the root its forest chain reaches.

use crate::grid::{scanline_fill, Grid};
use crate::opening::Opening;

/// Label of voxels outside the set.
pub const NO_LABEL: u32 = 0;

/// Region labels 1…count (0 outside the set).
pub struct Labelling {
    pub labels: Grid<u32>,
    pub count: u32,
}

/// Def. 10.8–10.9: labels the region roots, then propagates along the forest.
///
/// One pass in index order: a voxel follows its chain to a root, and a root not yet
/// labelled has its whole region flooded with a new label there; the chain then takes the
/// root's label. Regions are numbered in the order the pass first reaches them.
pub fn opening_forest_labelling(o: &Opening) -> Labelling {
    let spec = o.spec;
    let n = spec.len();
    let mut labels = vec![NO_LABEL; n];
    let is_root = |i: usize| o.centre(i) == i;
    let mut count = 0;
    // Along a chain x → f(x) → … the opening strictly grows until a root, so chains end.
    let mut chain = Vec::new();
    for start in 0..n {
        if labels[start] != NO_LABEL || o.radius(start) == 0 {
            continue;
        }
        let mut i = start;
        while labels[i] == NO_LABEL && !is_root(i) {
            chain.push(i);
            i = o.centre(i);
        }
        if labels[i] == NO_LABEL {
            count += 1;
            let r = o.radius(i);
            let same_region = |j: usize| is_root(j) && o.radius(j) == r;
            scanline_fill(spec.dims, &mut labels, [NO_LABEL, count], same_region, vec![i]);
        }
        let label = labels[i];
        for j in chain.drain(..) {
            labels[j] = label;
        }
    }
    Labelling { labels: Grid { spec, data: labels }, count }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::chessboard;
    use crate::grid::neighbours6;
    use crate::opening::opening;
    use crate::testing::random_set;
    use std::collections::VecDeque;

    /// Every voxel of the set is labelled, its label's region contains a root, and the
    /// regions are 6-connected.
    #[test]
    fn labels_cover_the_set_with_connected_regions() {
        let set = random_set([12, 10, 8], 99, 3.0 / 16.0);
        let spec = set.spec;
        let o = opening(&chessboard(&set, true));
        let l = opening_forest_labelling(&o);
        for label in 1..=l.count {
            let members: Vec<usize> = (0..spec.len()).filter(|&i| l.labels.data[i] == label).collect();
            assert!(!members.is_empty());
            // Flood from the first member within the label.
            let mut seen = vec![false; spec.len()];
            let mut queue = VecDeque::from([members[0]]);
            seen[members[0]] = true;
            let mut reached = 0;
            while let Some(i) = queue.pop_front() {
                reached += 1;
                for j in neighbours6(spec.dims, i) {
                    if !seen[j] && l.labels.data[j] == label {
                        seen[j] = true;
                        queue.push_back(j);
                    }
                }
            }
            assert_eq!(reached, members.len(), "region {label} is not 6-connected");
        }
        for i in 0..spec.len() {
            assert_eq!(set.data[i], l.labels.data[i] != NO_LABEL);
        }
    }

    /// Def. 10.8–10.10 by brute force: the region roots grouped into 6-connected sets of
    /// equal opening, one label each, and every voxel with the label of the root its chain
    /// ends at. The labels themselves are numbers in no promised order, so the two
    /// labellings must match up one to one.
    #[test]
    fn labels_follow_the_forest_to_root_regions() {
        for (k, &outside) in [0.1, 3.0 / 16.0, 0.3].iter().enumerate() {
            let set = random_set([14, 11, 9], 7 + k as u64, outside);
            let spec = set.spec;
            let o = opening(&chessboard(&set, true));
            let l = opening_forest_labelling(&o);
            let is_root = |i: usize| o.radius(i) > 0 && o.centre(i) == i;
            // Root regions by flooding, numbered in index order.
            let mut region = vec![0u32; spec.len()];
            let mut regions = 0;
            for seed in (0..spec.len()).filter(|&i| is_root(i)) {
                if region[seed] != 0 {
                    continue;
                }
                regions += 1;
                region[seed] = regions;
                let mut queue = VecDeque::from([seed]);
                while let Some(i) = queue.pop_front() {
                    for j in neighbours6(spec.dims, i) {
                        if region[j] == 0 && is_root(j) && o.radius(j) == o.radius(seed) {
                            region[j] = regions;
                            queue.push_back(j);
                        }
                    }
                }
            }
            assert_eq!(l.count, regions, "set {k}");
            let mut label_of_region = vec![NO_LABEL; regions as usize + 1];
            for v in (0..spec.len()).filter(|&v| o.radius(v) > 0) {
                let mut root = v;
                while !is_root(root) {
                    root = o.centre(root);
                }
                let r = region[root] as usize;
                if label_of_region[r] == NO_LABEL {
                    label_of_region[r] = l.labels.data[v];
                }
                assert_eq!(l.labels.data[v], label_of_region[r], "set {k}, voxel {v}");
            }
            let mut distinct = label_of_region[1..].to_vec();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(distinct.len(), regions as usize, "set {k}: two regions share a label");
            assert!(distinct[0] != NO_LABEL);
        }
    }
}
