//! Smooth and rough conductors (complex Fresnel; GGX or Beckmann microfacets).

use super::fresnel::fresnel_conductor;
use super::microfacet::Microfacet;
use super::{weighted_sample, BsdfCtx, BsdfModel, BsdfSample};
use crate::color::Rgb;
use crate::math::{vec3, Vec2, Vec3};
use crate::texture::Texture;

#[derive(Clone, Debug)]
pub struct Conductor {
    pub eta: Rgb,
    pub k: Rgb,
    pub specular_reflectance: Texture,
}

impl BsdfModel for Conductor {
    fn eval(&self, _: &BsdfCtx, _: Vec3, _: Vec3) -> Rgb {
        Rgb::BLACK
    }
    fn pdf(&self, _: &BsdfCtx, _: Vec3, _: Vec3) -> f32 {
        0.0
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, _: f32, _: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let f = fresnel_conductor(wi.z, self.eta, self.k) * self.specular_reflectance.eval(ctx.uv);
        Some(BsdfSample { wo: vec3(-wi.x, -wi.y, wi.z), weight: f, pdf: 1.0, delta: true })
    }
    fn has_smooth(&self) -> bool {
        false
    }
}

#[derive(Clone, Debug)]
pub struct RoughConductor {
    pub distribution: Microfacet,
    pub eta: Rgb,
    pub k: Rgb,
    pub specular_reflectance: Texture,
}

impl BsdfModel for RoughConductor {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::BLACK;
        }
        let m = (wi + wo).normalize();
        let d = self.distribution.d(m);
        if d == 0.0 {
            return Rgb::BLACK;
        }
        let g = self.distribution.g(wi, wo, m);
        let f = fresnel_conductor(wi.dot(m), self.eta, self.k);
        f * self.specular_reflectance.eval(ctx.uv) * (d * g / (4.0 * wi.z))
    }
    fn pdf(&self, _: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let m = (wi + wo).normalize();
        self.distribution.pdf(wi, m) / (4.0 * wo.dot(m).abs())
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, _: f32, u: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let (m, _) = self.distribution.sample(wi, u);
        weighted_sample(self, ctx, wi, wi.reflect(m))
    }
}
