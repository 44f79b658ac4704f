//! Beckmann and GGX microfacet distributions with Smith shadowing, as Mitsuba defines them
//! (separable G = G1(wi)·G1(wo); Beckmann's G1 by its rational approximation).

use crate::math::{vec3, Vec2, Vec3, PI};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetType {
    Beckmann,
    Ggx,
}

#[derive(Clone, Copy, Debug)]
pub struct Microfacet {
    pub kind: MicrofacetType,
    pub alpha_u: f32,
    pub alpha_v: f32,
}

impl Microfacet {
    pub fn new(kind: MicrofacetType, alpha_u: f32, alpha_v: f32) -> Microfacet {
        // Below 1e-4 the lobes are numerically a delta; keep them finite.
        Microfacet { kind, alpha_u: alpha_u.max(1e-4), alpha_v: alpha_v.max(1e-4) }
    }

    /// Normal distribution D(m) for a microfacet normal in the upper hemisphere.
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let cos2 = m.z * m.z;
        let e = (m.x * m.x / (self.alpha_u * self.alpha_u) + m.y * m.y / (self.alpha_v * self.alpha_v)) / cos2;
        let norm = PI * self.alpha_u * self.alpha_v * cos2 * cos2;
        let r = match self.kind {
            MicrofacetType::Beckmann => (-e).exp() / norm,
            MicrofacetType::Ggx => 1.0 / (norm * (1.0 + e) * (1.0 + e)),
        };
        if r * cos2 < 1e-20 {
            0.0
        } else {
            r
        }
    }

    /// Smith's masking for direction `v` seen through microfacet `m`.
    pub fn g1(&self, v: Vec3, m: Vec3) -> f32 {
        if v.dot(m) * v.z <= 0.0 {
            return 0.0;
        }
        let xy = (self.alpha_u * v.x).powi(2) + (self.alpha_v * v.y).powi(2);
        if xy == 0.0 {
            return 1.0;
        }
        let tan2 = xy / (v.z * v.z);
        match self.kind {
            MicrofacetType::Beckmann => {
                let a = 1.0 / tan2.sqrt();
                if a >= 1.6 {
                    1.0
                } else {
                    (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
                }
            }
            MicrofacetType::Ggx => 2.0 / (1.0 + (1.0 + tan2).sqrt()),
        }
    }

    pub fn g(&self, wi: Vec3, wo: Vec3, m: Vec3) -> f32 {
        self.g1(wi, m) * self.g1(wo, m)
    }

    /// Samples a microfacet normal seen from `wi` (upper hemisphere); returns (m, pdf of m).
    /// GGX samples visible normals exactly (Heitz 2018); Beckmann samples D(m)cosθ.
    pub fn sample(&self, wi: Vec3, u: Vec2) -> (Vec3, f32) {
        match self.kind {
            MicrofacetType::Ggx => {
                let wi = if wi.z < 0.0 { -wi } else { wi };
                let vh = vec3(self.alpha_u * wi.x, self.alpha_v * wi.y, wi.z).normalize();
                let lensq = vh.x * vh.x + vh.y * vh.y;
                let t1 = if lensq > 0.0 { vec3(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { vec3(1.0, 0.0, 0.0) };
                let t2 = vh.cross(t1);
                let r = u.x.sqrt();
                let phi = 2.0 * PI * u.y;
                let p1 = r * phi.cos();
                let s = 0.5 * (1.0 + vh.z);
                let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
                let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
                let m = vec3(self.alpha_u * nh.x, self.alpha_v * nh.y, nh.z.max(1e-6)).normalize();
                (m, self.pdf(wi, m))
            }
            MicrofacetType::Beckmann => {
                let phi_t = (self.alpha_v / self.alpha_u * (2.0 * PI * u.y).tan()).atan();
                let phi = if u.y > 0.25 && u.y <= 0.75 {
                    phi_t + PI
                } else if u.y > 0.75 {
                    phi_t + 2.0 * PI
                } else {
                    phi_t
                };
                let (sp, cp) = phi.sin_cos();
                let inv_a2 = cp * cp / (self.alpha_u * self.alpha_u) + sp * sp / (self.alpha_v * self.alpha_v);
                let tan2 = -(1.0 - u.x).max(1e-30).ln() / inv_a2;
                let cos_t = 1.0 / (1.0 + tan2).sqrt();
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                let m = vec3(sin_t * cp, sin_t * sp, cos_t);
                (m, self.pdf(wi, m))
            }
        }
    }

    /// Density of `sample`'s microfacet normal.
    pub fn pdf(&self, wi: Vec3, m: Vec3) -> f32 {
        match self.kind {
            MicrofacetType::Ggx => {
                let wi = if wi.z < 0.0 { -wi } else { wi };
                if wi.z == 0.0 {
                    return 0.0;
                }
                self.g1(wi, m) * wi.dot(m).abs() * self.d(m) / wi.z
            }
            MicrofacetType::Beckmann => self.d(m) * m.z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// ∫ D(m) cosθm dm = 1 for both distributions (checked by uniform hemisphere MC).
    #[test]
    fn projected_area_is_normalised() {
        for kind in [MicrofacetType::Beckmann, MicrofacetType::Ggx] {
            let mf = Microfacet::new(kind, 0.3, 0.5);
            let mut rng = Rng::new(1, 2, 3);
            let n = 400_000;
            let mut sum = 0.0f64;
            let mut sum2 = 0.0f64;
            for _ in 0..n {
                let u = rng.next_2d();
                let z = u.x;
                let r = (1.0 - z * z).sqrt();
                let phi = 2.0 * PI * u.y;
                let m = vec3(r * phi.cos(), r * phi.sin(), z);
                let v = (mf.d(m) * m.z * 2.0 * PI) as f64;
                sum += v;
                sum2 += v * v;
            }
            let mean = sum / n as f64;
            let se = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
            assert!((mean - 1.0).abs() < 5.0 * se + 1e-3, "{kind:?}: {mean} ± {se}");
        }
    }
}
