//! Materials: BSDFs with Mitsuba's semantics, plus the normal perturbations (bump and
//! normal maps) applied before them. All BSDF directions are in the local shading frame
//! (+z = shading normal); `wi` points towards the previous vertex, `wo` is the other one.
//! `eval` returns f(wi, wo)·|cosθo|, so that `sample` weights are eval/pdf.

mod coating;
mod conductor;
mod dielectric;
mod diffuse;
pub mod fresnel;
pub mod microfacet;
mod phong;
mod plastic;
mod ward;

pub use coating::Coating;
pub use conductor::{Conductor, RoughConductor};
pub use dielectric::{Dielectric, RoughDielectric, ThinDielectric};
pub use diffuse::{Diffuse, RoughDiffuse};
pub use phong::Phong;
pub use plastic::{Plastic, PlasticParts, RoughPlastic, TABLE_SIZE as PLASTIC_TABLE_SIZE};
pub use ward::{Ward, WardVariant};

use crate::color::Rgb;
use crate::math::{vec3, Frame, Vec2, Vec3};
use crate::texture::Texture;

/// Which quantity a path carries: radiance (camera paths) or importance (light paths).
/// Only refraction and shading normals treat the two differently.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    Radiance,
    Importance,
}

/// Per-query inputs a BSDF may read besides the directions.
#[derive(Clone, Copy, Debug)]
pub struct BsdfCtx {
    pub uv: Vec2,
    pub mode: TransportMode,
}

#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wo: Vec3,
    /// f·|cosθo| / pdf.
    pub weight: Rgb,
    /// Solid-angle density; for delta lobes the discrete probability of picking the lobe.
    pub pdf: f32,
    pub delta: bool,
}

/// What every BSDF model implements.
pub trait BsdfModel {
    /// f(wi, wo)·|cosθo| for the non-delta components.
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb;
    /// Density with which `sample` produces `wo` through its non-delta components.
    fn pdf(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32;
    /// Samples an outgoing direction (`u` picks a component, `u2` the direction).
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, u: f32, u2: Vec2) -> Option<BsdfSample>;
    /// Whether any component is non-delta (only then is light sampling useful).
    fn has_smooth(&self) -> bool {
        true
    }
    /// Whether the model transmits light through the surface (both sides are meaningful).
    fn two_sided_transmission(&self) -> bool {
        false
    }
}

/// Completes a sample of a non-delta model whose direction `wo` was drawn by any of its
/// lobes: density from `pdf` (the mixture over all lobes), weight eval/pdf. Directions
/// below the surface are rejected unless the model transmits.
pub(crate) fn weighted_sample<M: BsdfModel + ?Sized>(
    model: &M,
    ctx: &BsdfCtx,
    wi: Vec3,
    wo: Vec3,
) -> Option<BsdfSample> {
    if wo.z * wi.z <= 0.0 && !model.two_sided_transmission() {
        return None;
    }
    let pdf = model.pdf(ctx, wi, wo);
    if !(pdf > 0.0) || !pdf.is_finite() {
        return None;
    }
    Some(BsdfSample { wo, weight: model.eval(ctx, wi, wo) / pdf, pdf, delta: false })
}

/// Density of a glossy lobe mixed with a cosine-weighted diffuse base, the lobe sampled
/// with probability `glossy_weight` (how Phong and Ward sample); upper hemisphere only.
pub(crate) fn glossy_diffuse_pdf(glossy_weight: f32, lobe_pdf: impl FnOnce() -> f32, wi: Vec3, wo: Vec3) -> f32 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return 0.0;
    }
    glossy_weight * lobe_pdf() + (1.0 - glossy_weight) * crate::sampling::cosine_hemisphere_pdf(wo.z)
}

/// Samples that mixture: `lobe` maps `u2` to a direction of the glossy lobe.
pub(crate) fn sample_glossy_diffuse<M: BsdfModel + ?Sized>(
    model: &M,
    ctx: &BsdfCtx,
    wi: Vec3,
    (u, u2): (f32, Vec2),
    glossy_weight: f32,
    lobe: impl FnOnce(Vec2) -> Vec3,
) -> Option<BsdfSample> {
    if wi.z <= 0.0 {
        return None;
    }
    let wo = if u < glossy_weight { lobe(u2) } else { crate::sampling::cosine_hemisphere(u2) };
    weighted_sample(model, ctx, wi, wo)
}

