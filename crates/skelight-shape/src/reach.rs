//! Which empty space the analysis keeps (issue 31, item 7). Surface voxelisation leaves the
//! inside of every closed mesh empty — a box pillar, a floor slab modelled as a closed box,
//! closed furniture — and each such pocket would get a skeleton of its own that no light
//! path enters. By default the analysis keeps the components of the empty space that hold
//! the camera or a light (the sources), found by one flood from their voxels before the
//! thinning, so that the thinning does no work in the others.
//!
//! Components are 26-connected: the thinning works on the complex of the empty voxels (the
//! closure of their cubes), where voxels sharing only an edge or a corner are joined, so each
//! component is what one connected part of the skeleton comes from. Conservative
//! voxelisation makes a closed surface 26-separating (two voxels touching on either side of
//! it both meet it), so the inside of a closed mesh is a component of its own.

use rayon::prelude::*;

use crate::grid::{scanline_fill, Grid};
use crate::pipeline::{Anchor, ANCHOR_REACH};

/// What the analysis kept of the empty space, and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kept {
    /// Every component: asked for (`keep_all_space`).
    All,
    /// The components holding a source.
    Reached,
    /// No sources given: the largest component joined to no border of the grid (the
    /// building's inside rather than the air around it).
    LargestEnclosed,
    /// No sources given and every component reaches the grid's border (an open scene, which
    /// then has no closed solid either): every component.
    AllNothingEnclosed,
    /// A source has no empty voxel within [`ANCHOR_REACH`] voxels (it lies in a thick solid or
    /// outside the grid): every component, since the space it lights is unknown.
    AllSourceUnplaced,
}

/// The empty space kept for the analysis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reach {
    pub kept: Kept,
    /// Empty voxels dropped: the insides of closed solids, the air outside a closed building.
    pub dropped: usize,
}

impl Reach {
    /// Everything kept, for the reason `kept`.
    pub(crate) fn all(kept: Kept) -> Reach {
        Reach { kept, dropped: 0 }
    }
}

/// The empty voxels of `empty` that light can reach: the components of the `sources`' voxels
/// (each `None` where a source could not be placed, see [`place`]); with no sources, the
/// largest enclosed component. Falls back to everything as [`Kept`] says.
pub fn keep_reachable(mut empty: Grid<bool>, sources: &[Option<usize>]) -> (Grid<bool>, Reach) {
    let Some(sources) = sources.iter().copied().collect::<Option<Vec<usize>>>() else {
        return (empty, Reach::all(Kept::AllSourceUnplaced));
    };
    let runs = Runs::of(&empty);
    let mut labels = vec![0u32; runs.spans.len()];
    let (label, how) = if sources.is_empty() {
        match runs.largest_enclosed(&mut labels) {
            Some(label) => (label, Kept::LargestEnclosed),
            None => return (empty, Reach::all(Kept::AllNothingEnclosed)),
        }
    } else {
        let seeds = sources.iter().map(|&v| runs.run_of(empty.spec.coords(v))).collect();
        runs.spread(&mut labels, 1, seeds);
        (1, Kept::Reached)
    };
    let dropped = runs.clear(&mut empty, |run| labels[run] != label);
    (empty, Reach { kept: how, dropped })
}

/// The runs of empty voxels along x, row by row: the flood steps from run to run (door,
/// thesis grid: 1.87 M voxels, 39 k runs). A 26-connected scanline fill, which reads every
/// voxel of the eight rows beside each run, took 23.7 ms there on a busy machine; this
/// takes 2.1–2.5 ms.
struct Runs {
    dims: [usize; 3],
    /// `[start, end)` along x of each run, rows in raster order, runs in order along each.
    spans: Vec<[u32; 2]>,
    /// The index in `spans` of each row's first run, and the number of runs at the end.
    first: Vec<u32>,
}

impl Runs {
    /// The runs of `empty`, found plane by plane in parallel.
    fn of(empty: &Grid<bool>) -> Runs {
        let [w, h, _] = empty.spec.dims;
        let planes: Vec<(Vec<[u32; 2]>, Vec<u32>)> = empty
            .data
            .par_chunks(w * h)
            .map(|plane| {
                let (mut spans, mut counts) = (Vec::new(), Vec::with_capacity(h));
                for row in plane.chunks(w) {
                    let before = spans.len();
                    let mut x = 0;
                    while x < w {
                        let start = run_end(row, x, false);
                        x = run_end(row, start, true);
                        if start < x {
                            spans.push([start as u32, x as u32]);
                        }
                    }
                    counts.push((spans.len() - before) as u32);
                }
                (spans, counts)
            })
            .collect();
        let mut first = Vec::with_capacity(empty.spec.len() / w + 1);
        let mut total = 0;
        for count in planes.iter().flat_map(|p| &p.1) {
            first.push(total);
            total += count;
        }
        first.push(total);
        let spans = planes.into_iter().flat_map(|p| p.0).collect();
        Runs { dims: empty.spec.dims, spans, first }
    }

