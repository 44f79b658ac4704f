//! The scene model every estimator reads: triangle meshes with materials, lights, camera
//! and render settings, plus the ray-tracing acceleration structure over all triangles.

pub mod builtin;
pub mod load;
pub mod shapes;

use crate::camera::Camera;
use crate::color::Rgb;
use crate::film::{Filter, MAX_FILM_SIDE};
use crate::geometry::{offset_origin, Accelerator, BuildTriangle, Bvh, Hit, HitFilter, Ray, Sphere};
use crate::light::{AreaEmitter, Light};
use crate::material::Material;
use crate::math::{vec2, Aabb, Frame, Vec2, Vec3};
use crate::sampling::{mix64, Distribution1D};
use crate::texture::Texture;

/// A triangle mesh in world space.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals, or empty for flat shading.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates, or empty (then uv = barycentrics, as in Mitsuba).
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    pub material: u32,
    /// Emitted radiance on the front side, for area lights.
    pub emission: Option<Rgb>,
    /// Opacity mask: hits where it is below a random threshold pass through.
    pub alpha: Option<Texture>,
    /// The exact shape when the mesh tessellates a sphere: rays then hit the sphere itself
    /// (see [`crate::geometry::Sphere`]), and the triangles serve only the empty-space
    /// analysis, bounds and emitter sampling (emissive spheres stay tessellated).
    pub sphere: Option<Sphere>,
}

impl Mesh {
    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        self.indices[i].map(|k| self.positions[k as usize])
    }
    pub fn uv_at(&self, i: usize, b1: f32, b2: f32) -> Vec2 {
        if self.uvs.is_empty() {
            return vec2(b1, b2);
        }
        let [a, b, c] = self.indices[i].map(|k| self.uvs[k as usize]);
        a * (1.0 - b1 - b2) + b * b1 + c * b2
    }
    /// Position derivatives (dp/du, dp/dv) of triangle `i` from its uv parameterisation (the
    /// edges when it has none or it is degenerate), for tangent frames and bump mapping.
    pub fn position_derivatives(&self, i: usize) -> (Vec3, Vec3) {
        self.derivatives_at(i, self.triangle(i))
    }

    /// [`Mesh::position_derivatives`] of triangle `i` whose vertices the caller has loaded.
    fn derivatives_at(&self, i: usize, [p0, p1, p2]: [Vec3; 3]) -> (Vec3, Vec3) {
        let (e1, e2) = (p1 - p0, p2 - p0);
        if self.uvs.is_empty() {
            return (e1, e2);
        }
        let [t0, t1, t2] = self.indices[i].map(|k| self.uvs[k as usize]);
        let (du1, dv1, du2, dv2) = (t1.x - t0.x, t1.y - t0.y, t2.x - t0.x, t2.y - t0.y);
        let det = du1 * dv2 - dv1 * du2;
        if det.abs() < 1e-12 {
            (e1, e2)
        } else {
            let inv = 1.0 / det;
            ((e1 * dv2 - e2 * dv1) * inv, (e2 * du1 - e1 * du2) * inv)
        }
    }
    /// What triangle `i`'s hits share: its unit geometric normal and, where the shading
    /// normal is the same at every point (no shading normals, or three equal ones, as on
    /// flat-shaded shapes), its shading frame with the tangent along dp/du.
    pub fn triangle_frames(&self, i: usize) -> TriangleFrames {
        let [p0, p1, p2] = self.triangle(i);
        let ng = (p1 - p0).cross(p2 - p0).normalize();
        let ns = match self.indices[i].map(|k| self.normals.get(k as usize)) {
            [None, ..] => Some(ng),
            [Some(a), Some(b), Some(c)] if a == b && b == c && a.length_squared() > 0.0 => Some(a.normalize()),
            _ => None,
        };
        let shading = ns.map(|n| Frame::from_normal_tangent(n, self.position_derivatives(i).0));
        TriangleFrames { ng, shading }
    }
}

