//! Every BSDF's sampling, density and evaluation must agree: a χ² test of sampled
//! directions against `pdf`, weight = eval/pdf for every sample, and energy conservation.

use super::microfacet::{Microfacet, MicrofacetType};
use super::*;
use crate::color::rgb;
use crate::math::PI;
use crate::sampling::Rng;

fn white() -> Texture {
    Texture::constant(1.0)
}

fn test_bsdfs() -> Vec<(&'static str, Bsdf)> {
    let ggx = Microfacet::new(MicrofacetType::Ggx, 0.3, 0.3);
    let ggx_aniso = Microfacet::new(MicrofacetType::Ggx, 0.2, 0.5);
    let beck = Microfacet::new(MicrofacetType::Beckmann, 0.35, 0.35);
    let mirror_k = (Rgb::BLACK, Rgb::WHITE);
    vec![
        ("diffuse", Bsdf::Diffuse(Diffuse { reflectance: white() })),
        ("roughdiffuse", Bsdf::RoughDiffuse(RoughDiffuse { reflectance: white(), alpha: 0.5 })),
        (
            "roughconductor-ggx",
            Bsdf::RoughConductor(RoughConductor {
                distribution: ggx,
                eta: mirror_k.0,
                k: mirror_k.1,
                specular_reflectance: white(),
            }),
        ),
        (
            "roughconductor-ggx-aniso",
            Bsdf::RoughConductor(RoughConductor {
                distribution: ggx_aniso,
                eta: rgb(0.2, 0.9, 1.1),
                k: rgb(3.9, 2.4, 2.1),
                specular_reflectance: white(),
            }),
        ),
        (
            "roughconductor-beckmann",
            Bsdf::RoughConductor(RoughConductor {
                distribution: beck,
                eta: mirror_k.0,
                k: mirror_k.1,
                specular_reflectance: white(),
            }),
        ),
        (
            "roughdielectric-ggx",
            Bsdf::RoughDielectric(RoughDielectric {
                distribution: ggx,
                eta: 1.5,
                specular_reflectance: Rgb::WHITE,
                specular_transmittance: Rgb::WHITE,
            }),
        ),
        (
            "roughdielectric-beckmann",
            Bsdf::RoughDielectric(RoughDielectric {
                distribution: beck,
                eta: 1.33,
                specular_reflectance: Rgb::WHITE,
                specular_transmittance: Rgb::WHITE,
            }),
        ),
        ("plastic", Bsdf::Plastic(Plastic::new(Texture::constant(0.8), white(), 1.5, false))),
        ("roughplastic", Bsdf::RoughPlastic(RoughPlastic::new(ggx, Texture::constant(0.8), white(), 1.5, true))),
        ("phong", Bsdf::Phong(Phong::new(Texture::constant(0.5), Texture::constant(0.4), 20.0))),
        (
            "ward-balanced-aniso",
            Bsdf::Ward(Ward::new(WardVariant::Balanced, 0.1, 0.3, Texture::constant(0.5), Texture::constant(0.5))),
        ),
        ("ward", Bsdf::Ward(Ward::new(WardVariant::Ward, 0.2, 0.2, Texture::constant(0.3), Texture::constant(0.6)))),
        (
            "ward-duer",
            Bsdf::Ward(Ward::new(WardVariant::WardDuer, 0.25, 0.15, Texture::constant(0.5), Texture::constant(0.4))),
        ),
        (
            "coating",
            Bsdf::Coating(Coating::new(1.3, Rgb::WHITE, Rgb::BLACK, Bsdf::Diffuse(Diffuse { reflectance: white() }))),
        ),
        (
            "twosided",
            Bsdf::TwoSided(
                Box::new(Bsdf::Diffuse(Diffuse { reflectance: white() })),
                Box::new(Bsdf::Phong(Phong::new(Texture::constant(0.3), Texture::constant(0.6), 10.0))),
            ),
        ),
    ]
}

fn incident_directions(bsdf: &Bsdf) -> Vec<Vec3> {
    let mut v = vec![vec3(0.0, 0.0, 1.0), vec3(0.5, 0.2, 0.7).normalize(), vec3(0.9, -0.3, 0.2).normalize()];
    if bsdf.two_sided_transmission() || matches!(bsdf, Bsdf::TwoSided(..)) {
        v.push(vec3(-0.3, 0.4, -0.6).normalize());
    }
    v
}

const CTX: BsdfCtx = BsdfCtx { uv: Vec2 { x: 0.3, y: 0.6 }, mode: TransportMode::Radiance };

