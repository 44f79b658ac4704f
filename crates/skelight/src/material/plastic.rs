//! Plastic: a dielectric coating over a diffuse base, smooth or rough (Mitsuba's models,
//! including the internal-scattering term and its `nonlinear` option).

use super::fresnel::{fresnel_dielectric, fresnel_diffuse_reflectance, refract};
use super::microfacet::Microfacet;
use super::{weighted_sample, BsdfCtx, BsdfModel, BsdfSample};
use crate::color::Rgb;
use crate::math::{vec3, Vec2, Vec3, INV_PI};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, Rng};
use crate::texture::Texture;

/// The diffuse base seen through the interface, common to both plastics.
#[derive(Clone, Debug)]
struct DiffuseBase {
    diffuse: Texture,
    nonlinear: bool,
    /// Diffuse reflectance of the interface seen from inside.
    internal_reflectance: f32,
    inv_eta2: f32,
}

impl DiffuseBase {
    /// Diffuse term × cosθo for interface transmittances `t_i`, `t_o`.
    fn eval(&self, uv: Vec2, wo: Vec3, t_i: f32, t_o: f32) -> Rgb {
        let d = self.diffuse.eval(uv);
        let d = if self.nonlinear {
            d.map(|v| v / (1.0 - v * self.internal_reflectance))
        } else {
            d / (1.0 - self.internal_reflectance)
        };
        d * (INV_PI * self.inv_eta2 * wo.z * t_i * t_o)
    }
}

/// Fraction of samples sent to the specular lobe, before Fresnel: mean(spec)/(mean(spec)+mean(diffuse)).
fn specular_weight(diffuse: &Texture, specular: &Texture) -> f32 {
    let d = diffuse.mean().mean();
    let s = specular.mean().mean();
    if d + s > 0.0 {
        s / (d + s)
    } else {
        0.5
    }
}

/// Probability of choosing the specular lobe when the interface reflects `f` of the light.
fn specular_probability(f: f32, weight: f32) -> f32 {
    let ps = f * weight;
    let pd = (1.0 - f) * (1.0 - weight);
    if ps + pd > 0.0 {
        ps / (ps + pd)
    } else {
        0.0
    }
}

#[derive(Clone, Debug)]
pub struct Plastic {
    base: DiffuseBase,
    eta: f32,
    specular_reflectance: Texture,
    specular_weight: f32,
}

impl Plastic {
    pub fn new(diffuse: Texture, specular: Texture, eta: f32, nonlinear: bool) -> Plastic {
        Plastic {
            specular_weight: specular_weight(&diffuse, &specular),
            base: DiffuseBase {
                diffuse,
                nonlinear,
                internal_reflectance: fresnel_diffuse_reflectance(1.0 / eta),
                inv_eta2: 1.0 / (eta * eta),
            },
            eta,
            specular_reflectance: specular,
        }
    }
}

impl BsdfModel for Plastic {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::BLACK;
        }
        let t_i = 1.0 - fresnel_dielectric(wi.z, self.eta);
        let t_o = 1.0 - fresnel_dielectric(wo.z, self.eta);
        self.base.eval(ctx.uv, wo, t_i, t_o)
    }
    fn pdf(&self, _: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let ps = specular_probability(fresnel_dielectric(wi.z, self.eta), self.specular_weight);
        (1.0 - ps) * cosine_hemisphere_pdf(wo.z)
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, u: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let f = fresnel_dielectric(wi.z, self.eta);
        let ps = specular_probability(f, self.specular_weight);
        if u < ps {
            let weight = self.specular_reflectance.eval(ctx.uv) * (f / ps);
            return Some(BsdfSample { wo: vec3(-wi.x, -wi.y, wi.z), weight, pdf: ps, delta: true });
        }
        let wo = cosine_hemisphere(u2);
        let pdf = (1.0 - ps) * cosine_hemisphere_pdf(wo.z);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample { wo, weight: self.eval(ctx, wi, wo) / pdf, pdf, delta: false })
    }
}

/// A plastic's parameters as its model uses them, for renderers that re-implement it (the
/// GPU's flattening).
#[derive(Clone, Copy, Debug)]
pub struct PlasticParts<'a> {
    pub diffuse: &'a Texture,
    pub specular: &'a Texture,
    pub eta: f32,
    pub nonlinear: bool,
    /// Diffuse reflectance of the interface seen from inside.
    pub internal_reflectance: f32,
    /// Fraction of samples sent to the specular lobe before Fresnel.
    pub specular_weight: f32,
    /// The rough interface's microfacets (`None`: smooth).
    pub distribution: Option<Microfacet>,
    /// The rough interface's transmittance over cosθ in [0, 1], [`TABLE_SIZE`] entries (empty: smooth).
    pub external_transmittance: &'a [f32],
}

impl DiffuseBase {
    fn parts<'a>(
        &'a self,
        specular: &'a Texture,
        (eta, specular_weight): (f32, f32),
        distribution: Option<Microfacet>,
        external_transmittance: &'a [f32],
    ) -> PlasticParts<'a> {
        PlasticParts {
            diffuse: &self.diffuse,
            specular,
            eta,
            nonlinear: self.nonlinear,
            internal_reflectance: self.internal_reflectance,
            specular_weight,
            distribution,
            external_transmittance,
        }
    }
}