/// See [`Mesh::triangle_frames`]. Kept per triangle by the scene: most hits then need no
/// square root for their normals and frame.
#[derive(Clone, Copy, Debug)]
pub struct TriangleFrames {
    pub ng: Vec3,
    /// The shading frame, when it does not vary over the triangle.
    pub shading: Option<Frame>,
}

/// Settings a scene file carries besides its contents.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: usize,
    pub height: usize,
    pub filter: Filter,
    pub spp: u32,
    /// Longest path in segments (Mitsuba's `max_depth`; -1 = unbounded).
    pub max_depth: i32,
    /// Depth from which Russian roulette starts.
    pub rr_depth: u32,
    /// Integrator the file names (the command line chooses the estimator).
    pub integrator: String,
    /// The integrator's other properties as `name`, `value` text (Mitsuba's `<float
    /// name="strength" value="16"/>`), applied when the chosen estimator is the one named.
    pub integrator_params: Vec<(String, String)>,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 768,
            height: 576,
            filter: Filter::Gaussian { stddev: 0.5 },
            spp: 64,
            max_depth: -1,
            rr_depth: 5,
            integrator: "path".into(),
            integrator_params: Vec::new(),
        }
    }
}

/// Refuses resolutions that are zero, negative, or too large to hold in memory.
pub fn check_resolution(w: i64, h: i64) -> Result<(), String> {
    if w <= 0 || h <= 0 {
        return Err(format!("resolution {w}×{h} must be positive"));
    }
    if w > MAX_FILM_SIDE || h > MAX_FILM_SIDE || w * h > 1 << 28 {
        return Err(format!("resolution {w}×{h} is too large (at most {MAX_FILM_SIDE} on a side and 2^28 pixels)"));
    }
    Ok(())
}

/// What a loader produces: everything but the acceleration structure.
#[derive(Debug, Default)]
pub struct SceneDescription {
    pub meshes: Vec<Mesh>,
    pub materials: Vec<Material>,
    /// Lights other than emissive meshes (which come from `Mesh::emission`).
    pub lights: Vec<Light>,
    pub camera: Option<Camera>,
    pub settings: RenderSettings,
    pub warnings: Vec<String>,
}

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("scene has no camera")]
    NoCamera,
    #[error("mesh '{mesh}': {reason}")]
    BadMesh { mesh: String, reason: String },
    #[error("{0}")]
    Invalid(String),
}

/// A ray's hit with everything shading needs.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteraction {
    pub p: Vec3,
    pub t: f32,
    /// Geometric normal (from the winding).
    pub ng: Vec3,
    /// Shading frame (interpolated normal, perturbed by bump/normal maps).
    pub frame: Frame,
    pub uv: Vec2,
    /// Direction towards the ray's origin, world space.
    pub wi: Vec3,
    pub mesh: u32,
    pub prim: u32,
    pub material: u32,
}

impl SurfaceInteraction {
    /// Ray leaving the surface in direction `d` without re-hitting it.
    pub fn spawn_ray(&self, d: Vec3) -> Ray {
        Ray::new(offset_origin(self.p, self.ng, d), d)
    }
    /// Ray towards point `q`, stopping just short of it.
    pub fn spawn_ray_to(&self, q: Vec3) -> Ray {
        let o = offset_origin(self.p, self.ng, q - self.p);
        let d = q - o;
        Ray { o, d, tmax: 1.0 - 1e-4 }
    }
}

pub struct Scene {
    pub meshes: Vec<Mesh>,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    /// Light selection in proportion to power.
    pub light_distribution: Distribution1D,
    /// Index into `lights` of each mesh's area emitter.
    pub mesh_light: Vec<Option<u32>>,
    pub infinite_lights: Vec<u32>,
    pub camera: Camera,
    pub settings: RenderSettings,
    pub warnings: Vec<String>,
    accel: Box<dyn Accelerator>,
    /// Global triangle index → (mesh, triangle within mesh).
    tri_owner: Vec<(u32, u32)>,
    /// Global triangle index → [`Mesh::triangle_frames`].
    frames: Vec<TriangleFrames>,
    /// Meshes traced as exact spheres, tested one by one after the accelerator (scenes
    /// have few; their triangles are not in the accelerator).
    spheres: Vec<(u32, Sphere)>,
    bounds: Aabb,
}

