//! Smooth, thin and rough dielectric interfaces. `eta` is interior over exterior index;
//! directions below the local surface are inside.

use super::fresnel::{fresnel_dielectric, refract};
use super::microfacet::Microfacet;
use super::{weighted_sample, BsdfCtx, BsdfModel, BsdfSample, TransportMode};
use crate::color::Rgb;
use crate::math::{vec3, Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Dielectric {
    pub eta: f32,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

/// Radiance is compressed by (η_i/η_t)² when it crosses into a denser medium; importance is not.
#[inline]
fn transmission_scale(mode: TransportMode, etap: f32) -> f32 {
    match mode {
        TransportMode::Radiance => 1.0 / (etap * etap),
        TransportMode::Importance => 1.0,
    }
}

impl BsdfModel for Dielectric {
    fn eval(&self, _: &BsdfCtx, _: Vec3, _: Vec3) -> Rgb {
        Rgb::BLACK
    }
    fn pdf(&self, _: &BsdfCtx, _: Vec3, _: Vec3) -> f32 {
        0.0
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, u: f32, _: Vec2) -> Option<BsdfSample> {
        let r = fresnel_dielectric(wi.z, self.eta);
        if u < r {
            let wo = vec3(-wi.x, -wi.y, wi.z);
            Some(BsdfSample { wo, weight: self.specular_reflectance, pdf: r, delta: true })
        } else {
            let (wo, etap) = refract(wi, vec3(0.0, 0.0, 1.0), self.eta)?;
            let weight = self.specular_transmittance * transmission_scale(ctx.mode, etap);
            Some(BsdfSample { wo, weight, pdf: 1.0 - r, delta: true })
        }
    }
    fn has_smooth(&self) -> bool {
        false
    }
}

/// A thin slab: internal reflections summed, transmission continues straight on.
#[derive(Clone, Debug)]
pub struct ThinDielectric {
    pub eta: f32,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

impl BsdfModel for ThinDielectric {
    fn eval(&self, _: &BsdfCtx, _: Vec3, _: Vec3) -> Rgb {
        Rgb::BLACK
    }
    fn pdf(&self, _: &BsdfCtx, _: Vec3, _: Vec3) -> f32 {
        0.0
    }
    fn sample(&self, _: &BsdfCtx, wi: Vec3, u: f32, _: Vec2) -> Option<BsdfSample> {
        let mut r = fresnel_dielectric(wi.z.abs(), self.eta);
        if r < 1.0 {
            r += (1.0 - r) * (1.0 - r) * r / (1.0 - r * r);
        }
        if u < r {
            Some(BsdfSample { wo: vec3(-wi.x, -wi.y, wi.z), weight: self.specular_reflectance, pdf: r, delta: true })
        } else {
            Some(BsdfSample { wo: -wi, weight: self.specular_transmittance, pdf: 1.0 - r, delta: true })
        }
    }
    fn has_smooth(&self) -> bool {
        false
    }
}

/// Rough interface (Walter et al. 2007) with visible-normal sampling.
#[derive(Clone, Debug)]
pub struct RoughDielectric {
    pub distribution: Microfacet,
    pub eta: f32,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

impl RoughDielectric {
    /// Generalised half vector for the pair, facing +z, and the relative index on wo's side.
    fn half_vector(&self, wi: Vec3, wo: Vec3) -> Option<(Vec3, f32, bool)> {
        if wi.z == 0.0 || wo.z == 0.0 {
            return None;
        }
        let reflect = wi.z * wo.z > 0.0;
        let etap = if reflect {
            1.0
        } else if wi.z > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let m = wo * etap + wi;
        if m.length_squared() == 0.0 {
            return None;
        }
        let m = m.normalize();
        let m = if m.z < 0.0 { -m } else { m };
        // Back-facing microfacets contribute nothing.
        if m.dot(wo) * wo.z < 0.0 || m.dot(wi) * wi.z < 0.0 {
            return None;
        }
        Some((m, etap, reflect))
    }
}

impl BsdfModel for RoughDielectric {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        let Some((m, etap, reflect)) = self.half_vector(wi, wo) else {
            return Rgb::BLACK;
        };
        let mf = &self.distribution;
        let f = fresnel_dielectric(wi.dot(m), self.eta);
        let d = mf.d(m);
        let g = mf.g(wi, wo, m);
        if reflect {
            self.specular_reflectance * (f * d * g / (4.0 * wi.z.abs()))
        } else {
            let denom = (wo.dot(m) + wi.dot(m) / etap).powi(2) * wi.z.abs();
            let ft = (1.0 - f) * d * g * (wo.dot(m) * wi.dot(m)).abs() / denom;
            self.specular_transmittance * (ft * transmission_scale(ctx.mode, etap))
        }
    }
    fn pdf(&self, _: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        let Some((m, etap, reflect)) = self.half_vector(wi, wo) else {
            return 0.0;
        };
        let r = fresnel_dielectric(wi.dot(m), self.eta);
        let pdf_m = self.distribution.pdf(wi, m);
        if reflect {
            pdf_m / (4.0 * wo.dot(m).abs()) * r
        } else {
            let denom = (wo.dot(m) + wi.dot(m) / etap).powi(2);
            pdf_m * wo.dot(m).abs() / denom * (1.0 - r)
        }
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, u: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z == 0.0 {
            return None;
        }
        let (m, pdf_m) = self.distribution.sample(wi, u2);
        if pdf_m <= 0.0 {
            return None;
        }
        let r = fresnel_dielectric(wi.dot(m), self.eta);
        let wo = if u < r {
            let wo = wi.reflect(m);
            if wo.z * wi.z <= 0.0 {
                return None;
            }
            wo
        } else {
            let (wo, _) = refract(wi, m, self.eta)?;
            if wo.z * wi.z >= 0.0 {
                return None;
            }
            wo
        };
        weighted_sample(self, ctx, wi, wo)
    }
    fn two_sided_transmission(&self) -> bool {
        true
    }
}
