//! Fresnel equations and the named indices of refraction Mitsuba scenes use.

use crate::color::{rgb, Rgb};

/// Unpolarised Fresnel reflectance of a dielectric interface. `cos_i` may be negative
/// (arriving from inside); `eta` is interior over exterior index.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_i < 0.0 { (-cos_i, 1.0 / eta) } else { (cos_i, eta) };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// Fresnel reflectance of a conductor with complex index `eta + i k` (per channel).
pub fn fresnel_conductor(cos_i: f32, eta: Rgb, k: Rgb) -> Rgb {
    let c = |eta_r: f32, eta_i: f32| {
        let c2 = cos_i * cos_i;
        let s2 = 1.0 - c2;
        let s4 = s2 * s2;
        let t1 = eta_r * eta_r - eta_i * eta_i - s2;
        let a2pb2 = (t1 * t1 + 4.0 * eta_i * eta_i * eta_r * eta_r).max(0.0).sqrt();
        let a = (0.5 * (a2pb2 + t1)).max(0.0).sqrt();
        let term1 = a2pb2 + c2;
        let term2 = 2.0 * cos_i * a;
        let rs = (term1 - term2) / (term1 + term2);
        let term3 = a2pb2 * c2 + s4;
        let term4 = term2 * s2;
        let rp = rs * (term3 - term4) / (term3 + term4);
        (0.5 * (rs + rp)).clamp(0.0, 1.0)
    };
    rgb(c(eta.r, k.r), c(eta.g, k.g), c(eta.b, k.b))
}

/// Refracts `wi` (pointing away from the surface) through the interface with normal `n`.
/// Returns the transmitted direction and the relative index crossed, or `None` on total
/// internal reflection.
pub fn refract(wi: crate::math::Vec3, n: crate::math::Vec3, eta: f32) -> Option<(crate::math::Vec3, f32)> {
    let mut cos_i = n.dot(wi);
    let (mut eta, mut n) = (eta, n);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wi / eta + n * (cos_i / eta - cos_t), eta))
}

/// Hemispherical average 2∫F(μ)μdμ of the dielectric Fresnel reflectance (for light
/// arriving from the side where the relative index is `eta`), by Gauss–Legendre-free
/// midpoint quadrature fine enough for four digits.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let n = 2048;
    let mut sum = 0.0f64;
    for i in 0..n {
        let mu = (i as f64 + 0.5) / n as f64;
        sum += fresnel_dielectric(mu as f32, eta) as f64 * mu;
    }
    (2.0 * sum / n as f64) as f32
}

/// Index of refraction by Mitsuba's material names (`int_ior="bk7"`).
pub fn named_ior(name: &str) -> Option<f32> {
    Some(match name.to_ascii_lowercase().as_str() {
        "vacuum" => 1.0,
        "helium" => 1.000036,
        "hydrogen" => 1.000132,
        "air" => 1.000277,
        "carbon dioxide" => 1.00045,
        "water" => 1.3330,
        "acetone" => 1.36,
        "ethanol" => 1.361,
        "carbon tetrachloride" => 1.461,
        "glycerol" => 1.4729,
        "benzene" => 1.501,
        "silicone oil" => 1.52045,
        "bromine" => 1.661,
        "water ice" => 1.31,
        "fused quartz" => 1.458,
        "pyrex" => 1.470,
        "acrylic glass" => 1.49,
        "polypropylene" => 1.49,
        "bk7" => 1.5046,
        "sodium chloride" => 1.544,
        "amber" => 1.55,
        "pet" => 1.5750,
        "diamond" => 2.419,
        _ => return None,
    })
}

/// Complex index (eta, k) of conductors by Mitsuba's preset names, reduced to linear RGB.
/// `none` is the ideal mirror.
pub fn named_conductor(name: &str) -> Option<(Rgb, Rgb)> {
    Some(match name {
        "none" => (Rgb::BLACK, Rgb::WHITE),
        "Ag" => (rgb(0.155, 0.117, 0.138), rgb(4.828, 3.122, 2.147)),
        "Al" => (rgb(1.657, 0.880, 0.521), rgb(9.224, 6.270, 4.837)),
        "Au" => (rgb(0.143, 0.374, 1.442), rgb(3.983, 2.385, 1.603)),
        "Cu" => (rgb(0.200, 0.924, 1.102), rgb(3.912, 2.452, 2.142)),
        "CuZn" => (rgb(0.444, 0.527, 1.094), rgb(3.695, 2.765, 1.829)),
        "Cr" => (rgb(4.368, 2.916, 1.654), rgb(5.209, 4.232, 3.755)),
        "Fe" => (rgb(2.912, 2.950, 2.589), rgb(3.089, 2.934, 2.767)),
        "Hg" => (rgb(2.397, 1.436, 0.907), rgb(6.380, 4.592, 3.735)),
        "Ni" => (rgb(2.365, 1.657, 1.424), rgb(4.463, 3.235, 2.610)),
        "Pt" => (rgb(2.375, 2.085, 1.842), rgb(4.265, 3.716, 3.137)),
        "Ti" => (rgb(2.741, 2.542, 2.267), rgb(3.814, 3.435, 3.039)),
        "W" => (rgb(4.372, 3.300, 2.996), rgb(3.507, 2.617, 2.253)),
        "Li" => (rgb(0.266, 0.197, 0.221), rgb(1.592, 2.129, 2.837)),
        "Na" => (rgb(0.060, 0.056, 0.058), rgb(3.170, 2.594, 2.062)),
        "K" => (rgb(0.063, 0.047, 0.040), rgb(2.184, 1.679, 1.412)),
        "Cs" => (rgb(2.140, 1.953, 1.719), rgb(0.000, 0.000, 0.000)),
        "Be" => (rgb(4.176, 3.178, 2.778), rgb(3.828, 3.183, 2.995)),
        "V" => (rgb(4.275, 3.508, 2.769), rgb(3.487, 2.884, 3.111)),
        "Ir" => (rgb(3.079, 2.071, 1.619), rgb(5.580, 4.057, 3.263)),
        "Rh" => (rgb(2.569, 1.908, 1.651), rgb(6.757, 4.950, 4.196)),
        "Ta" => (rgb(1.071, 1.187, 2.611), rgb(6.202, 4.957, 3.791)),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_limits() {
        // Normal incidence: ((n-1)/(n+1))^2.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing incidence reflects everything; total internal reflection from inside.
        assert!(fresnel_dielectric(1e-6, 1.5) > 0.999);
        assert_eq!(fresnel_dielectric(-0.3, 1.5), 1.0);
        // Known value for glass from outside (~0.0918 for 1.5 hemispherical average).
        let fdr = fresnel_diffuse_reflectance(1.5);
        assert!((fdr - 0.0918).abs() < 2e-3, "{fdr}");
    }

    #[test]
    fn conductor_reduces_to_dielectric_without_absorption() {
        for c in [0.1, 0.5, 0.9] {
            let f = fresnel_conductor(c, Rgb::splat(1.5), Rgb::BLACK);
            assert!((f.r - fresnel_dielectric(c, 1.5)).abs() < 1e-4);
        }
        let mirror = fresnel_conductor(0.5, Rgb::BLACK, Rgb::WHITE);
        assert!((mirror.g - 1.0).abs() < 1e-5, "{mirror:?}");
    }
}
