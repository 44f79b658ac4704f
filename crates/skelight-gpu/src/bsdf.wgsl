// The BSDFs, as the CPU's material/ (Mitsuba's models). Directions are world vectors; `s.n`
// is the shading normal on the side the walk arrived from (flipped for two-sided materials,
// which mirrors the back BSDF as the CPU's TwoSided does), and the models work in the local
// frame around it (+z = s.n; the lobes are isotropic, so the tangent does not matter).
// `wi` points towards the walk's previous vertex, `wo` the other way; `bsdf_eval` is
// f(wi, wo)·|cos θo| over the non-delta components and `bsdf_pdf` the density with which
// `bsdf_sample` draws wo through them, so that reversed densities are bsdf_pdf(wo, wi).

// Whether any component is not a delta (only then are connections and light samples made).
fn has_smooth(m: Material) -> bool {
    return m.kind != CONDUCTOR && m.kind != DIELECTRIC;
}

fn local_of(n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let f = frame(n);
    return vec3<f32>(dot(f[0], v), dot(f[1], v), dot(f[2], v));
}

// ---- Microfacets (isotropic α; GGX or Beckmann; Smith's separable G), as microfacet.rs ----

fn mf_d(m: Material, h: vec3<f32>) -> f32 {
    if (h.z <= 0.0) {
        return 0.0;
    }
    let a2 = m.alpha * m.alpha;
    let cos2 = h.z * h.z;
    let e = (h.x * h.x + h.y * h.y) / (a2 * cos2);
    let norm = PI * a2 * cos2 * cos2;
    var r = 1.0 / (norm * (1.0 + e) * (1.0 + e));
    if ((m.flags & BECKMANN) != 0u) {
        r = exp(-e) / norm;
    }
    return select(r, 0.0, r * cos2 < 1e-20);
}

fn mf_g1(m: Material, v: vec3<f32>, h: vec3<f32>) -> f32 {
    if (dot(v, h) * v.z <= 0.0) {
        return 0.0;
    }
    let xy = m.alpha * m.alpha * (v.x * v.x + v.y * v.y);
    if (xy == 0.0) {
        return 1.0;
    }
    let tan2 = xy / (v.z * v.z);
    if ((m.flags & BECKMANN) != 0u) {
        let a = 1.0 / sqrt(tan2);
        if (a >= 1.6) {
            return 1.0;
        }
        return (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a);
    }
    return 2.0 / (1.0 + sqrt(1.0 + tan2));
}

// Density of mf_sample's normal `h` seen from `wi`.
fn mf_pdf(m: Material, wi_in: vec3<f32>, h: vec3<f32>) -> f32 {
    if ((m.flags & BECKMANN) != 0u) {
        return mf_d(m, h) * h.z;
    }
    let wi = select(wi_in, -wi_in, wi_in.z < 0.0);
    if (wi.z == 0.0) {
        return 0.0;
    }
    return mf_g1(m, wi, h) * abs(dot(wi, h)) * mf_d(m, h) / wi.z;
}

// A microfacet normal: GGX's visible normals (Heitz 2018), Beckmann's D(h)·cos θh.
fn mf_sample(m: Material, wi_in: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    if ((m.flags & BECKMANN) != 0u) {
        let phi = 2.0 * PI * u.y;
        let tan2 = -log(max(1.0 - u.x, 1e-30)) * m.alpha * m.alpha;
        let cos_t = 1.0 / sqrt(1.0 + tan2);
        let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
        return vec3<f32>(sin_t * cos(phi), sin_t * sin(phi), cos_t);
    }
    let wi = select(wi_in, -wi_in, wi_in.z < 0.0);
    let vh = normalize(vec3<f32>(m.alpha * wi.x, m.alpha * wi.y, wi.z));
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(-vh.y, vh.x, 0.0) * inverseSqrt(lensq), lensq > 0.0);
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    let p1 = r * cos(phi);
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * r * sin(phi);
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    return normalize(vec3<f32>(m.alpha * nh.x, m.alpha * nh.y, max(nh.z, 1e-6)));
}

// Density of reflecting `wi` into `wo` about a sampled microfacet normal.
fn mf_reflection_pdf(m: Material, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    let h = normalize(wi + wo);
    return mf_pdf(m, wi, h) / (4.0 * abs(dot(wo, h)));
}

