//! The path-tracing walk (next-event estimation, MIS against BSDF sampling with the power
//! heuristic, Russian roulette), with a hook for guided path tracers: a [`DirectionGuide`]
//! may offer, at each vertex, a second distribution of directions that is mixed with BSDF
//! sampling (one-sample MIS with the balance heuristic, thesis eq. 168–169: the direction is
//! drawn from the mixture and weighted by the mixture's density). Light sampling and emitter
//! hits are then weighted against that mixture density, so the estimator stays unbiased
//! whatever the guide proposes, as long as its density is exact. `pt` is the walk with
//! [`Unguided`]; `skelpt` offers the skeleton's lobes (and `portalpt`, `ppg` after it theirs).
//! Path lengths follow Mitsuba: `max_depth` counts segments, so 2 means direct lighting only.

use super::mutation::{factor, Strategy};
use super::visibility::{light_visible, ShadowEnd};
use crate::color::Rgb;
use crate::geometry::Ray;
use crate::material::{Bsdf, BsdfCtx, BsdfModel, TransportMode};
use crate::math::Vec3;
use crate::sampling::{power_heuristic, power_heuristic_over_pdf, Rng};
use crate::scene::{Scene, SurfaceInteraction};

/// A second way of drawing directions, offered vertex by vertex.
pub trait DirectionGuide: Sync {
    type Vertex<'a>: GuidedVertex
    where
        Self: 'a;
    /// What the guide offers at `si` (whose BSDF is `bsdf`), or `None` to leave the
    /// vertex to BSDF sampling alone. Must depend on the vertex only: the densities of
    /// the directions sampled there and of light samples taken there use the same answer.
    fn at<'a>(&'a self, si: &SurfaceInteraction, bsdf: &Bsdf) -> Option<Self::Vertex<'a>>;
}

/// The guide's distribution at one vertex.
pub trait GuidedVertex {
    /// Which part of the guide this is (a skeleton node), for learning from paths.
    fn key(&self) -> u32 {
        0
    }
    /// The probability c of drawing from the guide rather than from the BSDF, in [0, 1): at
    /// 1, delta lobes and directions the guide cannot draw would never be taken (a bias);
    /// at 0 the vertex is path tracing's, but its steps are recorded (for guides that learn).
    fn selection(&self) -> f32;
    /// Solid-angle density of world direction `wo`.
    fn pdf(&self, wo: Vec3) -> f32;
    /// Draws a world direction.
    fn sample(&self, rng: &mut Rng) -> Vec3;
}

/// Whether a guide may draw at `si` with BSDF `bsdf`: not where the side it is seen from is
/// near-specular, has no smooth lobe, or has a delta lobe beside smooth ones (a coating:
/// drawn with probability 1 − c only, guiding would pay 1/(1 − c) on every specular path;
/// measured worse on veach-door).
#[inline]
pub fn guidable(si: &SurfaceInteraction, bsdf: &Bsdf) -> bool {
    let side = bsdf.facing(si.frame.to_local(si.wi));
    !(side.near_specular() || !side.has_smooth() || side.has_delta_lobe())
}

/// No guide: plain path tracing.
pub struct Unguided;

/// A type with no values: [`Unguided`] never offers a vertex.
pub enum Never {}

impl GuidedVertex for Never {
    fn selection(&self) -> f32 {
        match *self {}
    }
    fn pdf(&self, _: Vec3) -> f32 {
        match *self {}
    }
    fn sample(&self, _: &mut Rng) -> Vec3 {
        match *self {}
    }
}

impl DirectionGuide for Unguided {
    type Vertex<'a> = Never;
    #[inline]
    fn at(&self, _: &SurfaceInteraction, _: &Bsdf) -> Option<Never> {
        None
    }
}

/// The density of direction `wo` (world) under the vertex's mixture of guide and BSDF
/// sampling, given the BSDF's own density `bsdf_pdf` of it.
#[inline]
fn mixture_pdf<V: GuidedVertex>(guide: Option<&V>, bsdf_pdf: f32, wo: Vec3) -> f32 {
    match guide {
        Some(g) => {
            let c = g.selection();
            if c > 0.0 {
                (1.0 - c) * bsdf_pdf + c * g.pdf(wo)
            } else {
                bsdf_pdf
            }
        }
        None => bsdf_pdf,
    }
}

