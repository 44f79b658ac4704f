//! Path vertices for the bidirectional estimators (`lt`, `bpt`, `ibpt` and the skeleton-guided
//! ones built on them) and the sampling densities between them.
//!
//! Every vertex records two densities, both per unit area at the vertex (per unit solid angle
//! for a vertex at infinity): `pdf_fwd`, with which its own sub-path produced it, and
//! `pdf_rev`, with which the opposite sub-path would have produced it. Multiple importance
//! sampling (`mis`) needs nothing else.

use crate::color::Rgb;
use crate::material::{Bsdf, BsdfCtx, BsdfModel, TransportMode};
use crate::math::{vec2, vec3, Frame, Vec2, Vec3, PI};
use crate::scene::{Scene, SurfaceInteraction};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexKind {
    /// A point on the camera's lens (the pinhole itself for pinhole cameras); `n` is the
    /// viewing direction.
    Camera,
    /// A point on a light. For distant lights (`infinite`) the vertex is a direction: `n` is
    /// the direction light travels and `p` only where the ray started.
    Light { light: u32, infinite: bool },
    /// A scattering point on a surface.
    Surface,
    /// A camera ray that left the scene towards the direction `-n` (every infinite light
    /// shines along it).
    Escaped,
}

#[derive(Clone, Copy, Debug)]
pub struct Vertex {
    pub kind: VertexKind,
    /// Full surface data for `Surface` vertices; position and normal only otherwise.
    pub si: SurfaceInteraction,
    /// Throughput of the sub-path up to and including this vertex's sampling density.
    pub beta: Rgb,
    pub pdf_fwd: f32,
    pub pdf_rev: f32,
    /// The sub-path left this vertex through a specular (delta) lobe.
    pub delta: bool,
}

/// A stand-in surface record for vertices that are not on a scene surface.
fn point_record(p: Vec3, n: Vec3) -> SurfaceInteraction {
    let frame_normal = if n.length_squared() > 0.0 { n } else { vec3(0.0, 0.0, 1.0) };
    SurfaceInteraction {
        p,
        t: 0.0,
        ng: n,
        frame: Frame::from_normal(frame_normal),
        uv: vec2(0.0, 0.0),
        wi: Vec3::ZERO,
        mesh: u32::MAX,
        prim: u32::MAX,
        material: u32::MAX,
    }
}

impl Vertex {
    pub fn camera(p: Vec3, forward: Vec3, beta: Rgb, pdf_fwd: f32) -> Vertex {
        Vertex { kind: VertexKind::Camera, si: point_record(p, forward), beta, pdf_fwd, pdf_rev: 0.0, delta: false }
    }

    /// A light vertex at `p` with emitting-side normal `n` (or travel direction if infinite).
    pub fn light(light: u32, infinite: bool, p: Vec3, n: Vec3, beta: Rgb, pdf_fwd: f32) -> Vertex {
        Vertex {
            kind: VertexKind::Light { light, infinite },
            si: point_record(p, n),
            beta,
            pdf_fwd,
            pdf_rev: 0.0,
            delta: false,
        }
    }

    pub fn surface(si: SurfaceInteraction, beta: Rgb, pdf_fwd: f32) -> Vertex {
        Vertex { kind: VertexKind::Surface, si, beta, pdf_fwd, pdf_rev: 0.0, delta: false }
    }

    pub fn escaped(from: Vec3, direction: Vec3, beta: Rgb, pdf_fwd: f32) -> Vertex {
        Vertex {
            kind: VertexKind::Escaped,
            si: point_record(from + direction, -direction),
            beta,
            pdf_fwd,
            pdf_rev: 0.0,
            delta: false,
        }
    }

    /// A surface vertex on an emitter, seen as the light vertex it is for strategies that
    /// start there (the camera sub-path's densities are kept).
    pub fn as_light(&self, light: u32) -> Vertex {
        let si = &self.si;
        let n = if si.frame.n.dot(si.ng) < 0.0 { -si.ng } else { si.ng };
        Vertex { kind: VertexKind::Light { light, infinite: false }, si: point_record(si.p, n), ..*self }
    }

    /// The escaped direction, seen as a vertex on infinite light `light`.
    pub fn as_infinite_light(&self, light: u32) -> Vertex {
        Vertex { kind: VertexKind::Light { light, infinite: true }, ..*self }
    }

    #[inline]
    pub fn p(&self) -> Vec3 {
        self.si.p
    }
    /// Geometric normal (see [`VertexKind`] for the other kinds).
    #[inline]
    pub fn n(&self) -> Vec3 {
        self.si.ng
    }
    pub fn is_infinite(&self) -> bool {
        matches!(self.kind, VertexKind::Light { infinite: true, .. } | VertexKind::Escaped)
    }
    pub fn is_light(&self) -> bool {
        matches!(self.kind, VertexKind::Light { .. })
    }