fn reflect_about(v: vec3<f32>, h: vec3<f32>) -> vec3<f32> {
    return 2.0 * dot(v, h) * h - v;
}

// ---- Fresnel ----

fn fresnel_dielectric(cos_in: f32, eta_in: f32) -> f32 {
    let inside = cos_in < 0.0;
    let cos_i = abs(cos_in);
    let eta = select(eta_in, 1.0 / eta_in, inside);
    let sin2_t = max(1.0 - cos_i * cos_i, 0.0) / (eta * eta);
    if (sin2_t >= 1.0) {
        return 1.0;
    }
    let cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_parl * r_parl + r_perp * r_perp);
}

fn fresnel_conductor_channel(cos_i: f32, eta_r: f32, eta_i: f32) -> f32 {
    let c2 = cos_i * cos_i;
    let s2 = 1.0 - c2;
    let t1 = eta_r * eta_r - eta_i * eta_i - s2;
    let a2pb2 = sqrt(max(t1 * t1 + 4.0 * eta_i * eta_i * eta_r * eta_r, 0.0));
    let a = sqrt(max(0.5 * (a2pb2 + t1), 0.0));
    let term1 = a2pb2 + c2;
    let term2 = 2.0 * cos_i * a;
    let rs = (term1 - term2) / (term1 + term2);
    let term3 = a2pb2 * c2 + s2 * s2;
    let term4 = term2 * s2;
    let rp = rs * (term3 - term4) / (term3 + term4);
    return clamp(0.5 * (rs + rp), 0.0, 1.0);
}

fn fresnel_conductor(m: Material, cos_i: f32) -> vec3<f32> {
    return vec3<f32>(fresnel_conductor_channel(cos_i, m.eta.x, m.k.x), fresnel_conductor_channel(cos_i, m.eta.y, m.k.y),
                     fresnel_conductor_channel(cos_i, m.eta.z, m.k.z));
}

// ---- Plastics (plastic.rs): a dielectric interface over a diffuse base ----

// The diffuse base × cos θo seen through interface transmittances t_i, t_o.
fn plastic_base(m: Material, wo: vec3<f32>, t_i: f32, t_o: f32) -> vec3<f32> {
    var d = m.reflectance / (1.0 - m.eta.y);
    if ((m.flags & NONLINEAR) != 0u) {
        d = m.reflectance / (1.0 - m.reflectance * m.eta.y);
    }
    return d * (INV_PI / (m.eta.x * m.eta.x) * wo.z * t_i * t_o);
}

// Probability of the specular lobe where the interface reflects `f`.
fn specular_probability(f: f32, weight: f32) -> f32 {
    let ps = f * weight;
    let pd = (1.0 - f) * (1.0 - weight);
    return select(0.0, ps / (ps + pd), ps + pd > 0.0);
}

// A rough plastic's tabulated interface transmittance at cos θ = mu (64 entries).
fn rough_transmittance(m: Material, mu: f32) -> f32 {
    let x = clamp(mu, 0.0, 1.0) * 63.0;
    let i = min(u32(x), 62u);
    let f = x - f32(i);
    return data[m.table + i] * (1.0 - f) + data[m.table + i + 1u] * f;
}

// ---- Phong (phong.rs) ----

fn phong_lobe_pdf(m: Material, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    let c = dot(vec3<f32>(-wi.x, -wi.y, wi.z), wo);
    return select(0.0, (m.alpha + 1.0) * 0.5 * INV_PI * pow(c, m.alpha), c > 0.0);
}

// ---- A smooth dielectric coating over a diffuse base (coating.rs) ----
// η in eta.x, the specular sampling weight in eta.z, the coat's specular reflectance in
// `transmittance`, absorption × thickness in `k`.

// The direction inside the layer for an outside direction (same azimuth, upper side).
fn coat_in(m: Material, w: vec3<f32>) -> vec3<f32> {
    let inv = 1.0 / m.eta.x;
    let sin2 = max(1.0 - w.z * w.z, 0.0) * inv * inv;
    return vec3<f32>(inv * w.x, inv * w.y, sqrt(max(1.0 - sin2, 0.0)));
}