/// A direction drawn at a vertex: where, its weight f·|cos|/p, its density p (for a delta
/// lobe, the probability of having picked it) and whether it is a delta direction, with
/// f·|cos| and the BSDF's own density of it (for learning guides).
struct Drawn {
    wo: Vec3,
    weight: Rgb,
    pdf: f32,
    delta: bool,
    value: Rgb,
    bsdf_pdf: f32,
}

/// One non-delta direction taken at a guided vertex, with what is needed to tell, once the
/// path is finished, how much light came back along it (for guides that learn).
#[derive(Clone, Copy, Debug)]
pub struct GuidedStep {
    /// [`GuidedVertex::key`].
    pub key: u32,
    pub x: Vec3,
    pub normal: Vec3,
    /// Towards where the path came from (the vertex's `si.wi`).
    pub wi: Vec3,
    pub wo: Vec3,
    /// f·|cos| towards `wo`.
    pub value: Rgb,
    pub bsdf_pdf: f32,
    /// The mixture density it was drawn with.
    pub pdf: f32,
    /// The path's radiance before anything found beyond this vertex was added.
    pub radiance_before: Rgb,
    /// The path throughput up to and including this direction's weight.
    pub beta_after: Rgb,
}

impl GuidedStep {
    /// f·|cos|·L along `wo` (luminance), L being the radiance the rest of the path brought
    /// back along it, given the path's final radiance `total`.
    pub fn integrand(&self, total: Rgb) -> f32 {
        let l = total - self.radiance_before;
        let per = |c: f32, b: f32, v: f32| if b > 0.0 { c / b * v } else { 0.0 };
        let r = per(l.r, self.beta_after.r, self.value.r);
        let g = per(l.g, self.beta_after.g, self.value.g);
        let b = per(l.b, self.beta_after.b, self.value.b);
        crate::color::rgb(r, g, b).luminance()
    }
}

/// Draws the next direction at `si` from the mixture of the guide (probability c) and the
/// BSDF (1 − c): each non-delta direction is weighted by the mixture's density, a delta
/// one by its lobe's probability times 1 − c.
#[inline]
fn draw<V: GuidedVertex>(
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    ctx: &BsdfCtx,
    wi: Vec3,
    guide: Option<&V>,
    rng: &mut Rng,
) -> Option<Drawn> {
    let from_guide = guide.filter(|g| rng.next_f32() < g.selection());
    if let Some(g) = from_guide {
        let wo = g.sample(rng);
        let local = si.frame.to_local(wo);
        let f = bsdf.eval(ctx, wi, local);
        let bsdf_pdf = bsdf.pdf(ctx, wi, local);
        let pdf = mixture_pdf(guide, bsdf_pdf, wo);
        if f.is_black() || !(pdf > 0.0) {
            return None;
        }
        return Some(Drawn { wo, weight: f / pdf, pdf, delta: false, value: f, bsdf_pdf });
    }
    let u = rng.next_f32();
    let u2 = rng.next_2d();
    let bs = bsdf.sample(ctx, wi, u, u2)?;
    let wo = si.frame.to_world(bs.wo);
    let (value, bsdf_pdf) = (bs.weight * bs.pdf, bs.pdf);
    match guide {
        None => Some(Drawn { wo, weight: bs.weight, pdf: bs.pdf, delta: bs.delta, value, bsdf_pdf }),
        Some(g) if bs.delta => {
            let keep = 1.0 - g.selection();
            Some(Drawn { wo, weight: bs.weight / keep, pdf: bs.pdf * keep, delta: true, value, bsdf_pdf })
        }
        Some(_) => {
            let pdf = mixture_pdf(guide, bs.pdf, wo);
            Some(Drawn { wo, weight: bs.weight * (bs.pdf / pdf), pdf, delta: false, value, bsdf_pdf })
        }
    }
}

/// [`Strategy::Hit`]'s factor, times [`Strategy::GuidedHit`]'s where the direction that
/// found the light was drawn at a guided vertex.
#[inline(always)]
fn hit_factor(guided: bool) -> f32 {
    if guided {
        factor(Strategy::Hit) * factor(Strategy::GuidedHit)
    } else {
        factor(Strategy::Hit)
    }
}