    /// The runs of row `row`, as indices into `spans`.
    fn of_row(&self, row: usize) -> std::ops::Range<usize> {
        self.first[row] as usize..self.first[row + 1] as usize
    }

    /// The run holding the empty voxel `v`.
    fn run_of(&self, [x, y, z]: [usize; 3]) -> usize {
        let rows = self.of_row(z * self.dims[1] + y);
        rows.start + self.spans[rows].partition_point(|&[_, end]| end as usize <= x)
    }

    /// Gives `label` to every run joined to `seeds` (runs) by 26-paths of empty voxels whose
    /// runs have label 0 yet; returns the voxels it labelled and whether they touch the
    /// grid's border.
    fn spread(&self, labels: &mut [u32], label: u32, mut seeds: Vec<usize>) -> (usize, bool) {
        let [w, h, d] = self.dims;
        let (mut voxels, mut border) = (0, false);
        while let Some(r) = seeds.pop() {
            if labels[r] != 0 {
                continue;
            }
            labels[r] = label;
            let [a, b] = self.spans[r];
            let row = self.first.partition_point(|&f| f as usize <= r) - 1;
            let (y, z) = (row % h, row / h);
            voxels += (b - a) as usize;
            border |= a == 0 || b as usize == w || y == 0 || z == 0 || y + 1 == h || z + 1 == d;
            for z2 in z.saturating_sub(1)..(z + 2).min(d) {
                for y2 in y.saturating_sub(1)..(y + 2).min(h) {
                    // The runs meeting x in [a − 1, b]: those ending after a − 1 and starting
                    // at b or before.
                    let beside = self.of_row(z2 * h + y2);
                    let from = beside.start + self.spans[beside.clone()].partition_point(|&[_, end]| end < a);
                    let meeting = (from..beside.end).take_while(|&q| self.spans[q][0] <= b);
                    seeds.extend(meeting.filter(|&q| labels[q] == 0));
                }
            }
        }
        (voxels, border)
    }

    /// Labels every component and returns the label of the largest that touches no border
    /// of the grid (the first of equals), if one does not.
    fn largest_enclosed(&self, labels: &mut [u32]) -> Option<u32> {
        let mut best: Option<(usize, u32)> = None;
        let mut label = 0;
        for r in 0..self.spans.len() {
            if labels[r] == 0 {
                label += 1;
                let (voxels, border) = self.spread(labels, label, vec![r]);
                if !border && best.is_none_or(|(most, _)| voxels > most) {
                    best = Some((voxels, label));
                }
            }
        }
        best.map(|(_, label)| label)
    }

    /// Clears the voxels of the runs `drop` picks from `empty`; returns how many.
    fn clear(&self, empty: &mut Grid<bool>, drop: impl Fn(usize) -> bool) -> usize {
        let w = self.dims[0];
        let mut cleared = 0;
        for row in 0..self.first.len() - 1 {
            for r in self.of_row(row).filter(|&r| drop(r)) {
                let [a, b] = self.spans[r];
                empty.data[row * w + a as usize..row * w + b as usize].fill(false);
                cleared += (b - a) as usize;
            }
        }
        cleared
    }
}

/// The end of the run of voxels equal to `value` from `x` on: 16 at a time while they all
/// are (one vectorised test), then one by one.
fn run_end(row: &[bool], mut x: usize, value: bool) -> usize {
    const STEP: usize = 16;
    while x + STEP <= row.len() && row[x..x + STEP].iter().fold(true, |all, &e| all & (e == value)) {
        x += STEP;
    }
    while x < row.len() && row[x] == value {
        x += 1;
    }
    x
}