// The outside direction of a direction inside the layer; z < 0 where it is totally reflected.
fn coat_out(m: Material, w: vec3<f32>) -> vec3<f32> {
    let sin2 = max(1.0 - w.z * w.z, 0.0) * m.eta.x * m.eta.x;
    if (sin2 >= 1.0) {
        return vec3<f32>(0.0, 0.0, -1.0);
    }
    return vec3<f32>(m.eta.x * w.x, m.eta.x * w.y, sqrt(1.0 - sin2));
}

fn coat_absorption(m: Material, wi_in: vec3<f32>, wo_in: vec3<f32>) -> vec3<f32> {
    return exp(-m.k * (1.0 / abs(wi_in.z) + 1.0 / abs(wo_in.z)));
}

// The solid-angle Jacobian of refraction out of the layer, over η².
fn coat_jacobian(m: Material, wo: vec3<f32>, wo_in: vec3<f32>) -> f32 {
    return wo.z / (m.eta.x * m.eta.x * wo_in.z);
}

// ---- Rough dielectric (Walter et al. 2007), as dielectric.rs's RoughDielectric ----
// In the frame of the unflipped shading normal: wi.z < 0 means the walk arrives from inside.
// Both directions are mirrored to the outside then, with the relative index inverted: the
// model is symmetric under that exchange, as the CPU's generalised half vector is.

struct RoughPair {
    wi: vec3<f32>,
    wo: vec3<f32>,
    eta: f32,              // η across the interface from wi's side
    h: vec3<f32>,          // the generalised half vector, facing wi's side
    etap: f32,             // 1 for a reflection, else eta; 0: no microfacet joins them
}

fn rough_pair(m: Material, wi_in: vec3<f32>, wo_in: vec3<f32>) -> RoughPair {
    let inside = wi_in.z < 0.0;
    let wi = select(wi_in, -wi_in, inside);
    let wo = select(wo_in, -wo_in, inside);
    let eta = select(m.eta.x, 1.0 / m.eta.x, inside);
    var r = RoughPair(wi, wo, eta, vec3<f32>(0.0), 0.0);
    if (wi.z == 0.0 || wo.z == 0.0) {
        return r;
    }
    let etap = select(eta, 1.0, wo.z > 0.0);
    var h = wo * etap + wi;
    if (dot(h, h) == 0.0) {
        return r;
    }
    h = normalize(h);
    h = select(h, -h, h.z < 0.0);
    // Back-facing microfacets contribute nothing.
    if (dot(h, wo) * wo.z < 0.0 || dot(h, wi) < 0.0) {
        return r;
    }
    r.h = h;
    r.etap = etap;
    return r;
}

// f(wi, wo)·|cos θo|; transmitted radiance (not importance) compressed by 1/η'².
fn rough_dielectric_eval(m: Material, wi_in: vec3<f32>, wo_in: vec3<f32>, radiance: bool) -> vec3<f32> {
    let r = rough_pair(m, wi_in, wo_in);
    if (r.etap == 0.0) {
        return vec3<f32>(0.0);
    }
    let h = r.h;
    let f = fresnel_dielectric(dot(r.wi, h), r.eta);
    let dg = mf_d(m, h) * mf_g1(m, r.wi, h) * mf_g1(m, r.wo, h);
    if (r.wo.z > 0.0) {
        return m.reflectance * (f * dg / (4.0 * r.wi.z));
    }
    let denom = sq(dot(r.wo, h) + dot(r.wi, h) / r.etap) * r.wi.z;
    let ft = (1.0 - f) * dg * abs(dot(r.wo, h) * dot(r.wi, h)) / denom;
    return m.transmittance * (ft * select(1.0, 1.0 / (r.etap * r.etap), radiance));
}

// The density of rough_dielectric_sample's wo: the visible normal's, through the reflection
// or refraction Jacobian, times the Fresnel choice.
fn rough_dielectric_pdf(m: Material, wi_in: vec3<f32>, wo_in: vec3<f32>) -> f32 {
    let r = rough_pair(m, wi_in, wo_in);
    if (r.etap == 0.0) {
        return 0.0;
    }
    let h = r.h;
    let f = fresnel_dielectric(dot(r.wi, h), r.eta);
    let pdf_h = mf_pdf(m, r.wi, h);
    if (r.wo.z > 0.0) {
        return pdf_h / (4.0 * abs(dot(r.wo, h))) * f;
    }
    return pdf_h * abs(dot(r.wo, h)) / sq(dot(r.wo, h) + dot(r.wi, h) / r.etap) * (1.0 - f);
}