    /// Whether the path this vertex lies on could have been split here: false where the
    /// sub-path went on through a specular lobe (that part of the path has no density).
    pub fn connectible(&self) -> bool {
        match self.kind {
            VertexKind::Surface => !self.delta,
            VertexKind::Escaped => false,
            _ => true,
        }
    }

    /// Whether a new connection may end here: the BSDF has a non-specular part. How the
    /// sub-path went on from here does not matter — a plastic vertex left through its
    /// specular coat still connects through its diffuse base.
    pub fn can_connect(&self, scene: &Scene) -> bool {
        match self.kind {
            VertexKind::Surface => scene.materials[self.si.material as usize].bsdf.has_smooth(),
            VertexKind::Escaped => false,
            _ => true,
        }
    }

    /// Whether a sub-path from the other end can arrive here by chance (emitters with area
    /// or at infinity; a lens with an aperture).
    pub fn hittable(&self, scene: &Scene) -> bool {
        match self.kind {
            VertexKind::Light { light, .. } => scene.lights[light as usize].can_be_hit(),
            VertexKind::Camera => scene.camera.aperture_radius > 0.0,
            _ => false,
        }
    }

    /// Whether a light vertex seen directly by the camera (a two-vertex path) is weighed
    /// against the strategies that start on the light: only for emitters with area, so that
    /// every estimator sees point and distant lights alike (see `mis`).
    pub fn seen_by_other_strategies(&self, scene: &Scene) -> bool {
        self.is_light() && !self.is_infinite() && self.hittable(scene)
    }

    /// Unit direction from this vertex towards `other`.
    pub fn dir_to(&self, other: &Vertex) -> Vec3 {
        if other.is_infinite() {
            -other.n()
        } else {
            (other.p() - self.p()).normalize()
        }
    }

    /// Converts a solid-angle density at this vertex into a density per unit area at `next`.
    pub fn convert_density(&self, pdf: f32, next: &Vertex) -> f32 {
        if next.is_infinite() {
            return pdf;
        }
        let d = next.p() - self.p();
        let dist2 = d.length_squared();
        if !(dist2 > 0.0) {
            return 0.0;
        }
        let n = next.n();
        // |cos| / dist² with one division: the dot product of the unnormalised d over dist³.
        if n.length_squared() > 0.0 {
            pdf * n.dot(d).abs() / (dist2 * dist2.sqrt())
        } else {
            pdf / dist2
        }
    }

    /// Density (per unit area at `next`) with which this vertex, reached from `prev`,
    /// samples `next`.
    pub fn pdf(&self, scene: &Scene, prev: Option<&Vertex>, next: &Vertex) -> f32 {
        match self.kind {
            VertexKind::Camera => self.convert_density(scene.camera.pdf_we(self.dir_to(next)).1, next),
            VertexKind::Light { .. } => self.pdf_light(scene, next),
            VertexKind::Surface => {
                let Some(prev) = prev else { return 0.0 };
                let bsdf = &scene.materials[self.si.material as usize].bsdf;
                let f = &self.si.frame;
                self.bsdf_density(bsdf, f.to_local(self.dir_to(prev)), f.to_local(self.dir_to(next)), next)
            }
            VertexKind::Escaped => 0.0,
        }
    }

    /// Density (per unit area at `next`) with which this light vertex's emission reaches `next`.
    pub fn pdf_light(&self, scene: &Scene, next: &Vertex) -> f32 {
        let VertexKind::Light { light, infinite } = self.kind else { return 0.0 };
        if infinite {
            // Rays start uniformly on a disk of the emission sphere's radius.
            let (_, radius) = scene.emission_sphere();
            let n = next.n();
            let cos = if n.length_squared() > 0.0 { n.dot(self.n()).abs() } else { 1.0 };
            return cos / (PI * radius * radius);
        }
        let pdf_dir = scene.lights[light as usize].pdf_le_direction(self.n(), self.dir_to(next));
        self.convert_density(pdf_dir, next)
    }

    /// Density with which a light sub-path starts at this light vertex (light choice included).
    pub fn pdf_light_origin(&self, scene: &Scene) -> f32 {
        let VertexKind::Light { light, .. } = self.kind else { return 0.0 };
        scene.light_distribution.pmf(light as usize) * scene.lights[light as usize].pdf_le_origin(self.n())
    }

    /// What this light vertex emits towards direction `d` (radiance, or intensity for
    /// point-like lights); zero for distant lights, which are handled by their sampling.
    pub fn emission(&self, scene: &Scene, d: Vec3) -> Rgb {
        let VertexKind::Light { light, infinite: false } = self.kind else { return Rgb::BLACK };
        scene.lights[light as usize].emitted_towards(self.n(), d)
    }

