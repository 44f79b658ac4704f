//! A static kd-tree over points, for the k nearest of a query (importance caching's record
//! look-up, Georgiev et al. 2012 §5). Implicit: the points are reordered so that every
//! subtree is a range whose median splits it, the split axis stored at the median; no
//! pointers, one array walked in place.

use crate::math::Vec3;

pub struct KdTree {
    /// Points in tree order, with their caller's index.
    points: Vec<(Vec3, u32)>,
    /// Split axis of the subtree whose median is at this position.
    axes: Vec<u8>,
}

impl KdTree {
    pub fn new(points: &[Vec3]) -> KdTree {
        let mut tree = KdTree {
            points: points.iter().enumerate().map(|(i, p)| (*p, i as u32)).collect(),
            axes: vec![0; points.len()],
        };
        let n = tree.points.len();
        tree.split(0, n);
        tree
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    fn split(&mut self, lo: usize, hi: usize) {
        if hi - lo <= 1 {
            return;
        }
        let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for (p, _) in &self.points[lo..hi] {
            min = min.min(*p);
            max = max.max(*p);
        }
        let extent = max - min;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        let mid = (lo + hi) / 2;
        self.points[lo..hi].select_nth_unstable_by(mid - lo, |a, b| a.0[axis].total_cmp(&b.0[axis]));
        self.axes[mid] = axis as u8;
        self.split(lo, mid);
        self.split(mid + 1, hi);
    }

    /// The `k` nearest points to `q` (fewer if the tree holds fewer), as (squared
    /// distance, caller's index), nearest first, written into `out` (cleared first).
    pub fn nearest(&self, q: Vec3, k: usize, out: &mut Vec<(f32, u32)>) {
        out.clear();
        if k > 0 {
            self.search(q, k, 0, self.points.len(), out);
        }
    }

    fn search(&self, q: Vec3, k: usize, lo: usize, hi: usize, out: &mut Vec<(f32, u32)>) {
        if lo >= hi {
            return;
        }
        let mid = (lo + hi) / 2;
        let (p, index) = self.points[mid];
        let d2 = (p - q).length_squared();
        if out.len() < k || d2 < out[out.len() - 1].0 {
            // Insertion into the short sorted list (k is a handful).
            let at = out.partition_point(|e| e.0 <= d2);
            if out.len() == k {
                out.pop();
            }
            out.insert(at, (d2, index));
        }
        if hi - lo == 1 {
            return;
        }
        let axis = self.axes[mid] as usize;
        let delta = q[axis] - p[axis];
        let (near, far) = if delta < 0.0 { ((lo, mid), (mid + 1, hi)) } else { ((mid + 1, hi), (lo, mid)) };
        self.search(q, k, near.0, near.1, out);
        if out.len() < k || delta * delta < out[out.len() - 1].0 {
            self.search(q, k, far.0, far.1, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::vec3;
    use crate::sampling::Rng;

    /// The tree's k nearest are a brute-force search's, for random points and queries
    /// (duplicates and a flat set included).
    #[test]
    fn nearest_matches_brute_force() {
        let mut rng = Rng::new(5, 6, 7);
        for (n, flat) in [(0usize, false), (1, false), (7, false), (300, false), (300, true)] {
            let mut pts: Vec<Vec3> =
                (0..n).map(|_| vec3(rng.next_f32(), if flat { 0.5 } else { rng.next_f32() }, rng.next_f32())).collect();
            if n > 10 {
                pts[3] = pts[4];
            }
            let tree = KdTree::new(&pts);
            let mut out = Vec::new();
            for _ in 0..200 {
                let q = vec3(rng.next_f32() * 1.2 - 0.1, rng.next_f32(), rng.next_f32());
                for k in [1, 3, 6] {
                    tree.nearest(q, k, &mut out);
                    let mut brute: Vec<(f32, u32)> =
                        pts.iter().enumerate().map(|(i, p)| ((*p - q).length_squared(), i as u32)).collect();
                    brute.sort_by(|a, b| a.0.total_cmp(&b.0));
                    brute.truncate(k);
                    let got: Vec<f32> = out.iter().map(|e| e.0).collect();
                    let want: Vec<f32> = brute.iter().map(|e| e.0).collect();
                    assert_eq!(got, want, "n = {n}, k = {k}");
                    for (d2, i) in &out {
                        assert_eq!((pts[*i as usize] - q).length_squared(), *d2);
                    }
                }
            }
        }
    }
}