/// Radiance arriving along `ray` by paths of at most `max_depth` segments, with directions
/// drawn from BSDF sampling mixed with `guide`'s distribution where it offers one. With
/// `steps`, every non-delta direction drawn at a guided vertex is recorded there.
pub fn trace<G: DirectionGuide>(
    scene: &Scene,
    max_depth: i32,
    mut ray: Ray,
    rng: &mut Rng,
    guide: &G,
    mut steps: Option<&mut Vec<GuidedStep>>,
) -> Rgb {
    let rr_depth = scene.settings.rr_depth as i32;
    let mut l = Rgb::BLACK;
    let mut beta = Rgb::WHITE;
    // State of the previous scattering event, for MIS on emitter hits.
    let mut prev_delta = true;
    let mut prev_guided = false;
    let mut prev_pdf = 0.0f32;
    let mut prev_p = ray.o;
    let mut depth = 0i32;
    loop {
        let Some(si) = scene.intersect(&ray) else {
            for &li in &scene.infinite_lights {
                let light = &scene.lights[li as usize];
                let le = light.eval_infinite(ray.d);
                if le.is_black() {
                    continue;
                }
                let w = if prev_delta {
                    1.0
                } else {
                    power_heuristic(prev_pdf, scene.light_distribution.pmf(li as usize) * light.pdf_infinite(ray.d))
                };
                l += beta * le * (w * hit_factor(prev_guided));
            }
            break;
        };
        depth += 1;
        let le = scene.emitted(&si);
        if !le.is_black() {
            let w = if prev_delta {
                1.0
            } else {
                let li = scene.mesh_light[si.mesh as usize].expect("emissive mesh has a light");
                let light = &scene.lights[li as usize];
                let pdf_light = scene.light_distribution.pmf(li as usize) * light.pdf_li_area(prev_p, si.p, si.ng);
                power_heuristic(prev_pdf, pdf_light)
            };
            l += beta * le * (w * hit_factor(prev_guided));
        }
        if max_depth >= 0 && depth >= max_depth {
            break;
        }
        let bsdf = &scene.materials[si.material as usize].bsdf;
        let ctx = BsdfCtx { uv: si.uv, mode: TransportMode::Radiance };
        let wi = si.frame.to_local(si.wi);
        let here = guide.at(&si, bsdf);

        // Next-event estimation.
        if bsdf.has_smooth() && !scene.lights.is_empty() {
            let (li, pmf, _) = scene.light_distribution.sample_discrete(rng.next_f32());
            let u = rng.next_2d();
            if let Some(ls) = scene.lights[li].sample_li(si.p, u) {
                if !ls.radiance.is_black() && ls.pdf > 0.0 {
                    let wo = si.frame.to_local(ls.wi);
                    let f = bsdf.eval(&ctx, wi, wo);
                    let end = ShadowEnd::of_light(ls.p, ls.wi, !ls.dist.is_finite());
                    if !f.is_black() && light_visible(scene, &si, end) {
                        let pdf = pmf * ls.pdf;
                        let scale = if ls.delta {
                            1.0 / pdf
                        } else {
                            power_heuristic_over_pdf(pdf, mixture_pdf(here.as_ref(), bsdf.pdf(&ctx, wi, wo), ls.wi))
                        };
                        l += beta * f * ls.radiance * (scale * factor(Strategy::Nee));
                    }
                }
            }
        }

        // Continue in a direction drawn from the BSDF (mixed with the guide's).
        let Some(next) = draw(&si, bsdf, &ctx, wi, here.as_ref(), rng) else {
            break;
        };
        beta *= next.weight;
        if beta.is_black() || !beta.is_finite() {
            break;
        }
        if let (Some(steps), Some(g), false) = (steps.as_deref_mut(), here.as_ref(), next.delta) {
            steps.push(GuidedStep {
                key: g.key(),
                x: si.p,
                normal: si.ng,
                wi: si.wi,
                wo: next.wo,
                value: next.value,
                bsdf_pdf: next.bsdf_pdf,
                pdf: next.pdf,
                radiance_before: l,
                beta_after: beta,
            });
        }
        prev_delta = next.delta;
        prev_guided = here.is_some();
        prev_pdf = next.pdf;
        prev_p = si.p;
        ray = si.spawn_ray(next.wo);
        if depth >= rr_depth {
            let q = beta.max_component().min(0.95);
            if rng.next_f32() >= q {
                break;
            }
            beta = beta / q;
        }
    }
    l
}

