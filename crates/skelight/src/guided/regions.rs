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

use skelight_shape::labeling::NO_LABEL;
use skelight_shape::mapping::surface_voxel;

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
    origin: Vec3,
    voxel: f32,
    dims: [i64; 3],
    /// Regions 1..=count (index 0 unused).
    pub count: u32,
    /// Each region's voxel count and the mean of its voxels' centres.
    pub sizes: Vec<u64>,
    pub centroids: Vec<Vec3>,
    pub portals: Vec<PortalShape>,
}

impl Regions {
    pub fn new(guide: Arc<SkeletonGuide>) -> Regions {
        let spec = guide.labelling.labels.spec;
        let origin = vec3(spec.origin[0] as f32, spec.origin[1] as f32, spec.origin[2] as f32);
        let voxel = spec.voxel as f32;
        let dims = spec.dims.map(|d| d as i64);
        let count = guide.labelling.count;
        let mut sums = vec![[0.0f64; 3]; count as usize + 1];
        let mut sizes = vec![0u64; count as usize + 1];
        for (i, &l) in guide.labelling.labels.data.iter().enumerate() {
            if l != NO_LABEL && (l as usize) < sizes.len() {
                let [x, y, z] = spec.coords(i);
                let c = spec.center(x, y, z);
                for a in 0..3 {
                    sums[l as usize][a] += c[a];
                }
                sizes[l as usize] += 1;
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
        let portals = guide
            .portals
            .iter()
            .map(|p| {
                let faces: Vec<([u32; 3], u8)> = p
                    .squares
                    .iter()
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
                let c = p.centroid;
                PortalShape {
                    from: p.from,
                    to: p.to,
                    faces,
                    voxel_lo: lo,
                    voxel_hi: hi,
                    area: p.area as f32,
                    centroid: vec3(c[0] as f32, c[1] as f32, c[2] as f32),
                }
            })
            .collect();
        Regions { guide, origin, voxel, dims, count, sizes, centroids, portals }
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
        self.guide.labelling.labels.data[i]
    }

    /// The region of the labelled voxel standing for surface point `p` seen from `towards`
    /// (eq. 151–154, as the node mapping), if any.
    pub fn region_at(&self, p: Vec3, ng: Vec3, towards: Vec3) -> Option<u32> {
        let labels = &self.guide.labelling.labels;
        let v = surface_voxel(&labels.spec, |i| labels.data[i] != NO_LABEL, to_f64(p), to_f64(ng), to_f64(towards))?;
        Some(labels.data[v])
    }

    /// The regions of surface point `p` (normal `ng`, seen from `towards`) blended over
    /// `radius` voxels: every labelled voxel whose centre lies within `radius` voxels (per
    /// axis) of the point half a voxel off the surface weighs by a tent in each axis times
    /// how far in front of the surface it lies (0 behind it, 1 from half a voxel ahead), so
    /// the weights vary continuously with `p`. Where no voxel weighs (a point deep in thin
    /// geometry), the region of [`Regions::region_at`] alone; a radius of 0 is that too (a
    /// hard switch between regions). Empty outside the grid.
    pub fn blend_at(&self, p: Vec3, ng: Vec3, towards: Vec3, radius: f32) -> RegionBlend {
        let n = if ng.dot(towards) >= 0.0 { ng } else { -ng };
        if radius > 0.0 {
            let mut blend = RegionBlend::default();
            let q = (p + n * (0.5 * self.voxel) - self.origin) * (1.0 / self.voxel);
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
        let (guide, _) = guide_for(&scene, &GuideSettings { resolution: 48 }).expect("analyses");
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
