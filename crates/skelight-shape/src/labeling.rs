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
pub fn opening_forest_labelling(o: &Opening) -> Labelling {
    let spec = o.spec;
    let n = spec.len();
    let mut labels = vec![NO_LABEL; n];
    let is_root = |i: usize| o.radius(i) > 0 && o.centre(i) == i;
    let mut count = 0;
    for seed in 0..n {
        if !is_root(seed) || labels[seed] != NO_LABEL {
            continue;
        }
        count += 1;
        let r = o.radius(seed);
        scanline_fill(spec.dims, &mut labels, [NO_LABEL, count], |j| is_root(j) && o.radius(j) == r, vec![seed]);
    }
    // Along a chain x → f(x) → … the opening strictly grows until a root, so chains end.
    let mut chain = Vec::new();
    for start in 0..n {
        if o.radius(start) == 0 || labels[start] != NO_LABEL {
            continue;
        }
        let mut i = start;
        while labels[i] == NO_LABEL {
            chain.push(i);
            i = o.centre(i);
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
}