#[cfg(test)]
mod tests {
    //! The mixture of guide and BSDF sampling must estimate ∫ f·|cos|·g dω for any g
    //! whatever the guide proposes: checked with a guide that points a cos^s lobe at a
    //! fixed direction, on a diffuse BSDF (analytic answer) and on smooth plastic (a delta
    //! lobe beside a diffuse one: the unguided estimate is the reference).
    use super::*;
    use crate::material::{Diffuse, Plastic};
    use crate::math::{vec2, vec3, Frame};
    use crate::sampling::{power_cosine, power_cosine_pdf};
    use crate::texture::Texture;

    struct Lobe {
        axis: Vec3,
        strength: f32,
        c: f32,
    }
    impl GuidedVertex for Lobe {
        fn selection(&self) -> f32 {
            self.c
        }
        fn pdf(&self, wo: Vec3) -> f32 {
            power_cosine_pdf(self.axis.dot(wo), self.strength)
        }
        fn sample(&self, rng: &mut Rng) -> Vec3 {
            Frame::from_normal(self.axis).to_world(power_cosine(rng.next_2d(), self.strength))
        }
    }

    fn vertex() -> SurfaceInteraction {
        let n = vec3(0.0, 0.0, 1.0);
        SurfaceInteraction {
            p: Vec3::ZERO,
            t: 1.0,
            ng: n,
            frame: Frame::from_normal(n),
            uv: vec2(0.0, 0.0),
            wi: vec3(0.3, 0.1, 1.0).normalize(),
            mesh: 0,
            prim: 0,
            material: 0,
        }
    }

    /// Mean and standard error of weight·g(wo) over `n` draws.
    fn estimate(bsdf: &Bsdf, guide: Option<&Lobe>, g: impl Fn(Vec3) -> f32, n: u64) -> (f64, f64) {
        let si = vertex();
        let ctx = BsdfCtx { uv: si.uv, mode: TransportMode::Radiance };
        let wi = si.frame.to_local(si.wi);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for i in 0..n {
            let mut rng = Rng::new(7, 0, i);
            let v = draw(&si, bsdf, &ctx, wi, guide, &mut rng).map_or(0.0, |d| (d.weight.g * g(d.wo)) as f64);
            sum += v;
            sum2 += v * v;
        }
        let m = sum / n as f64;
        (m, ((sum2 / n as f64 - m * m) / n as f64).sqrt())
    }

    #[test]
    fn guided_draws_estimate_the_bsdf_integral() {
        let diffuse = Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(0.8) });
        let axis = vec3(0.6, 0.0, 0.8);
        // g: the cone of half-angle 30° around the z axis, where ∫ ρ/π·cos dω = ρ·sin²30°.
        let cone = |wo: Vec3| if wo.z > 30f32.to_radians().cos() { 1.0 } else { 0.0 };
        let exact = 0.8 * 0.25;
        for (strength, c) in [(8.0, 0.5), (64.0, 0.9), (0.0, 0.99)] {
            let guide = Lobe { axis, strength, c };
            let (m, se) = estimate(&diffuse, Some(&guide), cone, 400_000);
            assert!((m - exact).abs() < 4.5 * se, "s {strength}, c {c}: {m} ± {se}, exact {exact}");
        }
        let plastic = Bsdf::Plastic(Plastic::new(Texture::constant(0.5), Texture::constant(1.0), 1.5, false));
        let all = |_: Vec3| 1.0;
        let (reference, se_ref) = estimate(&plastic, None, all, 400_000);
        let guide = Lobe { axis, strength: 8.0, c: 0.5 };
        let (m, se) = estimate(&plastic, Some(&guide), all, 400_000);
        let z = (m - reference).abs() / (se * se + se_ref * se_ref).sqrt();
        assert!(z < 4.5, "plastic: guided {m} ± {se}, unguided {reference} ± {se_ref}");
    }
}
