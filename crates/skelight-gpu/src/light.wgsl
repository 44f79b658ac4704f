// The lights: area lights (emitting triangles, one entry each), point and spot lights (a
// point light is a spot whose cone is the whole sphere), directional lights and one
// environment (constant or a lat-long map, environment.wgsl), picked by power. Conventions as
// the CPU's light/mod.rs: Mitsuba 3's spot falloff, emission sampled by the cosine (area) or
// uniformly in the cone (spot); distant lights (directional, environment) start the light
// pass's rays uniformly on a disk of the emission sphere's radius across their direction,
// behind the scene. Point-like and directional lights (both `delta`) cannot be hit or seen;
// the environment is hit by rays that leave the scene.

const DISTANT: u32 = 0xfffffffeu;
const ENVIRONMENT: u32 = 0xfffffffdu;

// Picks an emitter by its cumulative probabilities.
fn pick_emitter(u: f32) -> u32 {
    var lo = 0u;
    var hi = P.emitters - 1u;
    loop {
        if (lo >= hi) {
            break;
        }
        let mid = (lo + hi) / 2u;
        if (u < emitters[mid].cdf) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

// A point on a light: an emitting triangle's, uniform by area, or a point light's position.
struct LightPoint {
    e: Emitter,
    q: vec3<f32>,
    ng: vec3<f32>,         // geometric normal (zero for point-like lights)
    ns: vec3<f32>,         // shading normal: the side that emits
    delta: bool,           // a point, spot or directional light (a delta in position or direction)
    distant: bool,         // a directional light or the environment: q is on a disk outside
                           // the scene, e.axis the direction light travels
    pdf_dir: f32,          // the environment's density (solid angle) of e.axis; 1 for others
}

fn sample_light_point() -> LightPoint {
    let e = emitters[pick_emitter(rnd())];
    var u = vec2<f32>(rnd(), rnd());
    if (e.tri == NONE) {
        return LightPoint(e, e.position, vec3<f32>(0.0), vec3<f32>(0.0), true, false, 1.0);
    }
    if (e.tri == DISTANT || e.tri == ENVIRONMENT) {
        var d = e;
        var pdf_dir = 1.0;
        if (e.tri == ENVIRONMENT) {
            // The direction light arrives from, by the environment's sampling (black where it
            // has none); the disk behind the scene across it.
            let es = env_sample(u);
            d.axis = -es.w;
            d.radiance = select(vec3<f32>(0.0), es.radiance, es.pdf > 0.0);
            pdf_dir = es.pdf;
            d.position = e.position - d.axis * e.cutoff;
            u = vec2<f32>(rnd(), rnd());
        }
        // Uniform on the disk (radius in `cutoff`), in the plane across the direction.
        let r = d.cutoff * sqrt(u.x);
        let phi = 2.0 * PI * u.y;
        let q = d.position + frame(d.axis) * vec3<f32>(r * cos(phi), r * sin(phi), 0.0);
        return LightPoint(d, q, vec3<f32>(0.0), vec3<f32>(0.0), e.tri == DISTANT, true, pdf_dir);
    }
    let t = tris[e.tri];
    if (u.x + u.y > 1.0) {
        u = vec2<f32>(1.0 - u.x, 1.0 - u.y);
    }
    let q = t.v0 + (t.v1 - t.v0) * u.x + (t.v2 - t.v0) * u.y;
    let ng = normalize(cross(t.v1 - t.v0, t.v2 - t.v0));
    return LightPoint(e, q, ng, shading_normal(e.tri, t, ng, u), false, false, 1.0);
}

// Mitsuba 3's spot falloff: full inside the beam, linear in angle to zero at the cutoff.
fn spot_falloff(e: Emitter, cos_t: f32) -> f32 {
    if (e.cos_cutoff <= -1.0) {
        return 1.0;
    }
    if (cos_t <= e.cos_cutoff) {
        return 0.0;
    }
    if (cos_t >= cos(e.beam_width)) {
        return 1.0;
    }
    return clamp((e.cutoff - acos(clamp(cos_t, -1.0, 1.0))) / (e.cutoff - e.beam_width), 0.0, 1.0);
}

// What the light point sends along unit direction `w`: radiance, or intensity × falloff.
fn emitted(lp: LightPoint, w: vec3<f32>) -> vec3<f32> {
    if (lp.distant) {
        return lp.e.radiance;   // irradiance, along the light's one direction
    }
    if (lp.delta) {
        return lp.e.radiance * spot_falloff(lp.e, dot(lp.e.axis, w));
    }
    return select(vec3<f32>(0.0), lp.e.radiance, dot(lp.ns, w) > 0.0);
}

// The density (per solid angle) with which the light pass emits along `w`.
fn emission_pdf(lp: LightPoint, w: vec3<f32>) -> f32 {
    if (lp.delta) {
        return select(0.0, 0.5 * INV_PI / (1.0 - lp.e.cos_cutoff), dot(lp.e.axis, w) > lp.e.cos_cutoff);
    }
    return max(dot(lp.ns, w), 0.0) * INV_PI;
}

// A direction of emission and its density: by the cosine about the emitting side, or
// uniform in a spot's cone (the sphere for a point light).
fn sample_emission(lp: LightPoint) -> vec4<f32> {
    let u = vec2<f32>(rnd(), rnd());
    if (lp.distant) {
        // A delta in direction (1), or the environment's density.
        return vec4<f32>(lp.e.axis, lp.pdf_dir);
    }
    if (lp.delta) {
        let cos_t = 1.0 - u.x * (1.0 - lp.e.cos_cutoff);
        let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
        let phi = 2.0 * PI * u.y;
        let w = frame(lp.e.axis) * vec3<f32>(sin_t * cos(phi), sin_t * sin(phi), cos_t);
        return vec4<f32>(w, emission_pdf(lp, w));
    }
    let local = cosine_hemisphere(u);
    return vec4<f32>(frame(lp.ns) * local, local.z * INV_PI);
}

// The light point's density: per unit area on area lights and on a distant light's disk, the
// pick alone on point-like ones.
fn origin_density(lp: LightPoint) -> f32 {
    return select(lp.e.pick / lp.e.area, lp.e.pick, lp.delta && !lp.distant);
}

// The density of the light point next-event estimation picks: per unit area on area lights,
// the pick alone on point-like and directional ones, per solid angle for the environment.
// It is also L_0, the light side's density of the path's first vertex, in the MIS.
fn nee_density(lp: LightPoint) -> f32 {
    if (lp.distant && !lp.delta) {
        return lp.e.pick * lp.pdf_dir;
    }
    return select(lp.e.pick / lp.e.area, lp.e.pick, lp.delta);
}

// Where a connection from scene point `p` to the light point goes: the unit direction, the
// distance a shadow ray must cover, and the geometric factor |cos at the light| / distance²
// (a distant light: its direction reversed, unbounded, 1).
struct LightConnection {
    w: vec3<f32>,
    dist: f32,
    g: f32,
}

fn connect_to_light(lp: LightPoint, p: vec3<f32>) -> LightConnection {
    if (lp.distant) {
        return LightConnection(-lp.e.axis, 3.0e38, 1.0);
    }
    let to = lp.q - p;
    let dist2 = dot(to, to);
    let w = to * inverseSqrt(dist2);
    return LightConnection(w, sqrt(dist2), light_cos(lp, w) / dist2);
}

// The light pass's density (per unit area) of the point `p` (geometric normal `ng`) it
// reaches first from the light point: the emission's solid-angle density converted, or for a
// distant light the disk's density projected.
fn first_hit_density(lp: LightPoint, w: vec3<f32>, p: vec3<f32>, ng: vec3<f32>) -> f32 {
    if (lp.distant) {
        return abs(dot(ng, w)) / lp.e.area;
    }
    let to = p - lp.q;
    return emission_pdf(lp, w) * abs(dot(ng, w)) / dot(to, to);
}

// |cos| at the light point towards `w` (1 at point-like lights).
fn light_cos(lp: LightPoint, w: vec3<f32>) -> f32 {
    return select(abs(dot(lp.ng, w)), 1.0, lp.delta || lp.distant);
}
