//! Lambertian and Oren–Nayar rough diffuse reflection.

use super::{upper_cosine_pdf, weighted_sample, BsdfCtx, BsdfModel, BsdfSample};
use crate::color::Rgb;
use crate::math::{Vec2, Vec3, INV_PI};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::texture::Texture;

#[derive(Clone, Debug)]
pub struct Diffuse {
    pub reflectance: Texture,
}

/// A direction from the cosine lobe, on the side of `wi` when that is above the surface,
/// and its density; `None` from below the surface or for a grazing sample.
fn cosine_lobe(wi: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
    if wi.z <= 0.0 {
        return None;
    }
    let wo = cosine_hemisphere(u);
    let pdf = cosine_hemisphere_pdf(wo.z);
    (pdf > 0.0).then_some((wo, pdf))
}

/// Samples the cosine lobe and returns the sample weighted by `eval/pdf`.
pub(crate) fn sample_cosine<M: BsdfModel + ?Sized>(model: &M, ctx: &BsdfCtx, wi: Vec3, u: Vec2) -> Option<BsdfSample> {
    weighted_sample(model, ctx, wi, cosine_lobe(wi, u)?.0)
}

impl BsdfModel for Diffuse {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::BLACK;
        }
        self.reflectance.eval(ctx.uv) * (INV_PI * wo.z)
    }
    fn pdf(&self, _: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        upper_cosine_pdf(wi, wo)
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, _: f32, u: Vec2) -> Option<BsdfSample> {
        let (wo, pdf) = cosine_lobe(wi, u)?;
        // eval / pdf without the division: the cosine and 1/π cancel.
        Some(BsdfSample { wo, weight: self.reflectance.eval(ctx.uv), pdf, delta: false })
    }
}

/// Oren–Nayar (qualitative model); `alpha` is the standard deviation of facet angles (radians).
#[derive(Clone, Debug)]
pub struct RoughDiffuse {
    pub reflectance: Texture,
    pub alpha: f32,
}

impl BsdfModel for RoughDiffuse {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::BLACK;
        }
        let s2 = self.alpha * self.alpha;
        let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
        let b = 0.45 * s2 / (s2 + 0.09);
        let sin_i = (1.0 - wi.z * wi.z).max(0.0).sqrt();
        let sin_o = (1.0 - wo.z * wo.z).max(0.0).sqrt();
        let cos_phi = if sin_i > 1e-4 && sin_o > 1e-4 {
            ((wi.x * wo.x + wi.y * wo.y) / (sin_i * sin_o)).clamp(-1.0, 1.0)
        } else {
            0.0
        };
        let (sin_alpha, tan_beta) = if wi.z > wo.z { (sin_o, sin_i / wi.z) } else { (sin_i, sin_o / wo.z) };
        let on = a + b * cos_phi.max(0.0) * sin_alpha * tan_beta;
        self.reflectance.eval(ctx.uv) * (INV_PI * wo.z * on)
    }
    fn pdf(&self, _: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        upper_cosine_pdf(wi, wo)
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, _: f32, u: Vec2) -> Option<BsdfSample> {
        sample_cosine(self, ctx, wi, u)
    }
}