    /// f(prev → self → next)·|cos| at a surface vertex; with `Importance`, corrected for
    /// shading normals (the adjoint BSDF).
    pub fn f(&self, scene: &Scene, prev: &Vertex, next: &Vertex, mode: TransportMode) -> Rgb {
        self.join(scene, prev, next, mode).f
    }

    /// What a connection ending at this surface vertex needs from it: [`Vertex::f`], and the
    /// local directions from which [`Vertex::end_densities`] gives the two densities MIS
    /// needs at this end, asked for only once the connection is known to carry light.
    /// Black for other kinds.
    pub fn join(&self, scene: &Scene, prev: &Vertex, next: &Vertex, mode: TransportMode) -> Joined {
        if self.kind != VertexKind::Surface {
            return Joined { f: Rgb::BLACK, wi_local: Vec3::ZERO, wo_local: Vec3::ZERO };
        }
        self.join_towards(scene, prev, self.dir_to(next), mode)
    }

    /// [`Vertex::join`] of a surface vertex, given the unit direction `wo` towards `next`
    /// (which a connection's two ends share).
    pub fn join_towards(&self, scene: &Scene, prev: &Vertex, wo: Vec3, mode: TransportMode) -> Joined {
        let wi = self.dir_to(prev);
        let bsdf = &scene.materials[self.si.material as usize].bsdf;
        let frame = &self.si.frame;
        let (wi_local, wo_local) = (frame.to_local(wi), frame.to_local(wo));
        let f = bsdf.eval(&BsdfCtx { uv: self.si.uv, mode }, wi_local, wo_local);
        let f = match mode {
            TransportMode::Radiance => f,
            TransportMode::Importance => f * shading_normal_correction(&self.si, wi, wo),
        };
        Joined { f, wi_local, wo_local }
    }

    /// The densities at this end of a connection [`Vertex::join`] made with the same `prev`
    /// and `next` (see [`EndDensities`]), from its local directions: no BSDF lookup or
    /// direction again. Zero for vertices that are not on a surface.
    pub fn end_densities(&self, scene: &Scene, joined: &Joined, prev: &Vertex, next: &Vertex) -> EndDensities {
        if self.kind != VertexKind::Surface {
            return EndDensities::default();
        }
        let bsdf = &scene.materials[self.si.material as usize].bsdf;
        EndDensities {
            next: self.bsdf_density(bsdf, joined.wi_local, joined.wo_local, next),
            prev: self.bsdf_density(bsdf, joined.wo_local, joined.wi_local, prev),
        }
    }

    /// Density per unit area at `to` with which this surface vertex's BSDF, sampled from
    /// local direction `wi`, produces local direction `wo` towards `to` (radiance context,
    /// as sub-paths record it).
    fn bsdf_density(&self, bsdf: &Bsdf, wi: Vec3, wo: Vec3, to: &Vertex) -> f32 {
        let ctx = BsdfCtx { uv: self.si.uv, mode: TransportMode::Radiance };
        self.convert_density(bsdf.pdf(&ctx, wi, wo), to)
    }
}

/// A surface vertex's part in a connection prev → vertex → next: f·|cos| (adjoint for
/// importance), and the local directions towards prev and next for its MIS densities.
#[derive(Clone, Copy, Debug)]
pub struct Joined {
    pub f: Rgb,
    wi_local: Vec3,
    wo_local: Vec3,
}

/// The densities, per unit area, with which a connection's end vertex samples `next` having
/// come from `prev`, and `prev` having come from `next`: the same as [`Vertex::pdf`]'s, so
/// MIS can take them instead of evaluating the BSDF again.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EndDensities {
    pub next: f32,
    pub prev: f32,
}

/// Veach's correction for shading normals in importance transport (adjoint BSDF):
/// |wi·ns| |wo·ng| / (|wi·ng| |wo·ns|), with `wi` towards the light and `wo` onwards.
pub fn shading_normal_correction(si: &SurfaceInteraction, wi: Vec3, wo: Vec3) -> f32 {
    let num = wi.dot(si.frame.n).abs() * wo.dot(si.ng).abs();
    let den = wi.dot(si.ng).abs() * wo.dot(si.frame.n).abs();
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// A light sub-path that passed through the thin-lens aperture (the t = 0 strategy).
#[derive(Clone, Copy, Debug)]
pub struct LensHit {
    /// How many light vertices precede the lens on the path.
    pub light_vertices: u32,
    /// The lens vertex: `pdf_fwd` is the light side's density there, `beta` the
    /// contribution to splat (before MIS).
    pub vertex: Vertex,
    pub raster: Vec2,
}
