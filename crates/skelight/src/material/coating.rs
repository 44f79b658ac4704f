//! Smooth dielectric coating over any BSDF (Mitsuba's `coating`): a specular reflection
//! on top, the nested BSDF seen through the refracting interface, optional absorption.

use super::fresnel::fresnel_dielectric;
use super::{Bsdf, BsdfCtx, BsdfModel, BsdfSample};
use crate::color::Rgb;
use crate::math::{vec3, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Coating {
    pub eta: f32,
    pub specular_reflectance: Rgb,
    /// Absorption coefficient × thickness of the layer.
    pub sigma_a_thickness: Rgb,
    pub nested: Box<Bsdf>,
    specular_weight: f32,
}

impl Coating {
    pub fn new(eta: f32, specular_reflectance: Rgb, sigma_a_thickness: Rgb, nested: Bsdf) -> Coating {
        let s = specular_reflectance.mean();
        let d = nested.mean_albedo();
        let specular_weight = if s + d > 0.0 { s / (s + d) } else { 0.5 };
        Coating { eta, specular_reflectance, sigma_a_thickness, nested: Box::new(nested), specular_weight }
    }
    /// Probability of sampling the specular reflection before Fresnel (for renderers that
    /// re-implement the model, as the GPU's).
    pub fn specular_weight(&self) -> f32 {
        self.specular_weight
    }
    /// Direction inside the layer for an outside direction `w` (same azimuth, upper side).
    fn refract_in(&self, w: Vec3) -> Vec3 {
        let inv = 1.0 / self.eta;
        let sin2 = (1.0 - w.z * w.z).max(0.0) * inv * inv;
        vec3(inv * w.x, inv * w.y, (1.0 - sin2).max(0.0).sqrt())
    }
    /// Outside direction for a direction `w` inside the layer, unless it is totally reflected.
    fn refract_out(&self, w: Vec3) -> Option<Vec3> {
        let sin2 = (1.0 - w.z * w.z).max(0.0) * self.eta * self.eta;
        if sin2 >= 1.0 {
            return None;
        }
        Some(vec3(self.eta * w.x, self.eta * w.y, (1.0 - sin2).sqrt()))
    }
    fn specular_probability(&self, r: f32) -> f32 {
        let ps = r * self.specular_weight;
        let pd = (1.0 - r) * (1.0 - self.specular_weight);
        if ps + pd > 0.0 {
            ps / (ps + pd)
        } else {
            0.0
        }
    }
    fn absorption(&self, wi_in: Vec3, wo_in: Vec3) -> Rgb {
        if self.sigma_a_thickness.is_black() {
            return Rgb::WHITE;
        }
        let len = 1.0 / wi_in.z.abs() + 1.0 / wo_in.z.abs();
        self.sigma_a_thickness.map(|s| (-s * len).exp())
    }
}

impl BsdfModel for Coating {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::BLACK;
        }
        let (wi_in, wo_in) = (self.refract_in(wi), self.refract_in(wo));
        let t = (1.0 - fresnel_dielectric(wi.z, self.eta)) * (1.0 - fresnel_dielectric(wo.z, self.eta));
        let jacobian = wo.z / (self.eta * self.eta * wo_in.z);
        self.nested.eval(ctx, wi_in, wo_in) * self.absorption(wi_in, wo_in) * (t * jacobian)
    }
    fn pdf(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let ps = self.specular_probability(fresnel_dielectric(wi.z, self.eta));
        let (wi_in, wo_in) = (self.refract_in(wi), self.refract_in(wo));
        let jacobian = wo.z / (self.eta * self.eta * wo_in.z);
        (1.0 - ps) * self.nested.pdf(ctx, wi_in, wo_in) * jacobian
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, u: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let r = fresnel_dielectric(wi.z, self.eta);
        let ps = self.specular_probability(r);
        if u < ps {
            let weight = self.specular_reflectance * (r / ps);
            return Some(BsdfSample { wo: vec3(-wi.x, -wi.y, wi.z), weight, pdf: ps, delta: true });
        }
        let u = (u - ps) / (1.0 - ps);
        let wi_in = self.refract_in(wi);
        let inner = self.nested.sample(ctx, wi_in, u, u2)?;
        if inner.wo.z <= 0.0 {
            return None;
        }
        let wo = self.refract_out(inner.wo)?;
        if inner.delta {
            // A delta lobe below stays a delta lobe; its weight carries the interface losses.
            let t = (1.0 - r) * (1.0 - fresnel_dielectric(wo.z, self.eta));
            let weight = inner.weight * self.absorption(wi_in, inner.wo) * (t / (1.0 - ps));
            return Some(BsdfSample { wo, weight, pdf: (1.0 - ps) * inner.pdf, delta: true });
        }
        let pdf = self.pdf(ctx, wi, wo);
        if !(pdf > 0.0) {
            return None;
        }
        Some(BsdfSample { wo, weight: self.eval(ctx, wi, wo) / pdf, pdf, delta: false })
    }
    fn has_smooth(&self) -> bool {
        self.nested.has_smooth()
    }
}