/// Density of cosine-weighted sampling, for upper-hemisphere pairs only.
#[inline]
pub(crate) fn upper_cosine_pdf(wi: Vec3, wo: Vec3) -> f32 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        0.0
    } else {
        crate::sampling::cosine_hemisphere_pdf(wo.z)
    }
}

#[derive(Clone, Debug)]
pub enum Bsdf {
    Diffuse(Diffuse),
    RoughDiffuse(RoughDiffuse),
    Conductor(Conductor),
    RoughConductor(RoughConductor),
    Dielectric(Dielectric),
    ThinDielectric(ThinDielectric),
    RoughDielectric(RoughDielectric),
    Plastic(Plastic),
    RoughPlastic(RoughPlastic),
    Phong(Phong),
    Ward(Ward),
    Coating(Coating),
    /// Front BSDF above the surface, back BSDF (mirrored) below it.
    TwoSided(Box<Bsdf>, Box<Bsdf>),
    /// Absorbs everything (emitters without a reflective surface).
    Black,
}

macro_rules! dispatch {
    ($self:expr, $m:ident => $e:expr, twosided($f:ident, $b:ident) => $t:expr, black => $k:expr) => {
        match $self {
            Bsdf::Diffuse($m) => $e,
            Bsdf::RoughDiffuse($m) => $e,
            Bsdf::Conductor($m) => $e,
            Bsdf::RoughConductor($m) => $e,
            Bsdf::Dielectric($m) => $e,
            Bsdf::ThinDielectric($m) => $e,
            Bsdf::RoughDielectric($m) => $e,
            Bsdf::Plastic($m) => $e,
            Bsdf::RoughPlastic($m) => $e,
            Bsdf::Phong($m) => $e,
            Bsdf::Ward($m) => $e,
            Bsdf::Coating($m) => $e,
            Bsdf::TwoSided($f, $b) => $t,
            Bsdf::Black => $k,
        }
    };
}

#[inline]
fn flip(v: Vec3) -> Vec3 {
    vec3(v.x, v.y, -v.z)
}

impl BsdfModel for Bsdf {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        dispatch!(self, m => m.eval(ctx, wi, wo),
            twosided(f, b) => if wi.z >= 0.0 { f.eval(ctx, wi, wo) } else { b.eval(ctx, flip(wi), flip(wo)) },
            black => Rgb::BLACK)
    }
    fn pdf(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        dispatch!(self, m => m.pdf(ctx, wi, wo),
            twosided(f, b) => if wi.z >= 0.0 { f.pdf(ctx, wi, wo) } else { b.pdf(ctx, flip(wi), flip(wo)) },
            black => 0.0)
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, u: f32, u2: Vec2) -> Option<BsdfSample> {
        dispatch!(self, m => m.sample(ctx, wi, u, u2),
            twosided(f, b) => if wi.z >= 0.0 {
                f.sample(ctx, wi, u, u2)
            } else {
                b.sample(ctx, flip(wi), u, u2).map(|s| BsdfSample { wo: flip(s.wo), ..s })
            },
            black => None)
    }
    fn has_smooth(&self) -> bool {
        dispatch!(self, m => m.has_smooth(), twosided(f, b) => f.has_smooth() || b.has_smooth(), black => false)
    }
    fn two_sided_transmission(&self) -> bool {
        dispatch!(self, m => m.two_sided_transmission(), twosided(_f, _b) => false, black => false)
    }
}

impl Bsdf {
    /// Whether any lobe is a delta (mirror, smooth glass, smooth coatings): no connection
    /// between two vertices can reach such a lobe, only sampling it can.
    pub fn has_delta_lobe(&self) -> bool {
        match self {
            Bsdf::Conductor(_)
            | Bsdf::Dielectric(_)
            | Bsdf::ThinDielectric(_)
            | Bsdf::Plastic(_)
            | Bsdf::Coating(_) => true,
            Bsdf::TwoSided(f, b) => f.has_delta_lobe() || b.has_delta_lobe(),
            _ => false,
        }
    }

    /// The BSDF that answers light arriving from local direction `wi` (a two-sided
    /// material's back for `wi` below the surface, as `eval`, `pdf` and `sample` choose).
    pub fn facing(&self, wi: Vec3) -> &Bsdf {
        match self {
            Bsdf::TwoSided(f, b) => {
                if wi.z >= 0.0 {
                    f.facing(wi)
                } else {
                    b.facing(flip(wi))
                }
            }
            _ => self,
        }
    }