/// Upper quantile of χ²(k) by the Wilson–Hilferty approximation; z = 3.72 is p = 1e-4.
fn chi2_quantile(k: f64) -> f64 {
    let z = 3.72;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

#[test]
fn sampling_weights_and_densities_agree_with_eval() {
    for (name, bsdf) in test_bsdfs() {
        for wi in incident_directions(&bsdf) {
            let mut rng = Rng::new(17, 0, 0);
            for _ in 0..5000 {
                let Some(s) = bsdf.sample(&CTX, wi, rng.next_f32(), rng.next_2d()) else {
                    continue;
                };
                assert!(s.weight.is_finite() && s.pdf > 0.0, "{name}: {s:?}");
                if s.delta {
                    continue;
                }
                let pdf = bsdf.pdf(&CTX, wi, s.wo);
                assert!(
                    (pdf - s.pdf).abs() <= 1e-3 * pdf.max(s.pdf) + 1e-6,
                    "{name} wi={wi:?}: pdf {pdf} vs sampled {}",
                    s.pdf
                );
                let expect = bsdf.eval(&CTX, wi, s.wo) / s.pdf;
                let err = (expect - s.weight).map(f32::abs).max_component();
                assert!(
                    err <= 2e-3 * expect.max_component().max(1.0),
                    "{name} wi={wi:?}: weight {:?} vs eval/pdf {expect:?}",
                    s.weight
                );
            }
        }
    }
}

#[test]
fn sampled_directions_follow_the_pdf_chi_square() {
    const NZ: usize = 24;
    const NPHI: usize = 32;
    const SUB: usize = 16;
    let n_samples = 200_000usize;
    for (name, bsdf) in test_bsdfs() {
        for wi in incident_directions(&bsdf) {
            let mut rng = Rng::new(99, 1, 0);
            let mut observed = vec![0f64; NZ * NPHI];
            let bin = |w: Vec3| {
                let iz = ((w.z.clamp(-1.0, 1.0).acos() / PI * NZ as f32) as usize).min(NZ - 1);
                let phi = w.y.atan2(w.x) + PI;
                let ip = ((phi / (2.0 * PI) * NPHI as f32) as usize).min(NPHI - 1);
                iz * NPHI + ip
            };
            for _ in 0..n_samples {
                if let Some(s) = bsdf.sample(&CTX, wi, rng.next_f32(), rng.next_2d()) {
                    if !s.delta {
                        observed[bin(s.wo)] += 1.0;
                    }
                }
            }
            // Expected counts: integrate pdf·sinθ over each (θ, φ) cell; θ cells resolve the
            // narrow lobes at the poles (transmission at normal incidence).
            let mut expected = vec![0f64; NZ * NPHI];
            let cell = (std::f64::consts::PI / NZ as f64) * (2.0 * PI as f64 / NPHI as f64) / (SUB * SUB) as f64;
            for iz in 0..NZ {
                for ip in 0..NPHI {
                    let mut acc = 0.0;
                    for a in 0..SUB {
                        for b in 0..SUB {
                            let theta = std::f64::consts::PI * (iz as f64 + (a as f64 + 0.5) / SUB as f64) / NZ as f64;
                            let z = theta.cos();
                            let phi = -PI as f64
                                + 2.0 * PI as f64 * (ip as f64 + (b as f64 + 0.5) / SUB as f64) / NPHI as f64;
                            let r = (1.0 - z * z).max(0.0).sqrt();
                            let wo = vec3((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                            acc += bsdf.pdf(&CTX, wi, wo) as f64 * cell * theta.sin();
                        }
                    }
                    expected[iz * NPHI + ip] = acc * n_samples as f64;
                }
            }
            // Pool cells with small expectations so the χ² approximation holds.
            let (mut chi2, mut dof) = (0.0, 0usize);
            let (mut pool_o, mut pool_e) = (0.0, 0.0);
            for (o, e) in observed.iter().zip(&expected) {
                if *e < 5.0 {
                    pool_o += o;
                    pool_e += e;
                } else {
                    chi2 += (o - e).powi(2) / e;
                    dof += 1;
                }
            }
            if pool_e >= 5.0 {
                chi2 += (pool_o - pool_e).powi(2) / pool_e;
                dof += 1;
            } else {
                assert!(pool_o <= 10.0 + 3.0 * pool_e, "{name}: {pool_o} samples where pdf gives {pool_e}");
            }
            let limit = chi2_quantile((dof.max(2) - 1) as f64);
            assert!(chi2 < limit, "{name} wi={wi:?}: chi2 {chi2:.1} > {limit:.1} (dof {dof})");
        }
    }
}

/// Albedo E[weight] of lossless configurations stays ≤ 1 (within 5 standard errors) and a
/// white Lambertian surface returns exactly 1.
#[test]
fn white_furnace_energy_conservation() {
    let mut list = test_bsdfs();
    list.push(("mirror", Bsdf::Conductor(Conductor { eta: Rgb::BLACK, k: Rgb::WHITE, specular_reflectance: white() })));
    list.push((
        "glass",
        Bsdf::Dielectric(Dielectric { eta: 1.5, specular_reflectance: Rgb::WHITE, specular_transmittance: Rgb::WHITE }),
    ));
    list.push((
        "thin",
        Bsdf::ThinDielectric(ThinDielectric {
            eta: 1.5,
            specular_reflectance: Rgb::WHITE,
            specular_transmittance: Rgb::WHITE,
        }),
    ));
    let ctx = BsdfCtx { mode: TransportMode::Importance, ..CTX };
    for (name, bsdf) in list {
        for wi in incident_directions(&bsdf) {
            let mut rng = Rng::new(5, 5, 5);
            let n = 100_000;
            let (mut s1, mut s2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let w = bsdf
                    .sample(&ctx, wi, rng.next_f32(), rng.next_2d())
                    .map(|s| s.weight.max_component() as f64)
                    .unwrap_or(0.0);
                s1 += w;
                s2 += w * w;
            }
            let mean = s1 / n as f64;
            let se = ((s2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
            assert!(mean <= 1.0 + 5.0 * se + 1e-4, "{name} wi={wi:?}: albedo {mean} ± {se}");
            if name == "diffuse" || name == "mirror" || name == "glass" || name == "thin" {
                assert!((mean - 1.0).abs() <= 5.0 * se + 1e-4, "{name}: albedo {mean}");
            }
        }
    }
}