/// Alpha test used during traversal: a deterministic hash of the ray picks the threshold,
/// so a mask of opacity a is hit with probability a.
struct AlphaFilter<'a> {
    meshes: &'a [Mesh],
    owner: &'a [(u32, u32)],
}

impl HitFilter for AlphaFilter<'_> {
    fn accept(&self, ray: &Ray, prim: u32, b1: f32, b2: f32) -> bool {
        let (m, t) = self.owner[prim as usize];
        let mesh = &self.meshes[m as usize];
        let Some(alpha) = &mesh.alpha else {
            return true;
        };
        let a = alpha.eval_scalar(mesh.uv_at(t as usize, b1, b2));
        if a >= 1.0 {
            return true;
        }
        if a <= 0.0 {
            return false;
        }
        let h = mix64(
            (ray.o.x.to_bits() as u64)
                ^ ((ray.o.y.to_bits() as u64) << 21)
                ^ ((ray.o.z.to_bits() as u64) << 42)
                ^ mix64((ray.d.x.to_bits() as u64) ^ ((ray.d.y.to_bits() as u64) << 32) ^ prim as u64)
                ^ (ray.d.z.to_bits() as u64).rotate_left(17),
        );
        ((h >> 40) as f32 * (1.0 / 16_777_216.0)) < a
    }
}