// A microfacet normal seen from wi, then reflection or refraction by its Fresnel term.
fn rough_dielectric_sample(s: Surface, wi_world: vec3<f32>, radiance: bool) -> BsdfSample {
    let m = s.material;
    let wi_in = local_of(s.ns, wi_world);
    if (wi_in.z == 0.0) {
        return no_sample();
    }
    let inside = wi_in.z < 0.0;
    let wi = select(wi_in, -wi_in, inside);
    let eta = select(m.eta.x, 1.0 / m.eta.x, inside);
    let u = rnd();
    let h = mf_sample(m, wi, vec2<f32>(rnd(), rnd()));
    let c = dot(wi, h);
    if (!(mf_pdf(m, wi, h) > 0.0) || c <= 0.0) {
        return no_sample();
    }
    var wo = reflect_about(wi, h);
    if (u >= fresnel_dielectric(c, eta)) {
        let sin2_t = max(1.0 - c * c, 0.0) / (eta * eta);
        if (sin2_t >= 1.0) {
            return no_sample();
        }
        wo = -wi / eta + h * (c / eta - sqrt(1.0 - sin2_t));
        if (wo.z >= 0.0) {
            return no_sample();
        }
    } else if (wo.z <= 0.0) {
        return no_sample();
    }
    let wo_in = select(wo, -wo, inside);
    let pdf = rough_dielectric_pdf(m, wi_in, wo_in);
    if (!(pdf > 0.0) || !finite(pdf)) {
        return no_sample();
    }
    return BsdfSample(frame(s.ns) * wo_in, rough_dielectric_eval(m, wi_in, wo_in, radiance) / pdf, pdf, true);
}

// ---- The BSDF interface, in the local frame ----

