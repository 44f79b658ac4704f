//! Mitsuba 0.6's energy-normalised modified Phong model (the seeds' glossy material).

use super::{glossy_diffuse_pdf, sample_glossy_diffuse, BsdfCtx, BsdfModel, BsdfSample};
use crate::color::Rgb;
use crate::math::{vec3, Frame, Vec2, Vec3, INV_2PI, INV_PI};
use crate::sampling::{power_cosine, power_cosine_pdf};
use crate::texture::Texture;

#[derive(Clone, Debug)]
pub struct Phong {
    pub diffuse: Texture,
    pub specular: Texture,
    pub exponent: f32,
    /// Probability of sampling the specular lobe.
    pub specular_weight: f32,
}

impl Phong {
    pub fn new(diffuse: Texture, specular: Texture, exponent: f32) -> Phong {
        let (d, s) = (diffuse.mean().mean(), specular.mean().mean());
        let specular_weight = if d + s > 0.0 { s / (d + s) } else { 0.5 };
        Phong { diffuse, specular, exponent, specular_weight }
    }
    fn lobe_pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        power_cosine_pdf(vec3(-wi.x, -wi.y, wi.z).dot(wo), self.exponent)
    }
}

impl BsdfModel for Phong {
    fn eval(&self, ctx: &BsdfCtx, wi: Vec3, wo: Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::BLACK;
        }
        let r = vec3(-wi.x, -wi.y, wi.z);
        let c = r.dot(wo);
        let mut f = self.diffuse.eval(ctx.uv) * INV_PI;
        if c > 0.0 {
            f += self.specular.eval(ctx.uv) * ((self.exponent + 2.0) * INV_2PI * c.powf(self.exponent));
        }
        f * wo.z
    }
    fn pdf(&self, _: &BsdfCtx, wi: Vec3, wo: Vec3) -> f32 {
        glossy_diffuse_pdf(self.specular_weight, || self.lobe_pdf(wi, wo), wi, wo)
    }
    fn sample(&self, ctx: &BsdfCtx, wi: Vec3, u: f32, u2: Vec2) -> Option<BsdfSample> {
        sample_glossy_diffuse(self, ctx, wi, (u, u2), self.specular_weight, |u2| {
            Frame::from_normal(vec3(-wi.x, -wi.y, wi.z)).to_world(power_cosine(u2, self.exponent))
        })
    }
}