impl Scene {
    pub fn build(desc: SceneDescription) -> Result<Scene, SceneError> {
        let SceneDescription { mut meshes, mut materials, lights: mut other_lights, camera, settings, warnings } = desc;
        let camera = camera.ok_or(SceneError::NoCamera)?;
        if materials.is_empty() {
            materials.push(Material::fallback("default"));
        }
        let mut tris = Vec::new();
        let mut tri_owner = Vec::new();
        let mut frames = Vec::new();
        let mut spheres = Vec::new();
        for mesh in meshes.iter_mut() {
            // Emitters are sampled on their triangles, and masks are tested on them: those
            // spheres stay tessellated.
            if mesh.emission.is_some_and(|e| !e.is_black()) || mesh.alpha.is_some() {
                mesh.sphere = None;
            }
        }
        for (mi, mesh) in meshes.iter().enumerate() {
            let bad = |reason: String| SceneError::BadMesh { mesh: mesh.name.clone(), reason };
            if mesh.material as usize >= materials.len() {
                return Err(bad(format!("material index {} out of range", mesh.material)));
            }
            if !mesh.normals.is_empty() && mesh.normals.len() != mesh.positions.len() {
                return Err(bad("normal count differs from vertex count".into()));
            }
            if !mesh.uvs.is_empty() && mesh.uvs.len() != mesh.positions.len() {
                return Err(bad("texture coordinate count differs from vertex count".into()));
            }
            if let Some(p) = mesh.positions.iter().find(|p| !p.is_finite()) {
                return Err(bad(format!("non-finite vertex position {p:?}")));
            }
            if let Some(p) = mesh.positions.iter().find(|p| p.abs().max_component() > MAX_COORDINATE) {
                return Err(bad(format!("vertex {p:?} lies beyond ±{MAX_COORDINATE:e}, too far to render")));
            }
            for (ti, idx) in mesh.indices.iter().enumerate() {
                if idx.iter().any(|&k| k as usize >= mesh.positions.len()) {
                    return Err(bad(format!(
                        "triangle {ti} refers to a vertex beyond the {} given",
                        mesh.positions.len()
                    )));
                }
            }
            if let Some(sphere) = mesh.sphere {
                spheres.push((mi as u32, sphere));
                continue;
            }
            for ti in 0..mesh.indices.len() {
                tris.push(BuildTriangle { v: mesh.triangle(ti), masked: mesh.alpha.is_some() });
                tri_owner.push((mi as u32, ti as u32));
                frames.push(mesh.triangle_frames(ti));
            }
        }
        if tris.len() >= (1usize << 31) {
            return Err(SceneError::Invalid("more than 2^31 triangles".into()));
        }
        let bvh = Bvh::build(&tris);
        let mut bounds = bvh.bounds();
        for (_, sphere) in &spheres {
            bounds = bounds.union(sphere.bounds());
        }
        let radius = if bounds.is_empty() { 1.0 } else { bounds.bounding_radius().max(1e-3) };

        // Emissive meshes become area lights.
        let mut lights = Vec::new();
        let mut mesh_light = vec![None; meshes.len()];
        for (mi, mesh) in meshes.iter().enumerate() {
            let Some(radiance) = mesh.emission else {
                continue;
            };
            if radiance.is_black() {
                continue;
            }
            let triangles: Vec<[Vec3; 3]> = (0..mesh.indices.len()).map(|t| mesh.triangle(t)).collect();
            let normals = (!mesh.normals.is_empty())
                .then(|| mesh.indices.iter().map(|idx| idx.map(|k| mesh.normals[k as usize])).collect());
            let Some(emitter) = AreaEmitter::new(mi as u32, radiance, triangles, normals) else { continue };
            mesh_light[mi] = Some(lights.len() as u32);
            lights.push(Light::Area(emitter));
        }
        lights.append(&mut other_lights);
        let infinite_lights = lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.is_infinite() && !l.is_delta())
            .map(|(i, _)| i as u32)
            .collect();
        let light_distribution = Distribution1D::new(&lights.iter().map(|l| l.power(radius)).collect::<Vec<_>>());
        Ok(Scene {
            meshes,
            materials,
            lights,
            light_distribution,
            mesh_light,
            infinite_lights,
            camera,
            settings,
            warnings,
            accel: Box::new(bvh),
            tri_owner,
            frames,
            spheres,
            bounds,
        })
    }

    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
    /// Centre and radius of the sphere distant lights shine through: their emitted rays start
    /// on a disk of this radius (slightly larger than the scene, so it never cuts geometry).
    pub fn emission_sphere(&self) -> (Vec3, f32) {
        let b = self.bounds;
        if b.is_empty() {
            (Vec3::ZERO, 1.0)
        } else {
            (b.center(), b.bounding_radius().max(1e-3) * 1.01)
        }
    }
    /// Changes the image size, keeping the camera's field of view.
    pub fn set_resolution(&mut self, width: usize, height: usize) {
        self.camera = self.camera.with_resolution(width, height);
        self.settings.width = width;
        self.settings.height = height;
    }
    pub fn triangle_count(&self) -> usize {
        self.tri_owner.len()
    }
    /// Every triangle of every mesh, exact spheres' tessellations included: the surfaces
    /// for analyses that need triangles (voxelisation).
    pub fn surface_triangles(&self) -> Vec<[Vec3; 3]> {
        self.meshes.iter().flat_map(|m| (0..m.indices.len()).map(|t| m.triangle(t))).collect()
    }
    /// Every triangle in global order, as accelerators take them (exact spheres are traced
    /// apart from them).
    pub fn build_triangles(&self) -> Vec<BuildTriangle> {
        self.tri_owner
            .iter()
            .map(|&(m, t)| {
                let mesh = &self.meshes[m as usize];
                BuildTriangle { v: mesh.triangle(t as usize), masked: mesh.alpha.is_some() }
            })
            .collect()
    }
    /// Replaces the ray-tracing backend (it must have been built from `build_triangles`).
    pub fn set_accelerator(&mut self, accel: Box<dyn Accelerator>) {
        self.accel = accel;
    }

    fn filter(&self) -> AlphaFilter<'_> {
        AlphaFilter { meshes: &self.meshes, owner: &self.tri_owner }
    }

    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let hit = self.accel.intersect(ray, &self.filter());
        let tmax = hit.as_ref().map_or(ray.tmax, |h| h.t);
        if let Some((mi, sphere, t)) = self.nearest_sphere(ray, tmax) {
            return Some(self.sphere_interaction(mi, &sphere, t, ray));
        }
        Some(self.triangle_interaction(&hit?, ray))
    }

    /// The nearest exact sphere `ray` meets before `tmax`.
    fn nearest_sphere(&self, ray: &Ray, mut tmax: f32) -> Option<(u32, Sphere, f32)> {
        let mut best = None;
        for &(mi, sphere) in &self.spheres {
            if let Some(t) = sphere.intersect(ray, tmax) {
                tmax = t;
                best = Some((mi, sphere, t));
            }
        }
        best
    }

    fn sphere_interaction(&self, mi: u32, sphere: &Sphere, t: f32, ray: &Ray) -> SurfaceInteraction {
        let (p, outward, uv, dpdu, dpdv) = sphere.surface_at(ray.at(t));
        let n = sphere.facing(outward);
        let material = self.meshes[mi as usize].material;
        let mut frame = Frame::from_normal_tangent(n, dpdu);
        if let Some(perturb) = &self.materials[material as usize].perturbation {
            frame = perturb.apply(&frame, dpdu, dpdv, uv);
        }
        SurfaceInteraction { p, t, ng: n, frame, uv, wi: -ray.d.normalize(), mesh: mi, prim: 0, material }
    }

    fn triangle_interaction(&self, hit: &Hit, ray: &Ray) -> SurfaceInteraction {
        let (mi, ti) = self.tri_owner[hit.prim as usize];
        let mesh = &self.meshes[mi as usize];
        let ti = ti as usize;
        let (b1, b2) = (hit.b1, hit.b2);
        let b0 = 1.0 - b1 - b2;
        let [p0, p1, p2] = mesh.triangle(ti);
        let p = p0 * b0 + p1 * b1 + p2 * b2;
        let TriangleFrames { ng, shading } = self.frames[hit.prim as usize];
        let uv = mesh.uv_at(ti, b1, b2);
        let material = mesh.material;
        let perturbation = &self.materials[material as usize].perturbation;
        let frame = match (shading, perturbation) {
            (Some(frame), None) => frame,
            _ => {
                let (dpdu, dpdv) = mesh.derivatives_at(ti, [p0, p1, p2]);
                let frame = shading.unwrap_or_else(|| {
                    let [n0, n1, n2] = mesh.indices[ti].map(|k| mesh.normals[k as usize]);
                    let n = n0 * b0 + n1 * b1 + n2 * b2;
                    let ns = if n.length_squared() > 0.0 { n.normalize() } else { ng };
                    Frame::from_normal_tangent(ns, dpdu)
                });
                match perturbation {
                    Some(perturb) => perturb.apply(&frame, dpdu, dpdv, uv),
                    None => frame,
                }
            }
        };
        let wi = -ray.d.normalize();
        SurfaceInteraction { p, t: hit.t, ng, frame, uv, wi, mesh: mi, prim: ti as u32, material }
    }

    pub fn occluded(&self, ray: &Ray) -> bool {
        self.spheres.iter().any(|(_, s)| s.intersect(ray, ray.tmax).is_some())
            || self.accel.occluded(ray, &self.filter())
    }

    /// Radiance emitted by the surface towards `si.wi` (zero unless it is an emitter's front).
    pub fn emitted(&self, si: &SurfaceInteraction) -> Rgb {
        match self.meshes[si.mesh as usize].emission {
            Some(l) if si.frame.n.dot(si.wi) > 0.0 => l,
            _ => Rgb::BLACK,
        }
    }

    /// Radiance from infinite lights along a ray that left the scene in direction `d`.
    pub fn environment(&self, d: Vec3) -> Rgb {
        self.infinite_lights.iter().fold(Rgb::BLACK, |acc, &i| acc + self.lights[i as usize].eval_infinite(d))
    }
}