impl Plastic {
    pub fn parts(&self) -> PlasticParts<'_> {
        self.base.parts(&self.specular_reflectance, (self.eta, self.specular_weight), None, &[])
    }
}

impl RoughPlastic {
    pub fn parts(&self) -> PlasticParts<'_> {
        let spec = &self.specular_reflectance;
        self.base.parts(spec, (self.eta, self.specular_weight), Some(self.distribution), &self.external_transmittance)
    }
}

/// Entries of a rough plastic's transmittance table.
pub const TABLE_SIZE: usize = 64;

#[derive(Clone, Debug)]
pub struct RoughPlastic {
    base: DiffuseBase,
    distribution: Microfacet,
    eta: f32,
    specular_reflectance: Texture,
    specular_weight: f32,
    /// Energy transmitted through the rough interface, tabulated over cosθ in [0, 1].
    external_transmittance: Vec<f32>,
}

/// Energy a rough dielectric interface reflects (`transmit = false`) or transmits for
/// incidence cosine `mu`: E over visible normals of F·G1(wo) resp. (1−F)·G1(wt), so light
/// shadowed by the microsurface counts as lost, as in Mitsuba's tables. Stratified
/// sampling with a fixed seed keeps the tables deterministic.
fn rough_interface_albedo(mf: &Microfacet, eta: f32, mu: f32, transmit: bool) -> f32 {
    let mu = mu.clamp(1e-6, 1.0);
    let wi = vec3((1.0 - mu * mu).sqrt(), 0.0, mu);
    let n = 48;
    let mut rng = Rng::new(0x5EED, mu.to_bits() as u64, eta.to_bits() as u64);
    let mut sum = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let u = Vec2 { x: (i as f32 + rng.next_f32()) / n as f32, y: (j as f32 + rng.next_f32()) / n as f32 };
            let (m, _) = mf.sample(wi, u);
            let f = fresnel_dielectric(wi.dot(m), eta);
            let value = if transmit {
                match refract(wi, m, eta) {
                    Some((wt, _)) if wt.z < 0.0 => (1.0 - f) * mf.g1(wt, m),
                    _ => 0.0,
                }
            } else {
                let wo = wi.reflect(m);
                if wo.z > 0.0 {
                    f * mf.g1(wo, m)
                } else {
                    0.0
                }
            };
            sum += value as f64;
        }
    }
    (sum / (n * n) as f64).clamp(0.0, 1.0) as f32
}

impl RoughPlastic {
    pub fn new(
        distribution: Microfacet,
        diffuse: Texture,
        specular: Texture,
        eta: f32,
        nonlinear: bool,
    ) -> RoughPlastic {
        let grid = |i: usize| i as f32 / (TABLE_SIZE - 1) as f32;
        let external_transmittance =
            (0..TABLE_SIZE).map(|i| rough_interface_albedo(&distribution, eta, grid(i), true)).collect();
        // Diffuse reflectance of the interface seen from inside, 2∫R(μ)μdμ, taken as twice
        // the mean over the table's grid as Mitsuba does (its value, ~1.5 % below the exact
        // integral, is part of the model the references were rendered with).
        let internal_reflectance = 2.0
            * (0..TABLE_SIZE)
                .map(|i| rough_interface_albedo(&distribution, 1.0 / eta, grid(i), false) * grid(i))
                .sum::<f32>()
            / TABLE_SIZE as f32;
        RoughPlastic {
            specular_weight: specular_weight(&diffuse, &specular),
            base: DiffuseBase { diffuse, nonlinear, internal_reflectance, inv_eta2: 1.0 / (eta * eta) },
            distribution,
            eta,
            specular_reflectance: specular,
            external_transmittance,
        }
    }
    fn transmittance(&self, mu: f32) -> f32 {
        lerp_table(&self.external_transmittance, mu)
    }
}

fn lerp_table(t: &[f32], mu: f32) -> f32 {
    let x = mu.clamp(0.0, 1.0) * (t.len() - 1) as f32;
    let i = (x as usize).min(t.len() - 2);
    let f = x - i as f32;
    t[i] * (1.0 - f) + t[i + 1] * f
}

impl BsdfModel for RoughPlastic {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::BLACK;
        }
        let m = (wi + wo).normalize();
        let mf = &self.distribution;
        let spec = fresnel_dielectric(wi.dot(m), self.eta) * mf.d(m) * mf.g(wi, wo, m) / (4.0 * wi.z);
        let diffuse = self.base.eval(ctx.uv, wo, self.transmittance(wi.z), self.transmittance(wo.z));
        self.specular_reflectance.eval(ctx.uv) * spec + diffuse
    }
    fn pdf(&self, _: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let ps = specular_probability(1.0 - self.transmittance(wi.z), self.specular_weight);
        let m = (wi + wo).normalize();
        let spec = self.distribution.pdf(wi, m) / (4.0 * wo.dot(m).abs());
        ps * spec + (1.0 - ps) * cosine_hemisphere_pdf(wo.z)
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, u: f32, u2: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let ps = specular_probability(1.0 - self.transmittance(wi.z), self.specular_weight);
        let wo = if u < ps {
            let (m, _) = self.distribution.sample(wi, u2);
            wi.reflect(m)
        } else {
            cosine_hemisphere(u2)
        };
        weighted_sample(self, ctx, wi, wo)
    }
}