fn eval_local(m: Material, wi: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {
    if (wi.z <= 0.0 || wo.z <= 0.0) {
        return vec3<f32>(0.0);
    }
    switch m.kind {
        case DIFFUSE: {
            return m.reflectance * (INV_PI * wo.z);
        }
        case ROUGH_DIFFUSE: {
            // Oren–Nayar, the qualitative model.
            let s2 = m.alpha * m.alpha;
            let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
            let b = 0.45 * s2 / (s2 + 0.09);
            let sin_i = sqrt(max(1.0 - wi.z * wi.z, 0.0));
            let sin_o = sqrt(max(1.0 - wo.z * wo.z, 0.0));
            var cos_phi = 0.0;
            if (sin_i > 1e-4 && sin_o > 1e-4) {
                cos_phi = clamp((wi.x * wo.x + wi.y * wo.y) / (sin_i * sin_o), -1.0, 1.0);
            }
            var sin_alpha = sin_i;
            var tan_beta = sin_o / wo.z;
            if (wi.z > wo.z) {
                sin_alpha = sin_o;
                tan_beta = sin_i / wi.z;
            }
            return m.reflectance * (INV_PI * wo.z * (a + b * max(cos_phi, 0.0) * sin_alpha * tan_beta));
        }
        case ROUGH_CONDUCTOR: {
            let h = normalize(wi + wo);
            let d = mf_d(m, h);
            if (d == 0.0) {
                return vec3<f32>(0.0);
            }
            let g = mf_g1(m, wi, h) * mf_g1(m, wo, h);
            return fresnel_conductor(m, dot(wi, h)) * m.reflectance * (d * g / (4.0 * wi.z));
        }
        case PLASTIC: {
            return plastic_base(m, wo, 1.0 - fresnel_dielectric(wi.z, m.eta.x), 1.0 - fresnel_dielectric(wo.z, m.eta.x));
        }
        case ROUGH_PLASTIC: {
            let h = normalize(wi + wo);
            let spec = fresnel_dielectric(dot(wi, h), m.eta.x) * mf_d(m, h) * mf_g1(m, wi, h) * mf_g1(m, wo, h) / (4.0 * wi.z);
            return m.transmittance * spec
                + plastic_base(m, wo, rough_transmittance(m, wi.z), rough_transmittance(m, wo.z));
        }
        case COATED_DIFFUSE: {
            let wi_in = coat_in(m, wi);
            let wo_in = coat_in(m, wo);
            let t = (1.0 - fresnel_dielectric(wi.z, m.eta.x)) * (1.0 - fresnel_dielectric(wo.z, m.eta.x));
            return m.reflectance * (INV_PI * wo_in.z * t * coat_jacobian(m, wo, wo_in)) * coat_absorption(m, wi_in, wo_in);
        }
        case PHONG: {
            let c = dot(vec3<f32>(-wi.x, -wi.y, wi.z), wo);
            var f = m.reflectance * INV_PI;
            if (c > 0.0) {
                f = f + m.transmittance * ((m.alpha + 2.0) * 0.5 * INV_PI * pow(c, m.alpha));
            }
            return f * wo.z;
        }
        default: {
            return vec3<f32>(0.0);
        }
    }
}

fn pdf_local(m: Material, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    if (wi.z <= 0.0 || wo.z <= 0.0) {
        return 0.0;
    }
    let cosine = wo.z * INV_PI;
    switch m.kind {
        case DIFFUSE, ROUGH_DIFFUSE: {
            return cosine;
        }
        case ROUGH_CONDUCTOR: {
            return mf_reflection_pdf(m, wi, wo);
        }
        case PLASTIC: {
            return (1.0 - specular_probability(fresnel_dielectric(wi.z, m.eta.x), m.eta.z)) * cosine;
        }
        case ROUGH_PLASTIC: {
            let ps = specular_probability(1.0 - rough_transmittance(m, wi.z), m.eta.z);
            return ps * mf_reflection_pdf(m, wi, wo) + (1.0 - ps) * cosine;
        }
        case PHONG: {
            return m.eta.x * phong_lobe_pdf(m, wi, wo) + (1.0 - m.eta.x) * cosine;
        }
        case COATED_DIFFUSE: {
            let ps = specular_probability(fresnel_dielectric(wi.z, m.eta.x), m.eta.z);
            let wo_in = coat_in(m, wo);
            return (1.0 - ps) * wo_in.z * INV_PI * coat_jacobian(m, wo, wo_in);
        }
        default: {
            return 0.0;
        }
    }
}

// `radiance`: the camera's walk (as bsdf_sample's).
fn bsdf_eval(s: Surface, wi: vec3<f32>, wo: vec3<f32>, radiance: bool) -> vec3<f32> {
    if (!has_smooth(s.material)) {
        return vec3<f32>(0.0);
    }
    if (s.material.kind == ROUGH_DIELECTRIC) {
        return rough_dielectric_eval(s.material, local_of(s.ns, wi), local_of(s.ns, wo), radiance);
    }
    return eval_local(s.material, local_of(s.n, wi), local_of(s.n, wo));
}

fn bsdf_pdf(s: Surface, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    if (!has_smooth(s.material)) {
        return 0.0;
    }
    if (s.material.kind == ROUGH_DIELECTRIC) {
        return rough_dielectric_pdf(s.material, local_of(s.ns, wi), local_of(s.ns, wo));
    }
    return pdf_local(s.material, local_of(s.n, wi), local_of(s.n, wo));
}

struct BsdfSample {
    wo: vec3<f32>,
    weight: vec3<f32>,     // f·cos / density
    pdf: f32,              // 0 where a delta lobe was sampled
    ok: bool,
}

fn no_sample() -> BsdfSample {
    return BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false);
}

// Completes a sample whose local direction `wo` was drawn by any non-delta lobe: the
// density is the mixture's, the weight eval/pdf (the CPU's weighted_sample).
fn weighted_sample(s: Surface, wi: vec3<f32>, wo: vec3<f32>) -> BsdfSample {
    if (wo.z * wi.z <= 0.0) {
        return no_sample();
    }
    let pdf = pdf_local(s.material, wi, wo);
    if (!(pdf > 0.0) || !finite(pdf)) {
        return no_sample();
    }
    return BsdfSample(frame(s.n) * wo, eval_local(s.material, wi, wo) / pdf, pdf, true);
}