/// The empty voxel whose centre is nearest to the anchor, on its side, within
/// [`ANCHOR_REACH`] voxels: the voxel that stands for a point that lies on a surface or just
/// inside a solid (an area light on its ceiling); `None` for a point in a thick solid or
/// outside the grid.
pub fn place(empty: &Grid<bool>, anchor: &Anchor) -> Option<usize> {
    let spec = &empty.spec;
    let p = anchor.position;
    let centre = [0, 1, 2].map(|a| ((p[a] - spec.origin[a]) / spec.voxel - 0.5).round() as i64);
    let mut best: Option<(f64, usize)> = None;
    for dz in -ANCHOR_REACH..=ANCHOR_REACH {
        for dy in -ANCHOR_REACH..=ANCHOR_REACH {
            for dx in -ANCHOR_REACH..=ANCHOR_REACH {
                let v = [centre[0] + dx, centre[1] + dy, centre[2] + dz];
                // Offsetting voxel 0 is the bounds check for a position that may lie outside.
                let Some([x, y, z]) = spec.offset([0; 3], v) else { continue };
                let i = spec.index(x, y, z);
                let c = spec.center(x, y, z);
                let d = [c[0] - p[0], c[1] - p[1], c[2] - p[2]];
                let on_side = d[0] * anchor.side[0] + d[1] * anchor.side[1] + d[2] * anchor.side[2] >= 0.0;
                let dist = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if empty.data[i] && on_side && best.is_none_or(|(b, _)| dist < b) {
                    best = Some((dist, i));
                }
            }
        }
    }
    best.map(|(_, i)| i)
}

/// The share of the empty voxels that `outside` (the empty voxels joined to the grid's
/// border) leaves out.
pub(crate) fn enclosed_share(empty: &Grid<bool>, outside: &[bool]) -> f64 {
    let total = empty.data.iter().filter(|&&e| e).count();
    (total - outside.iter().filter(|&&r| r).count()) as f64 / total as f64
}