/// Largest coordinate a vertex may have: beyond it, areas and the BVH's costs (extent² ×
/// triangle count) overflow f32, and so does the distance of the default view.
pub const MAX_COORDINATE: f32 = 1e12;

/// A camera that frames all meshes from the front (+z towards −z), for files without one.
/// Geometry that is not finite or lies beyond [`MAX_COORDINATE`] is left out of the framing
/// (`Scene::build` refuses it).
pub fn default_camera(desc: &SceneDescription) -> Camera {
    let mut b = Aabb::EMPTY;
    desc.meshes
        .iter()
        .flat_map(|m| m.positions.iter())
        .filter(|p| p.is_finite() && p.abs().max_component() <= MAX_COORDINATE)
        .for_each(|p| b.grow(*p));
    if b.is_empty() {
        b = Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };
    }
    let c = b.center();
    let r = b.bounding_radius().max(1e-3);
    let fov: f32 = 45.0;
    // Never so close to a far-off centre that the two are one point in f32.
    let dist = (r / (fov.to_radians() * 0.5).sin()).max(c.abs().max_component() * 1e-5);
    let target = [c.x as f64, c.y as f64, c.z as f64];
    let origin = [target[0], target[1], target[2] + dist as f64];
    let t = crate::math::Transform::look_at(origin, target, [0.0, 1.0, 0.0]).expect("a view along −z is valid");
    let s = &desc.settings;
    Camera::new(
        t,
        s.width,
        s.height,
        fov,
        crate::camera::FovAxis::X,
        crate::camera::Lens::PINHOLE,
        Camera::DEFAULT_NEAR_CLIP,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::vec3;
    use crate::sampling::Rng;

    fn scene_of(normals: Vec<Vec3>) -> Scene {
        let mesh = Mesh {
            name: "tri".into(),
            positions: vec![vec3(-1.0, -1.0, 0.0), vec3(1.0, -1.0, 0.3), vec3(0.0, 1.0, -0.2)],
            normals,
            uvs: Vec::new(),
            indices: vec![[0, 1, 2]],
            material: 0,
            emission: None,
            alpha: None,
            sphere: None,
        };
        let mut desc = SceneDescription { meshes: vec![mesh], ..Default::default() };
        desc.camera = Some(default_camera(&desc));
        Scene::build(desc).unwrap()
    }

    /// Hits take the frames kept per triangle where the shading normal is the same over the
    /// triangle, and interpolate where it is not: either way the frame is the one built
    /// from the mesh data at the hit point.
    #[test]
    fn hit_frames_match_the_mesh_data() {
        let tilted = vec3(0.2, 0.1, 1.0);
        let cases = [
            ("no normals", Vec::new()),
            ("equal normals", vec![tilted; 3]),
            ("varying normals", vec![vec3(0.0, 0.0, 1.0), vec3(0.5, 0.0, 1.0), vec3(0.0, -0.4, 1.0)]),
        ];
        let mut rng = Rng::new(3, 0, 0);
        for (name, normals) in cases {
            let scene = scene_of(normals.clone());
            let mesh = &scene.meshes[0];
            let [p0, p1, p2] = mesh.triangle(0);
            let ng = (p1 - p0).cross(p2 - p0).normalize();
            for _ in 0..1000 {
                let (mut b1, mut b2) = (rng.next_f32(), rng.next_f32());
                if b1 + b2 > 1.0 {
                    (b1, b2) = (1.0 - b1, 1.0 - b2);
                }
                let b0 = 1.0 - b1 - b2;
                let target = p0 * b0 + p1 * b1 + p2 * b2;
                let o = target + vec3(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 2.0);
                let si = scene.intersect(&Ray::new(o, (target - o).normalize())).expect("the ray meets the triangle");
                let ns = if normals.is_empty() {
                    ng
                } else {
                    (normals[0] * b0 + normals[1] * b1 + normals[2] * b2).normalize()
                };
                let expected = Frame::from_normal_tangent(ns, p1 - p0);
                // Both are unit vectors a few tens of f32 roundings from the exact frame (the
                // hit's barycentrics from the watertight test, interpolation, normalisation,
                // Gram–Schmidt): within 32 ε of each other (observed worst 2.5 ε). A frame
                // from the wrong normal is off by tenths.
                let close = |a: Vec3, b: Vec3| (a - b).length() <= 32.0 * f32::EPSILON;
                assert!(close(si.ng, ng), "{name}: geometric normal {:?}, expected {ng:?}", si.ng);
                assert!(
                    close(si.frame.n, expected.n) && close(si.frame.s, expected.s) && close(si.frame.t, expected.t),
                    "{name}: frame {:?} at ({b1}, {b2}), expected {expected:?}",
                    si.frame
                );
            }
        }
    }
}