// Samples the BSDF at `s` for a walk arriving from `wi_world`. `radiance`: the camera's walk
// (a dielectric compresses radiance by 1/η² where it enters a denser medium; importance is
// not compressed), as the CPU's TransportMode.
fn bsdf_sample(s: Surface, wi_world: vec3<f32>, radiance: bool) -> BsdfSample {
    let m = s.material;
    if (m.kind == CONDUCTOR) {
        let c = dot(s.n, wi_world);
        return BsdfSample(2.0 * c * s.n - wi_world, fresnel_conductor(m, c) * m.reflectance, 0.0, c > 0.0);
    }
    if (m.kind == DIELECTRIC) {
        // In the unflipped shading frame: cos_i < 0 means arriving from inside.
        let cos_i = dot(s.ns, wi_world);
        let r = fresnel_dielectric(cos_i, m.eta.x);
        if (rnd() < r) {
            return BsdfSample(2.0 * cos_i * s.ns - wi_world, m.reflectance, 0.0, true);
        }
        let inside = cos_i < 0.0;
        let eta = select(m.eta.x, 1.0 / m.eta.x, inside);
        let n = select(s.ns, -s.ns, inside);
        let c = abs(cos_i);
        let sin2_t = max(1.0 - c * c, 0.0) / (eta * eta);
        if (sin2_t >= 1.0) {
            return no_sample();
        }
        let wo = -wi_world / eta + n * (c / eta - sqrt(1.0 - sin2_t));
        let scale = select(1.0, 1.0 / (eta * eta), radiance);
        return BsdfSample(wo, m.transmittance * scale, 0.0, true);
    }
    if (m.kind == ROUGH_DIELECTRIC) {
        return rough_dielectric_sample(s, wi_world, radiance);
    }
    let wi = local_of(s.n, wi_world);
    if (wi.z <= 0.0) {
        return no_sample();
    }
    let u = rnd();
    let u2 = vec2<f32>(rnd(), rnd());
    switch m.kind {
        case DIFFUSE: {
            // By the cosine, f·cos/p = reflectance.
            let wo = cosine_hemisphere(u2);
            return BsdfSample(frame(s.n) * wo, m.reflectance, wo.z * INV_PI, wo.z > 0.0);
        }
        case ROUGH_CONDUCTOR: {
            return weighted_sample(s, wi, reflect_about(wi, mf_sample(m, wi, u2)));
        }
        case PLASTIC: {
            let f = fresnel_dielectric(wi.z, m.eta.x);
            let ps = specular_probability(f, m.eta.z);
            if (u < ps) {
                let wo = vec3<f32>(-wi.x, -wi.y, wi.z);
                return BsdfSample(frame(s.n) * wo, m.transmittance * (f / ps), 0.0, true);
            }
            return weighted_sample(s, wi, cosine_hemisphere(u2));
        }
        case ROUGH_PLASTIC: {
            let ps = specular_probability(1.0 - rough_transmittance(m, wi.z), m.eta.z);
            if (u < ps) {
                return weighted_sample(s, wi, reflect_about(wi, mf_sample(m, wi, u2)));
            }
            return weighted_sample(s, wi, cosine_hemisphere(u2));
        }
        case COATED_DIFFUSE: {
            let r = fresnel_dielectric(wi.z, m.eta.x);
            let ps = specular_probability(r, m.eta.z);
            if (u < ps) {
                let wo = vec3<f32>(-wi.x, -wi.y, wi.z);
                return BsdfSample(frame(s.n) * wo, m.transmittance * (r / ps), 0.0, true);
            }
            // The base's cosine lobe inside the layer, refracted out.
            return weighted_sample(s, wi, coat_out(m, cosine_hemisphere(u2)));
        }
        case PHONG: {
            if (u < m.eta.x) {
                let r = vec3<f32>(-wi.x, -wi.y, wi.z);
                let cos_t = pow(u2.x, 1.0 / (m.alpha + 1.0));
                let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
                let phi = 2.0 * PI * u2.y;
                return weighted_sample(s, wi, frame(r) * vec3<f32>(sin_t * cos(phi), sin_t * sin(phi), cos_t));
            }
            return weighted_sample(s, wi, cosine_hemisphere(u2));
        }
        default: {
            // Oren–Nayar: by the cosine.
            return weighted_sample(s, wi, cosine_hemisphere(u2));
        }
    }
}
