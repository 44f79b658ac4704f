//! Opening-forest regions and their portals as rendering reads them (thesis §10.3.3–10.3.4):
//! which regions a surface point belongs to, blended over a few voxels so that anything
//! chosen per region varies continuously over surfaces (§10.5's suggestion against the
//! seams of Figs. 91 and 94); the regions that hold a light; and, per portal, uniform
//! sampling of a point on its faces with the exact solid-angle density of the direction
//! towards it, summed over *every* face of the portal the line x + tω (t > 0) crosses,
//! occluded or not (a portal's faces form a staircase that one line may cross several times).
//!
//! A face belongs to portal {A, B} exactly when the voxels on its two sides are labelled A
//! and B (Def. 10.12), so the density walks the voxel grid along the line (a 3D DDA,
//! Amanatides & Woo) inside the portal's box and tests each face it crosses by its two labels:
//! no list of faces is searched.

use std::sync::Arc;

use skelight_shape::bottlenecks::join_wide_portals;
use skelight_shape::labeling::NO_LABEL;
use skelight_shape::mapping::surface_voxel;
use skelight_shape::portals::Portal;

use super::analysis::{to_f64, SkeletonGuide};
use crate::light::Light;
use crate::math::{vec3, Vec3};
use crate::scene::Scene;

/// How many distinct regions a point's blend keeps (the heaviest; more are rare).
pub const MAX_BLEND: usize = 8;

/// One portal as sampling reads it.
#[derive(Clone, Debug)]
pub struct PortalShape {
    pub from: u32,
    pub to: u32,
    /// Its faces: the lower voxel's coordinates and the axis the face is normal to.
    faces: Vec<([u32; 3], u8)>,
    /// The voxels on both sides of its faces, inclusive.
    voxel_lo: [i64; 3],
    voxel_hi: [i64; 3],
    /// World-space area (faces × voxel²).
    pub area: f32,
    pub centroid: Vec3,
}

/// A point's regions and their weights (summing to 1).
#[derive(Clone, Copy, Debug, Default)]
pub struct RegionBlend {
    len: usize,
    items: [(u32, f32); MAX_BLEND],
}

impl RegionBlend {
    pub fn single(region: u32) -> RegionBlend {
        let mut b = RegionBlend::default();
        b.items[0] = (region, 1.0);
        b.len = 1;
        b
    }
    pub fn iter(&self) -> impl Iterator<Item = (u32, f32)> + '_ {
        self.items[..self.len].iter().copied()
    }
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Adds weight `w` to `region`; a new region past [`MAX_BLEND`] replaces the lightest
    /// when heavier.
    fn add(&mut self, region: u32, w: f32) {
        if let Some(item) = self.items[..self.len].iter_mut().find(|(r, _)| *r == region) {
            item.1 += w;
        } else if self.len < MAX_BLEND {
            self.items[self.len] = (region, w);
            self.len += 1;
        } else if let Some(lightest) =
            self.items.iter_mut().min_by(|a, b| a.1.total_cmp(&b.1)).filter(|lightest| lightest.1 < w)
        {
            *lightest = (region, w);
        }
    }
    fn normalise(&mut self) {
        let total: f32 = self.iter().map(|(_, w)| w).sum();
        if total > 0.0 {
            for item in &mut self.items[..self.len] {
                item.1 /= total;
            }
        } else {
            self.len = 0;
        }
    }
}

/// The regions and portals of a scene's analysis.
pub struct Regions {
    guide: Arc<SkeletonGuide>,
    /// Per analysis region, the region it belongs to here (see [`Regions::joined`]).
    group: Vec<u32>,
    origin: Vec3,
    voxel: f32,
    dims: [i64; 3],
    /// Regions 1..=count (index 0 unused).
    pub count: u32,
    /// Each region's voxel count and the mean of its voxels' centres.
    pub sizes: Vec<u64>,
    pub centroids: Vec<Vec3>,
    pub portals: Vec<PortalShape>,
    /// For [`Regions::blend_at`] at the radius [`Regions::prepare_blend`] was given: per
    /// voxel, the one region of every labelled voxel a blend from a point in it can reach, or
    /// [`NO_LABEL`] where they differ (most of a room is one region: its points pay one
    /// lookup instead of the tent over the window).
    uniform: Option<(f32, Vec<u32>)>,
}

impl Regions {
    /// The analysis' regions as they are (the thesis' opening-forest regions, every portal
    /// kept).
    pub fn new(guide: Arc<SkeletonGuide>) -> Regions {
        Regions::joined(guide, f64::INFINITY)
    }