    /// Whether every reflection is concentrated in a narrow cone around a mirror direction
    /// (a delta lobe, or microfacets with roughness below 0.1, Phong exponents above 100):
    /// sampling any other distribution there wastes its samples.
    pub fn near_specular(&self) -> bool {
        const ROUGH: f32 = 0.1;
        let narrow = |m: &microfacet::Microfacet| m.alpha_u.max(m.alpha_v) < ROUGH;
        match self {
            Bsdf::RoughConductor(c) => narrow(&c.distribution),
            Bsdf::RoughDielectric(d) => narrow(&d.distribution),
            Bsdf::Phong(p) => p.exponent > 100.0,
            Bsdf::Ward(w) => w.alpha_u.max(w.alpha_v) < ROUGH,
            Bsdf::TwoSided(f, b) => f.near_specular() && b.near_specular(),
            _ => self.has_delta_lobe() && !self.has_smooth(),
        }
    }

    /// How many BSDFs this one is made of, itself included.
    pub fn node_count(&self) -> usize {
        match self {
            Bsdf::TwoSided(f, b) => 1 + f.node_count() + b.node_count(),
            Bsdf::Coating(c) => 1 + c.nested.node_count(),
            _ => 1,
        }
    }

    /// Rough mean albedo, for choosing between layered lobes.
    pub fn mean_albedo(&self) -> f32 {
        match self {
            Bsdf::Diffuse(d) => d.reflectance.mean().mean(),
            Bsdf::RoughDiffuse(d) => d.reflectance.mean().mean(),
            Bsdf::TwoSided(f, _) => f.mean_albedo(),
            Bsdf::Black => 0.0,
            _ => 0.5,
        }
    }
}

/// A change of shading normal computed from a texture before the BSDF is evaluated.
#[derive(Clone, Debug)]
pub enum Perturbation {
    /// Height field: the normal tilts with the height gradient, scaled.
    Bump { height: Texture, scale: f32 },
    /// Tangent-space normal map in [0, 1] encoding.
    NormalMap { normals: Texture },
}

impl Perturbation {
    /// New shading frame from the current one, the uv derivatives of position and the uv.
    pub fn apply(&self, frame: &Frame, dpdu: Vec3, dpdv: Vec3, uv: Vec2) -> Frame {
        let n = frame.n;
        let new_n = match self {
            Perturbation::Bump { height, scale } => {
                let h = 1.0 / 1024.0;
                let f = |du: f32, dv: f32| height.eval_scalar(Vec2 { x: uv.x + du, y: uv.y + dv });
                let hu = (f(h, 0.0) - f(-h, 0.0)) / (2.0 * h) * scale;
                let hv = (f(0.0, h) - f(0.0, -h)) / (2.0 * h) * scale;
                let pu = dpdu + n * hu;
                let pv = dpdv + n * hv;
                let c = pu.cross(pv);
                if c.length_squared() == 0.0 || !c.is_finite() {
                    return *frame;
                }
                let c = c.normalize();
                if c.dot(n) < 0.0 {
                    -c
                } else {
                    c
                }
            }
            Perturbation::NormalMap { normals } => {
                let t = normals.eval(uv);
                let local = vec3(2.0 * t.r - 1.0, 2.0 * t.g - 1.0, 2.0 * t.b - 1.0);
                if local.length_squared() == 0.0 {
                    return *frame;
                }
                frame.to_world(local.normalize())
            }
        };
        if !new_n.is_finite() {
            return *frame;
        }
        Frame::from_normal_tangent(new_n, frame.s)
    }
}

/// The colour that stands in for unsupported materials and textures, so that they show.
pub const FALLBACK_MAGENTA: Rgb = Rgb { r: 0.8, g: 0.0, b: 0.8 };

/// A surface's material: its BSDF and an optional normal perturbation.
#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    pub bsdf: Bsdf,
    pub perturbation: Option<Perturbation>,
}

impl Material {
    pub fn new(name: impl Into<String>, bsdf: Bsdf) -> Material {
        Material { name: name.into(), bsdf, perturbation: None }
    }
    /// The visible fallback for unsupported materials: magenta diffuse.
    pub fn fallback(name: impl Into<String>) -> Material {
        Material::new(name, Bsdf::Diffuse(Diffuse { reflectance: Texture::Constant(FALLBACK_MAGENTA) }))
    }
}

#[cfg(test)]
mod tests;