/// The empty voxels joined to the grid's border by 6-paths of empty voxels.
pub(crate) fn reached_from_border(empty: &Grid<bool>) -> Vec<bool> {
    let [w, h, d] = empty.spec.dims;
    let open = &empty.data[..];
    let mut reached = vec![false; open.len()];
    // Every voxel of a border row, and the two ends of every other row.
    let mut seeds: Vec<usize> = Vec::new();
    for z in 0..d {
        for y in 0..h {
            let row = (z * h + y) * w;
            if y == 0 || z == 0 || y + 1 == h || z + 1 == d {
                seeds.extend((row..row + w).filter(|&i| open[i]));
            } else {
                seeds.extend([row, row + w - 1].into_iter().filter(|&i| open[i]));
            }
        }
    }
    scanline_fill(empty.spec.dims, &mut reached, [false, true], |i| open[i], seeds);
    reached
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{neighbours6, GridSpec};
    use crate::pipeline::{analyse, Analysis, AnalysisSettings, Resolution};
    use crate::testing::{closed_box, set_from, Lcg};

    /// The fills reach exactly the voxels a voxel-by-voxel search reaches, from the border by
    /// 6-paths (the scanline fill) and from random seeds by 26-paths (the flood over runs), on
    /// random grids dense enough to hold enclosed pockets, long runs and pockets joined only
    /// by an edge or a corner.
    #[test]
    fn fills_match_a_voxel_search() {
        let mut r = Lcg(5);
        for (k, dims) in
            [[7, 5, 4], [1, 6, 6], [12, 9, 8], [9, 1, 1], [16, 16, 3]].into_iter().cycle().take(40).enumerate()
        {
            let spec = GridSpec { origin: [0.0; 3], voxel: 1.0, dims };
            let density = 0.2 + 0.6 * (k % 4) as f64 / 3.0;
            let empty = Grid { spec, data: (0..spec.len()).map(|_| r.next() < density).collect() };
            let neighbours26 = |i: usize| {
                let v = spec.coords(i);
                let steps = (0..27).map(|n| [n % 3, n / 3 % 3, n / 9].map(|s| s as i64 - 1));
                steps.filter_map(move |d| spec.offset(v, d)).map(|[x, y, z]| spec.index(x, y, z))
            };
            let search = |seeds: Vec<usize>, twenty_six: bool| {
                let mut reached = vec![false; spec.len()];
                let mut stack = seeds;
                while let Some(i) = stack.pop() {
                    if !empty.data[i] || std::mem::replace(&mut reached[i], true) {
                        continue;
                    }
                    if twenty_six {
                        stack.extend(neighbours26(i));
                    } else {
                        stack.extend(neighbours6(dims, i));
                    }
                }
                reached
            };
            let on_border = |i: usize| {
                let v = spec.coords(i);
                (0..3).any(|a| v[a] == 0 || v[a] + 1 == dims[a])
            };
            let border = search((0..spec.len()).filter(|&i| on_border(i)).collect(), false);
            assert_eq!(reached_from_border(&empty), border, "grid {k}, {dims:?}");
            let seeds: Vec<usize> =
                (0..3).map(|_| (r.next() * spec.len() as f64) as usize).filter(|&v| empty.data[v]).collect();
            if seeds.is_empty() {
                continue;
            }
            let total = empty.data.iter().filter(|&&e| e).count();
            let (kept, reach) = keep_reachable(empty.clone(), &seeds.iter().map(|&v| Some(v)).collect::<Vec<_>>());
            let reached = search(seeds.clone(), true);
            assert!(kept.data == reached, "grid {k}, {dims:?}, 26-paths from {seeds:?}");
            assert_eq!(reach.dropped, total - reached.iter().filter(|&&f| f).count());
        }
    }

    fn at(resolution: usize) -> AnalysisSettings {
        AnalysisSettings { resolution: Resolution::Longest(resolution), ..Default::default() }
    }

    /// A camera, with its side unset.
    fn point(position: [f64; 3]) -> Anchor {
        Anchor { position, side: [0.0; 3] }
    }

    /// Whether a node of the analysis' skeleton stands on a voxel inside the open box.
    fn node_inside(a: &Analysis, [lo, hi]: [[f64; 3]; 2]) -> bool {
        a.skeleton.nodes.iter().any(|n| {
            let [x, y, z] = a.spec.coords(n.voxel);
            let c = a.spec.center(x, y, z);
            (0..3).all(|k| lo[k] < c[k] && c[k] < hi[k])
        })
    }

    /// The unit room with a closed box pillar from floor to ceiling, or a closed-box floor
    /// slab: the camera's room alone is analysed, so the skeleton is one component with no
    /// node inside the solid; kept whole, the solid's inside (and the air around the room)
    /// come back with skeletons of their own.
    #[test]
    fn closed_solids_get_no_skeleton() {
        let pillar = [[0.35, 0.35, 0.0], [0.65, 0.65, 1.0]];
        let slab = [[0.0, 0.0, 0.0], [1.0, 1.0, 0.3]];
        let camera = point([0.2, 0.2, 0.6]);
        for (name, solid) in [("pillar", pillar), ("slab", slab)] {
            let mut scene = closed_box([0.0; 3], [1.0; 3]);
            scene.extend(closed_box(solid[0], solid[1]));
            let settings = AnalysisSettings { sources: vec![camera], ..at(32) };
            let a = analyse(&scene, &settings).unwrap();
            assert_eq!(a.reach.kept, Kept::Reached, "{name}");
            assert!(a.reach.dropped > 0, "{name}");
            assert_eq!(a.skeleton.components(), 1, "{name}");
            assert_eq!(a.filtered.components(), 1, "{name}");
            assert!(!a.skeleton.nodes.is_empty() && !node_inside(&a, solid), "{name}: a node inside the solid");
            // The voxels it dropped are those of the solid's inside and of the air outside.
            let inside = |i: usize| {
                let [x, y, z] = a.spec.coords(i);
                let c = a.spec.center(x, y, z);
                (0..3).all(|k| 0.0 < c[k] && c[k] < 1.0) && !(0..3).all(|k| solid[0][k] < c[k] && c[k] < solid[1][k])
            };
            assert!((0..a.spec.len()).all(|i| !a.empty.data[i] || inside(i)), "{name}: kept a voxel outside the room");
            let all = analyse(&scene, &AnalysisSettings { keep_all_space: true, ..settings.clone() }).unwrap();
            assert_eq!((all.reach.kept, all.reach.dropped), (Kept::All, 0));
            assert!(all.skeleton.components() >= 3, "{name}: room, solid, air around: {}", all.skeleton.components());
            assert!(node_inside(&all, solid), "{name}: no node inside the solid when kept whole");
            // No camera or light: the largest enclosed component, the room again.
            let alone = analyse(&scene, &at(32)).unwrap();
            assert_eq!(alone.reach.kept, Kept::LargestEnclosed, "{name}");
            assert!(alone.empty.data == a.empty.data, "{name}");
        }
    }

    /// A light inside a closed luminaire lights its inside: the components of every source
    /// are kept.
    #[test]
    fn every_source_keeps_its_component() {
        let pillar = [[0.35, 0.35, 0.0], [0.65, 0.65, 1.0]];
        let mut scene = closed_box([0.0; 3], [1.0; 3]);
        scene.extend(closed_box(pillar[0], pillar[1]));
        let sources = vec![point([0.2, 0.2, 0.6]), point([0.5, 0.5, 0.5])];
        let a = analyse(&scene, &AnalysisSettings { sources, ..at(32) }).unwrap();
        assert_eq!(a.reach.kept, Kept::Reached);
        assert_eq!(a.skeleton.components(), 2);
        assert!(node_inside(&a, pillar));
    }

    /// A light on the ceiling (its voxel full) stands for the empty voxel below it, on the
    /// side it emits to; a source outside the grid keeps everything.
    #[test]
    fn sources_in_solids_or_outside_the_grid_fall_back() {
        let pillar = [[0.35, 0.35, 0.0], [0.65, 0.65, 1.0]];
        let mut scene = closed_box([0.0; 3], [1.0; 3]);
        scene.extend(closed_box(pillar[0], pillar[1]));
        let light = Anchor { position: [0.8, 0.5, 1.0], side: [0.0, 0.0, -1.0] };
        let on_the_ceiling = analyse(&scene, &AnalysisSettings { sources: vec![light], ..at(32) }).unwrap();
        let voxel = on_the_ceiling.source_voxels[0].expect("placed below the ceiling");
        let [x, y, z] = crate::mapping::voxel_of(&on_the_ceiling.spec, light.position).unwrap();
        assert!(!voxelised_empty(&scene, 32).get(x, y, z), "the light's voxel is full");
        assert!(on_the_ceiling.empty.data[voxel]);
        assert_eq!(on_the_ceiling.reach.kept, Kept::Reached);
        assert_eq!(on_the_ceiling.skeleton.components(), 1);
        let lost = point([50.0, 0.5, 0.5]);
        let sources = vec![light, lost];
        let a = analyse(&scene, &AnalysisSettings { sources, ..at(32) }).unwrap();
        assert_eq!(a.source_voxels[1], None);
        assert_eq!((a.reach.kept, a.reach.dropped), (Kept::AllSourceUnplaced, 0));
        assert!(a.skeleton.components() >= 3 && node_inside(&a, pillar));
    }

    /// The empty space of the scene as the analysis voxelises it at `resolution`.
    fn voxelised_empty(scene: &[[[f64; 3]; 3]], resolution: usize) -> Grid<bool> {
        let spec = GridSpec::from_bounds([0.0; 3], [1.0; 3], resolution, 0.05).unwrap();
        crate::voxelize::empty_space(&crate::voxelize::voxelize(&spec, scene))
    }

    /// In a thick solid, a source within [`ANCHOR_REACH`] voxels of the empty space stands
    /// for the nearest empty voxel on its side; farther, it has none and everything is kept.
    #[test]
    fn a_source_deep_in_a_solid_keeps_everything() {
        // Two pockets in a solid block: x 1..4 and x 14..17.
        let empty = set_from([18, 6, 6], 1.0, |x, y, z| {
            (1..5).contains(&y) && (1..5).contains(&z) && ((1..4).contains(&x) || (14..17).contains(&x))
        });
        let total = empty.data.iter().filter(|&&e| e).count();
        let near = point([6.5, 3.0, 3.0]);
        let deep = point([8.5, 3.0, 3.0]);
        let voxel = place(&empty, &near).expect("three voxels from the pocket");
        assert_eq!(empty.spec.coords(voxel)[0], 3);
        assert_eq!(place(&empty, &Anchor { side: [1.0, 0.0, 0.0], ..near }).map(|v| empty.spec.coords(v)[0]), None);
        assert_eq!(place(&empty, &deep), None);
        let (kept, reach) = keep_reachable(empty.clone(), &[Some(voxel)]);
        assert_eq!((reach.kept, reach.dropped), (Kept::Reached, total / 2));
        assert!(kept.data[voxel] && !kept.data[empty.spec.index(15, 3, 3)]);
        let (kept, reach) = keep_reachable(empty.clone(), &[Some(voxel), place(&empty, &deep)]);
        assert_eq!((reach.kept, reach.dropped), (Kept::AllSourceUnplaced, 0));
        assert!(kept.data == empty.data);
        // No sources, and both pockets enclosed and alike: the first of them.
        let (kept, reach) = keep_reachable(empty.clone(), &[]);
        assert_eq!((reach.kept, reach.dropped), (Kept::LargestEnclosed, total / 2));
        assert!(kept.data[voxel]);
        // A pocket open to the border is not enclosed: the other one is kept, even smaller.
        let open = set_from([18, 6, 6], 1.0, |x, y, z| {
            (1..5).contains(&y) && (1..5).contains(&z) && ((0..6).contains(&x) || (14..17).contains(&x))
        });
        let (kept, reach) = keep_reachable(open.clone(), &[]);
        assert_eq!(reach.kept, Kept::LargestEnclosed);
        assert!(kept.data[open.spec.index(15, 3, 3)] && !kept.data[open.spec.index(2, 3, 3)]);
        let nothing = set_from([8, 4, 4], 1.0, |x, _, _| x < 5);
        assert_eq!(keep_reachable(nothing.clone(), &[]).1.kept, Kept::AllNothingEnclosed);
    }
}