    /// The analysis' regions joined across every portal that is not a bottleneck at
    /// `bottleneck` (see [`join_wide_portals`]: a portal is kept when the largest ball
    /// through it is narrower than `bottleneck` × the narrower of its two sides' largest
    /// balls); a group of joined regions is one region here, and the faces between two groups
    /// form one portal.
    pub fn joined(guide: Arc<SkeletonGuide>, bottleneck: f64) -> Regions {
        let spec = guide.labelling.labels.spec;
        let origin = vec3(spec.origin[0] as f32, spec.origin[1] as f32, spec.origin[2] as f32);
        let voxel = spec.voxel as f32;
        let dims = spec.dims.map(|d| d as i64);
        let (group, count) = if bottleneck.is_finite() && guide.widths.openings.len() == guide.portals.len() {
            join_wide_portals(guide.labelling.count, &guide.widths, &guide.portals, bottleneck)
        } else {
            ((0..=guide.labelling.count).collect(), guide.labelling.count)
        };
        let mut sums = vec![[0.0f64; 3]; count as usize + 1];
        let mut sizes = vec![0u64; count as usize + 1];
        for (i, &l) in guide.labelling.labels.data.iter().enumerate() {
            if l != NO_LABEL && (l as usize) < group.len() {
                let g = group[l as usize] as usize;
                let [x, y, z] = spec.coords(i);
                let c = spec.center(x, y, z);
                for a in 0..3 {
                    sums[g][a] += c[a];
                }
                sizes[g] += 1;
            }
        }
        let centroids = sums
            .iter()
            .zip(&sizes)
            .map(|(s, &n)| {
                let n = n.max(1) as f64;
                vec3((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
            })
            .collect();
        // The faces between two groups, gathered from their regions' portals.
        let mut between: std::collections::BTreeMap<(u32, u32), Vec<&Portal>> = Default::default();
        for p in &guide.portals {
            let (a, b) = (group[p.from as usize], group[p.to as usize]);
            if a != b {
                between.entry((a.min(b), a.max(b))).or_default().push(p);
            }
        }
        let portals = between
            .into_iter()
            .map(|((from, to), parts)| {
                let faces: Vec<([u32; 3], u8)> = parts
                    .iter()
                    .flat_map(|p| p.squares.iter())
                    .map(|&(i, axis)| {
                        let [x, y, z] = spec.coords(i);
                        ([x as u32, y as u32, z as u32], axis)
                    })
                    .collect();
                let mut lo = [i64::MAX; 3];
                let mut hi = [i64::MIN; 3];
                for &(v, axis) in &faces {
                    for a in 0..3 {
                        let c = v[a] as i64;
                        lo[a] = lo[a].min(c);
                        hi[a] = hi[a].max(c + i64::from(a == axis as usize));
                    }
                }
                let area: f64 = parts.iter().map(|p| p.area).sum();
                let c =
                    parts.iter().fold([0.0f64; 3], |acc, p| [0, 1, 2].map(|a| acc[a] + p.centroid[a] * p.area / area));
                PortalShape {
                    from,
                    to,
                    faces,
                    voxel_lo: lo,
                    voxel_hi: hi,
                    area: area as f32,
                    centroid: vec3(c[0] as f32, c[1] as f32, c[2] as f32),
                }
            })
            .collect();
        Regions { guide, group, origin, voxel, dims, count, sizes, centroids, portals, uniform: None }
    }

    /// The region graph: for every region (1..=count; index 0 unused), the regions it shares
    /// a portal with and that portal's index in [`Regions::portals`].
    pub fn graph(&self) -> Vec<Vec<(u32, usize)>> {
        let mut graph = vec![Vec::new(); self.count as usize + 1];
        for (i, p) in self.portals.iter().enumerate() {
            graph[p.from as usize].push((p.to, i));
            graph[p.to as usize].push((p.from, i));
        }
        graph
    }

    /// Rectangles that stand for portal `k`'s faces, one per axis its faces are normal to
    /// (those holding at least a tenth of them): a door's gap is mostly faces along one axis,
    /// with a few across the head of the gap, which one plane would tilt. Each is the
    /// rectangle in the plane that fits its faces' corners best (normal to their covariance's
    /// least principal axis, so an oblique staircase gets its own slant), spanning them all.
    pub fn fitted_quads(&self, k: usize) -> Vec<[Vec3; 4]> {
        let p = &self.portals[k];
        let mut counts = [0usize; 3];
        p.faces.iter().for_each(|&(_, a)| counts[a as usize] += 1);
        (0..3u8)
            .filter(|&a| counts[a as usize] > 0 && 10 * counts[a as usize] >= p.faces.len())
            .map(|axis| self.fit_rectangle(p.faces.iter().filter(|f| f.1 == axis)))
            .collect()
    }

    /// The rectangle fitted to `faces` (see [`Regions::fitted_quads`]).
    fn fit_rectangle<'a>(&self, faces: impl Iterator<Item = &'a ([u32; 3], u8)> + Clone) -> [Vec3; 4] {
        let corners = faces.flat_map(|&(v, axis)| {
            let axis = axis as usize;
            let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut g = vec3(v[0] as f32, v[1] as f32, v[2] as f32);
            g[axis] += 1.0;
            [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)].map(|(db, dc)| {
                let mut q = g;
                q[b] += db;
                q[c] += dc;
                self.origin + q * self.voxel
            })
        });
        let (mut sum, mut count) = (Vec3::ZERO, 0.0f32);
        for q in corners.clone() {
            sum += q;
            count += 1.0;
        }
        let mean = sum * (1.0 / count.max(1.0));
        let mut cov = [[0.0f64; 3]; 3];
        for q in corners.clone() {
            let d = q - mean;
            for i in 0..3 {
                for j in 0..3 {
                    cov[i][j] += d[i] as f64 * d[j] as f64;
                }
            }
        }
        let [u, v, n] = principal_axes(cov).map(|e| vec3(e[0] as f32, e[1] as f32, e[2] as f32));
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for q in corners {
            for (a, e) in [u, v, n].into_iter().enumerate() {
                lo[a] = lo[a].min((q - mean).dot(e));
                hi[a] = hi[a].max((q - mean).dot(e));
            }
        }
        let centre = mean + n * (0.5 * (lo[2] + hi[2]));
        [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])].map(|(a, b)| centre + u * a + v * b)
    }

    /// Readies [`Regions::blend_at`] for `radius`: the region of each voxel's reach where it
    /// is one. A blend from a point whose half-voxel-ahead point q lies in voxel V weighs the
    /// voxels x whose centres lie closer than `radius` to q per axis: V − ½ − radius < x <
    /// V + ½ + radius, so |x − V| ≤ ⌈radius − ½⌉. Where those are one region (or outside the
    /// set) the blend is that region alone. Per axis, a sliding minimum and maximum of the
    /// labels (unlabelled voxels left out) over that reach.
    pub fn prepare_blend(&mut self, radius: f32) {
        let reach = (radius - 0.5).ceil().max(0.0) as usize;
        let labels = &self.guide.labelling.labels.data;
        let mut lo: Vec<u32> =
            labels.iter().map(|&l| if l == NO_LABEL { u32::MAX } else { self.group[l as usize] }).collect();
        let mut hi: Vec<u32> = labels.iter().map(|&l| self.group[l as usize]).collect();
        let dims = self.dims.map(|d| d as usize);
        for axis in 0..3 {
            sliding_extreme(&mut lo, dims, axis, reach, u32::min);
            sliding_extreme(&mut hi, dims, axis, reach, u32::max);
        }
        let uniform = lo.iter().zip(&hi).map(|(&a, &b)| if a == b && b != NO_LABEL { a } else { NO_LABEL }).collect();
        self.uniform = Some((radius, uniform));
    }

    pub fn voxel_size(&self) -> f32 {
        self.voxel
    }

    /// The label of voxel `v` (NO_LABEL outside the grid and for scene voxels).
    #[inline]
    fn label(&self, v: [i64; 3]) -> u32 {
        if (0..3).any(|a| v[a] < 0 || v[a] >= self.dims[a]) {
            return NO_LABEL;
        }
        let i = (v[0] + self.dims[0] * (v[1] + self.dims[1] * v[2])) as usize;
        self.group[self.guide.labelling.labels.data[i] as usize]
    }

    /// The region of the labelled voxel standing for surface point `p` seen from `towards`
    /// (eq. 151–154, as the node mapping), if any.
    pub fn region_at(&self, p: Vec3, ng: Vec3, towards: Vec3) -> Option<u32> {
        let labels = &self.guide.labelling.labels;
        let v = surface_voxel(&labels.spec, |i| labels.data[i] != NO_LABEL, to_f64(p), to_f64(ng), to_f64(towards))?;
        Some(self.group[labels.data[v] as usize])
    }

    /// The regions of surface point `p` (normal `ng`, seen from `towards`) blended over
    /// `radius` voxels: every labelled voxel whose centre lies within `radius` voxels (per
    /// axis) of the point half a voxel off the surface weighs by a tent in each axis times
    /// how far in front of the surface it lies (0 behind it, 1 from half a voxel ahead), so
    /// the weights vary continuously with `p`. Where no voxel weighs (a point deep in thin
    /// geometry), the region of [`Regions::region_at`] alone; a radius of 0 is that too (a
    /// hard switch between regions). Empty outside the grid. After
    /// [`Regions::prepare_blend`] at this radius, a point whose reach is one region gets it
    /// in one lookup.
    pub fn blend_at(&self, p: Vec3, ng: Vec3, towards: Vec3, radius: f32) -> RegionBlend {
        let n = if ng.dot(towards) >= 0.0 { ng } else { -ng };
        if radius > 0.0 {
            let q = (p + n * (0.5 * self.voxel) - self.origin) * (1.0 / self.voxel);
            if let Some((r, uniform)) = &self.uniform {
                let v = [0, 1, 2].map(|a| q[a].floor() as i64);
                if *r == radius && (0..3).all(|a| v[a] >= 0 && v[a] < self.dims[a]) {
                    let only = uniform[(v[0] + self.dims[0] * (v[1] + self.dims[1] * v[2])) as usize];
                    if only != NO_LABEL {
                        return RegionBlend::single(only);
                    }
                }
            }
            let mut blend = RegionBlend::default();
            let lo = [0, 1, 2].map(|a| (q[a] - 0.5 - radius).ceil() as i64);
            let hi = [0, 1, 2].map(|a| (q[a] - 0.5 + radius).floor() as i64);
            let pg = (p - self.origin) * (1.0 / self.voxel);
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let l = self.label([x, y, z]);
                        if l == NO_LABEL {
                            continue;
                        }
                        let c = vec3(x as f32 + 0.5, y as f32 + 0.5, z as f32 + 0.5);
                        let tent = |a: usize| (1.0 - (q[a] - c[a]).abs() / radius).max(0.0);
                        let front = ((c - pg).dot(n) + 0.5).clamp(0.0, 1.0);
                        let w = tent(0) * tent(1) * tent(2) * front;
                        if w > 0.0 {
                            blend.add(l, w);
                        }
                    }
                }
            }
            blend.normalise();
            if !blend.is_empty() {
                return blend;
            }
        }
        self.region_at(p, ng, towards).map(RegionBlend::single).unwrap_or_default()
    }

    /// The regions that hold a light: an area light's (its centroid, on the side it faces),
    /// a point or spot light's; for distant lights (directional, constant, environment), the
    /// regions touching the grid's border, whose empty space opens to the outside of the
    /// scene. Indexed by region.
    pub fn lit(&self, scene: &Scene) -> Vec<bool> {
        let mut lit = vec![false; self.count as usize + 1];
        let mut mark = |r: Option<u32>| {
            if let Some(r) = r.filter(|&r| r != NO_LABEL && (r as usize) < lit.len()) {
                lit[r as usize] = true;
            }
        };
        for anchor in super::analysis::anchors(scene, &[super::analysis::AnchorKind::Lights]) {
            let p = vec3(anchor.position[0] as f32, anchor.position[1] as f32, anchor.position[2] as f32);
            let side = vec3(anchor.side[0] as f32, anchor.side[1] as f32, anchor.side[2] as f32);
            if side.length_squared() > 0.0 {
                mark(self.region_at(p, side.normalize(), side.normalize()));
            } else {
                mark(self.region_at(p, vec3(0.0, 0.0, 1.0), vec3(0.0, 0.0, 1.0)));
            }
        }
        if scene.lights.iter().any(Light::is_infinite) {
            let [nx, ny, nz] = self.dims;
            for z in 0..nz {
                for y in 0..ny {
                    for x in 0..nx {
                        let border = x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1;
                        if border {
                            mark(Some(self.label([x, y, z])));
                        }
                    }
                }
            }
        }
        lit
    }

    /// A point drawn uniformly by area on portal `k`'s faces (density 1/area).
    pub fn sample_portal(&self, k: usize, pick: f32, u: [f32; 2]) -> Vec3 {
        let p = &self.portals[k];
        let n = p.faces.len();
        let (v, axis) = p.faces[((pick * n as f32) as usize).min(n - 1)];
        let axis = axis as usize;
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut g = vec3(v[0] as f32, v[1] as f32, v[2] as f32);
        g[axis] += 1.0;
        g[b] += u[0];
        g[c] += u[1];
        self.origin + g * self.voxel
    }

    /// The solid-angle density at `x` of the direction `w` (unit) when a point is drawn
    /// uniformly by area on portal `k` and joined to x: Σ over the portal's faces the line
    /// x + tw (t > 0) crosses of t²/(|cos θ|·area), θ between w and the face's normal; 0 when
    /// it crosses none.
    pub fn portal_pdf(&self, k: usize, x: Vec3, w: Vec3) -> f32 {
        let p = &self.portals[k];
        // The portal's box in grid units, and the line clipped to it.
        let inv = 1.0 / self.voxel;
        let g0 = (x - self.origin) * inv;
        let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
        for a in 0..3 {
            let (lo, hi) = (p.voxel_lo[a] as f32, (p.voxel_hi[a] + 1) as f32);
            if w[a] == 0.0 {
                if g0[a] < lo || g0[a] > hi {
                    return 0.0;
                }
                continue;
            }
            let (ta, tb) = ((lo - g0[a]) / w[a], (hi - g0[a]) / w[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        if t0 > t1 {
            return 0.0;
        }
        // Amanatides–Woo from the entry point, in grid units (t too: world t = grid t·voxel).
        let entry = g0 + w * t0;
        let mut v = [0, 1, 2].map(|a| (entry[a].floor() as i64).clamp(p.voxel_lo[a], p.voxel_hi[a]));
        let step = [0, 1, 2].map(|a| if w[a] > 0.0 { 1i64 } else { -1 });
        let mut next = [0, 1, 2].map(|a| {
            if w[a] == 0.0 {
                f32::INFINITY
            } else {
                let boundary = v[a] as f32 + if w[a] > 0.0 { 1.0 } else { 0.0 };
                (boundary - g0[a]) / w[a]
            }
        });
        let delta = [0, 1, 2].map(|a| if w[a] == 0.0 { f32::INFINITY } else { 1.0 / w[a].abs() });
        let mut here = self.label(v);
        let mut sum = 0.0f32;
        loop {
            let a = if next[0] <= next[1] && next[0] <= next[2] {
                0
            } else if next[1] <= next[2] {
                1
            } else {
                2
            };
            let t = next[a];
            if t > t1 {
                break;
            }
            v[a] += step[a];
            if v[a] < p.voxel_lo[a] || v[a] > p.voxel_hi[a] {
                break;
            }
            let there = self.label(v);
            if t > 0.0 && ((here == p.from && there == p.to) || (here == p.to && there == p.from)) {
                let d = t * self.voxel;
                sum += d * d * delta[a];
            }
            here = there;
            next[a] += delta[a];
        }
        sum / p.area
    }
}

/// Replaces each value of a grid (x fastest) by `pick` over the values within `reach` along
/// `axis` (a sliding minimum or maximum, window clipped at the grid's ends).
fn sliding_extreme(values: &mut [u32], dims: [usize; 3], axis: usize, reach: usize, pick: fn(u32, u32) -> u32) {
    let stride = [1, dims[0], dims[0] * dims[1]][axis];
    let n = dims[axis];
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut line = vec![0u32; n];
    for j in 0..dims[c] {
        for i in 0..dims[b] {
            let mut start = [0usize; 3];
            start[b] = i;
            start[c] = j;
            let first = start[0] + dims[0] * (start[1] + dims[1] * start[2]);
            for (k, value) in line.iter_mut().enumerate() {
                *value = values[first + k * stride];
            }
            for k in 0..n {
                let window = &line[k.saturating_sub(reach)..(k + reach + 1).min(n)];
                values[first + k * stride] = window.iter().copied().reduce(pick).unwrap_or(line[k]);
            }
        }
    }
}

/// The unit eigenvectors of a symmetric 3×3 matrix, by decreasing eigenvalue (cyclic Jacobi
/// rotations; a handful of sweeps reach f64 precision on a 3×3).
fn principal_axes(mut a: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut e = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..32 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off <= 1e-12 * (a[0][0].abs() + a[1][1].abs() + a[2][2].abs()) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            // The rotation in the (p, q) plane that zeroes a[p][q].
            let theta = 0.5 * (2.0 * a[p][q]).atan2(a[q][q] - a[p][p]);
            let (s, c) = theta.sin_cos();
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * row_p[k] - s * row_q[k];
                a[q][k] = s * row_p[k] + c * row_q[k];
            }
            for row in &mut e {
                let (ep, eq) = (row[p], row[q]);
                row[p] = c * ep - s * eq;
                row[q] = s * ep + c * eq;
            }
        }
    }
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| a[j][j].total_cmp(&a[i][i]));
    order.map(|i| [e[0][i], e[1][i], e[2][i]])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::guided::analysis::{guide_for, GuideSettings};
    use crate::sampling::Rng;
    use skelight_shape::grid::{Grid, GridSpec};
    use skelight_shape::labeling::Labelling;
    use skelight_shape::mapping::NodeMapping;

    fn two_rooms() -> (Scene, Regions) {
        let scene = crate::scene::builtin::two_rooms();
        let (guide, _) = guide_for(&scene, &GuideSettings { resolution: 48, ..Default::default() }).expect("analyses");
        (scene, Regions::new(guide))
    }

    /// The density by brute force: the line intersected with every face of portal `k`.
    fn brute(r: &Regions, k: usize, x: Vec3, w: Vec3) -> f32 {
        let p = &r.portals[k];
        let mut sum = 0.0;
        for &(v, axis) in &p.faces {
            let a = axis as usize;
            if w[a] == 0.0 {
                continue;
            }
            let plane = r.origin[a] + (v[a] as f32 + 1.0) * r.voxel;
            let t = (plane - x[a]) / w[a];
            if t <= 0.0 {
                continue;
            }
            let q = x + w * t;
            let inside = (0..3).filter(|&b| b != a).all(|b| {
                let lo = r.origin[b] + v[b] as f32 * r.voxel;
                q[b] >= lo && q[b] < lo + r.voxel
            });
            if inside {
                sum += t * t / w[a].abs();
            }
        }
        sum / p.area
    }

    /// The grid walk finds every face of the portal the line crosses: it agrees with
    /// intersecting the line with each face, from points on both sides of the staircase (a
    /// density of the first crossed face alone does not).
    #[test]
    fn the_walk_sums_every_crossed_face() {
        let r = staircase();
        let mut rng = Rng::new(9, 0, 0);
        let (mut bad, mut several) = (0, 0);
        for x in [vec3(3.3, 6.7, 2.1), vec3(7.4, 6.1, 1.3), vec3(9.7, 8.2, 3.6)] {
            for _ in 0..20000 {
                let w = uniform_direction(&mut rng);
                let (a, b) = (r.portal_pdf(0, x, w), brute(&r, 0, x, w));
                if (a - b).abs() > 1e-4 * b.max(1e-3) {
                    if bad < 5 {
                        println!("from {x:?} along {w:?}: walk {a}, faces {b}");
                    }
                    bad += 1;
                }
                several += usize::from(crossings(&r, x, w) > 1);
            }
        }
        println!("{several} of 60000 lines cross several faces");
        assert!(several > 1000, "too few lines cross several faces to test the sum: {several}");
        assert_eq!(bad, 0, "{bad} directions whose density is not the sum over their crossed faces");
    }

    /// How many faces of the staircase's portal the line from `x` along `w` crosses.
    fn crossings(r: &Regions, x: Vec3, w: Vec3) -> usize {
        r.portals[0]
            .faces
            .iter()
            .filter(|&&(v, axis)| {
                let a = axis as usize;
                let t = (v[a] as f32 + 1.0 - x[a]) / w[a];
                let q = x + w * t;
                t > 0.0 && (0..3).filter(|&b| b != a).all(|b| q[b] >= v[b] as f32 && q[b] < v[b] as f32 + 1.0)
            })
            .count()
    }

    /// Two regions of a 12×12×4 grid split by the staircase x + y = 12 (voxel indices): their
    /// portal's faces alternate between the x and y axes, so a line running along it crosses
    /// several of them.
    fn staircase() -> Regions {
        let spec = GridSpec { origin: [0.0; 3], voxel: 1.0, dims: [12, 12, 4] };
        let mut labels = Grid::new(spec, 0u32);
        for i in 0..spec.len() {
            let [x, y, _] = spec.coords(i);
            labels.data[i] = if x + y < 12 { 1 } else { 2 };
        }
        let labelling = Labelling { labels, count: 2 };
        let portals = skelight_shape::portals::portals(&labelling);
        let guide = SkeletonGuide {
            graph: Default::default(),
            mapping: NodeMapping { grid: Grid::new(spec, 0) },
            raw: Default::default(),
            labelling,
            portals,
            widths: Default::default(),
            timings: Vec::new(),
            bytes: 0,
        };
        Regions::new(Arc::new(guide))
    }

    fn uniform_direction(rng: &mut Rng) -> Vec3 {
        crate::sampling::uniform_sphere(rng.next_2d())
    }

    /// ∫ p dω over the sphere, estimated from `n` uniform directions, with its standard error.
    fn integral(r: &Regions, k: usize, x: Vec3, n: usize, rng: &mut Rng) -> (f64, f64) {
        let (mut sum, mut sq) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let f = (r.portal_pdf(k, x, uniform_direction(rng)) * 4.0 * std::f32::consts::PI) as f64;
            sum += f;
            sq += f * f;
        }
        let mean = sum / n as f64;
        (mean, ((sq / n as f64 - mean * mean) / n as f64).sqrt())
    }

    /// The portal density integrates to one over the directions: E[p/p_uniform] = 1 for
    /// uniform directions, within four standard errors. On the staircase, a direction crossing
    /// k faces counts all k; a density of the first crossed face alone falls short there.
    #[test]
    fn portal_densities_integrate_to_one() {
        let mut rng = Rng::new(3, 0, 0);
        let (_, r) = two_rooms();
        assert!(!r.portals.is_empty());
        let mut cases: Vec<(String, Regions, usize, Vec3)> = Vec::new();
        for k in (0..r.portals.len()).take(4) {
            let p = &r.portals[k];
            // From a point of one of its regions, about two voxels from its centroid and off
            // every face's plane (a face seen edge-on gives p an infinite variance).
            let off = vec3(0.31, 0.17, 0.23) * r.voxel;
            let x = p.centroid + (r.centroids[p.from as usize] - p.centroid).normalize() * (2.0 * r.voxel) + off;
            cases.push((format!("two rooms, portal {k}"), Regions::new(Arc::clone(&r.guide)), k, x));
        }
        // On the staircase, from inside region 1 and close to the steps, so that many lines
        // run along them; off the faces' planes (integer coordinates).
        for x in [vec3(3.3, 6.7, 2.1), vec3(6.4, 4.2, 1.6)] {
            cases.push((format!("staircase from {x:?}"), staircase(), 0, x));
        }
        for (name, r, k, x) in &cases {
            let (mean, se) = integral(r, *k, *x, 400_000, &mut rng);
            println!("{name}: {} faces, ∫p dω = {mean:.4} ± {se:.4}", r.portals[*k].faces.len());
            assert!((mean - 1.0).abs() < 4.0 * se, "{name}: ∫p dω = {mean} ± {se}");
        }
    }

    /// Each direction drawn towards a point on the portal has a positive density, and the
    /// mean of 1/p over such draws is the solid angle the portal covers (E[1/p] = Ω): the
    /// same Ω as the uniform-sphere estimate of the directions that cross it, within four
    /// standard errors of both.
    #[test]
    fn drawn_directions_have_their_density() {
        let mut rng = Rng::new(4, 0, 0);
        let r = staircase();
        let x = vec3(4.4, 5.7, 2.2);
        let n = 200_000;
        let (mut inv, mut inv_sq) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let y = r.sample_portal(0, rng.next_f32(), [rng.next_f32(), rng.next_f32()]);
            let pdf = r.portal_pdf(0, x, (y - x).normalize());
            assert!(pdf > 0.0, "a drawn direction has density 0");
            inv += 1.0 / pdf as f64;
            inv_sq += 1.0 / (pdf as f64 * pdf as f64);
        }
        let omega_draws = inv / n as f64;
        let se_draws = ((inv_sq / n as f64 - omega_draws * omega_draws) / n as f64).sqrt();
        let m = 400_000;
        let hits = (0..m).filter(|_| r.portal_pdf(0, x, uniform_direction(&mut rng)) > 0.0).count();
        let share = hits as f64 / m as f64;
        let omega_sphere = 4.0 * std::f64::consts::PI * share;
        let se_sphere = 4.0 * std::f64::consts::PI * (share * (1.0 - share) / m as f64).sqrt();
        println!("Ω = {omega_draws:.5} ± {se_draws:.5} (draws) vs {omega_sphere:.5} ± {se_sphere:.5} (sphere)");
        let se = (se_draws * se_draws + se_sphere * se_sphere).sqrt();
        assert!((omega_draws - omega_sphere).abs() < 4.0 * se);
    }

    /// On the embedded two rooms, joining regions across wide portals leaves one region per
    /// room and one portal, in the gap the door left ajar leaves in the doorway (x = 4–4.1,
    /// z ∈ [1.5, 2.5], y < 2): the opening forest cuts each room into several regions, and
    /// all but the gap's portals are in mid-air.
    #[test]
    fn joined_regions_are_the_rooms_and_their_portal_the_door() {
        let (scene, raw) = two_rooms();
        let joined = Regions::joined(Arc::clone(&raw.guide), 0.5);
        println!(
            "{} regions, {} portals; joined: {} and {}",
            raw.count,
            raw.portals.len(),
            joined.count,
            joined.portals.len()
        );
        assert!(raw.count > 2, "nothing to join: {} regions", raw.count);
        assert_eq!((joined.count, joined.portals.len()), (2, 1));
        let door = &joined.portals[0];
        let c = door.centroid;
        let v = joined.voxel;
        assert!((c.x - 4.05).abs() < 2.0 * v && c.y < 2.0 && (1.5 - v..2.5 + v).contains(&c.z), "portal at {c:?}");
        // The lamp's room is lit, the other is routed through the door.
        let lit = joined.lit(&scene);
        assert_eq!(lit.iter().filter(|&&l| l).count(), 1);
        let up = vec3(0.0, 1.0, 0.0);
        let (near, far) =
            (joined.region_at(vec3(1.0, 0.0, 3.0), up, up), joined.region_at(vec3(7.0, 0.0, 3.0), up, up));
        assert!(near.is_some() && near != far && lit[far.unwrap() as usize], "regions {near:?} and {far:?}");
        // The fitted rectangle stands where the door left ajar leaves its gap: on the
        // partition's far face (the door opens into the far room), as tall as the doorway,
        // from the frame at z = 1.5 to short of the door's hinge at z = 2.5 (its free edge
        // swings to z ≈ 1.56), give or take the voxels the faces step by.
        let quads = joined.fitted_quads(0);
        println!("fitted quads {quads:?}");
        assert_eq!(quads.len(), 1, "the doorway's faces are all along x");
        let quad = quads[0];
        let (lo, hi) =
            quad.iter().fold((vec3(1e9, 1e9, 1e9), vec3(-1e9, -1e9, -1e9)), |(lo, hi), &c| (lo.min(c), hi.max(c)));
        assert!(lo.x > 4.1 - v && hi.x < 4.1 + 2.0 * v, "the quad leaves the wall: {quad:?}");
        assert!((lo.y - 0.0).abs() < 2.0 * v && (hi.y - 2.0).abs() < 2.0 * v, "its height: {quad:?}");
        assert!((lo.z - 1.5).abs() < 2.0 * v && hi.z < 2.0, "its width: {quad:?}");
        // Every voxel of the joined regions carries a group's label.
        assert!(
            joined.sizes[1..].iter().all(|&n| n > 0)
                && joined.sizes.iter().sum::<u64>() == raw.sizes.iter().sum::<u64>()
        );
    }

    /// The one-lookup blend of a prepared radius is the tent's wherever the tent finds one
    /// region: at points all over the two rooms, on the floor, the walls and the partition.
    #[test]
    fn prepared_blends_are_the_tents() {
        let (_, raw) = two_rooms();
        let slow = Regions::joined(Arc::clone(&raw.guide), 0.5);
        let mut fast = Regions::joined(Arc::clone(&raw.guide), 0.5);
        fast.prepare_blend(1.5);
        let mut rng = Rng::new(8, 0, 0);
        let mut mixed = 0;
        for _ in 0..20000 {
            let u = rng.next_2d();
            let (p, n) = match (rng.next_f32() * 4.0) as u32 {
                0 => (vec3(8.0 * u.x, 0.0, 4.0 * u.y), vec3(0.0, 1.0, 0.0)),
                1 => (vec3(8.0 * u.x, 2.5 * u.y, 0.0), vec3(0.0, 0.0, 1.0)),
                2 => (vec3(4.0, 2.5 * u.y, 4.0 * u.x), vec3(-1.0, 0.0, 0.0)),
                _ => (vec3(4.1, 2.5 * u.y, 4.0 * u.x), vec3(1.0, 0.0, 0.0)),
            };
            let (a, b) = (slow.blend_at(p, n, n, 1.5), fast.blend_at(p, n, n, 1.5));
            mixed += usize::from(a.len > 1);
            let same = a.len == b.len && a.iter().zip(b.iter()).all(|(x, y)| x.0 == y.0 && (x.1 - y.1).abs() < 1e-6);
            assert!(same || a.is_empty(), "at {p:?}: tent {:?}, prepared {:?}", &a.items[..a.len], &b.items[..b.len]);
        }
        println!("{mixed} of 20000 points blend several regions");
        assert!(mixed > 20, "too few points by the door to tell");
    }

    /// A joined portal's density (the faces of several of the analysis' portals, walked by the
    /// joined labels) integrates to one, from both rooms.
    #[test]
    fn joined_portal_densities_integrate_to_one() {
        let mut rng = Rng::new(5, 0, 0);
        let (_, raw) = two_rooms();
        let joined = Regions::joined(Arc::clone(&raw.guide), 0.5);
        let off = vec3(0.31, 0.17, 0.23) * joined.voxel;
        for x in [vec3(3.0, 1.0, 2.2) + off, vec3(5.0, 1.2, 1.8) + off] {
            let (mean, se) = integral(&joined, 0, x, 400_000, &mut rng);
            println!("from {x:?}: {} faces, ∫p dω = {mean:.4} ± {se:.4}", joined.portals[0].faces.len());
            assert!((mean - 1.0).abs() < 4.0 * se, "∫p dω = {mean} ± {se}");
        }
    }

    /// The principal axes of a known covariance: an ellipsoid's axes rotated by a known
    /// rotation come back, by decreasing variance.
    #[test]
    fn principal_axes_recover_a_rotated_ellipsoid() {
        let r = crate::math::Frame::from_normal(vec3(0.3, -0.5, 0.81).normalize());
        let axes = [r.s, r.t, r.n].map(|e| [e.x as f64, e.y as f64, e.z as f64]);
        let variances = [9.0, 4.0, 0.01];
        let mut cov = [[0.0f64; 3]; 3];
        for (e, var) in axes.iter().zip(variances) {
            for i in 0..3 {
                for j in 0..3 {
                    cov[i][j] += var * e[i] * e[j];
                }
            }
        }
        let found = principal_axes(cov);
        for (f, e) in found.iter().zip(&axes) {
            let dot: f64 = (0..3).map(|i| f[i] * e[i]).sum();
            // The axes were made in f32: they are orthonormal to about 1e-7.
            assert!(dot.abs() > 1.0 - 1e-6, "axis {f:?} against {e:?}");
        }
    }

    /// The largest change of a point's blend, Σ_R |Δw_R|, per voxel moved, between
    /// neighbouring points (a hundredth of a voxel apart) of the staircase's floor z = 0 seen
    /// from above, along lines that cross the border between its two regions.
    fn steepest_blend_change(r: &Regions, radius: f32) -> f32 {
        let up = vec3(0.0, 0.0, 1.0);
        let mut steepest = 0.0f32;
        for y in [2.3f32, 5.5, 8.7] {
            let mut last: Option<RegionBlend> = None;
            for i in 0..1200 {
                let p = vec3(i as f32 * 0.01, y, 0.0);
                let blend = r.blend_at(p, up, up, radius);
                assert!((blend.iter().map(|(_, w)| w).sum::<f32>() - 1.0).abs() < 1e-4, "weights at {p:?}");
                if let Some(before) = &last {
                    let weight = |b: &RegionBlend, reg: u32| b.iter().find(|(x, _)| *x == reg).map_or(0.0, |(_, w)| w);
                    let change: f32 = (1..=2).map(|reg| (weight(&blend, reg) - weight(before, reg)).abs()).sum();
                    steepest = steepest.max(change / 0.01);
                }
                last = Some(blend);
            }
        }
        steepest
    }

    /// Blends vary continuously over surfaces: their weights sum to one, and no step along a
    /// surface changes them faster than the tent allows. A tent of radius r voxels changes a
    /// voxel's weight by at most 1/r per voxel moved in each of the two axes the floor spans;
    /// normalised, the weights of two regions move by at most twice the sum: 4/r, 2.7 at 1.5.
    /// The hard switch (radius 0) that the thesis' seams come from changes by 2 in one step (200
    /// per voxel), and this measure sees it.
    #[test]
    fn blends_are_continuous() {
        let r = staircase();
        let smooth = steepest_blend_change(&r, 1.5);
        let hard = steepest_blend_change(&r, 0.0);
        println!("steepest change per voxel: {smooth:.2} blended, {hard:.2} hard");
        assert!(smooth <= 4.0 / 1.5 + 1e-3, "the blend jumps: {smooth} per voxel");
        assert!(hard > 100.0, "the hard switch does not show as a jump ({hard}): the measure cannot see seams");
    }
}
