// What both passes share: the scene's buffers, random numbers, BVH traversal, sampling and
// the diffuse BSDF. The kernels (camera_pass.wgsl, light_pass.wgsl) are appended to this file
// into one module. The BVH is binary, flattened depth-first with a miss link per node,
// traversed without a stack. Conventions follow the CPU: Mitsuba's max_depth counts
// segments, the side a BSDF or emitter is seen from follows the shading normal, area
// densities the geometric one.

struct Params {
    cam_pos: vec4<f32>,
    cam_x: vec4<f32>,      // world images of the camera's local axes (to_world's columns)
    cam_y: vec4<f32>,
    cam_z: vec4<f32>,
    inv_x: vec4<f32>,      // camera-local images of the world axes (world_to_local's columns)
    inv_y: vec4<f32>,
    inv_z: vec4<f32>,
    forward: vec4<f32>,    // unit viewing direction
    tan_half: vec2<f32>,
    near_clip: f32,
    eps_scale: f32,        // self-intersection offset per unit of coordinate magnitude
    width: u32,
    height: u32,
    seed_lo: u32,
    seed_hi: u32,
    first_sample: u32,
    samples: u32,
    max_depth: i32,        // segments; -1: unbounded
    rr_depth: i32,
    emitters: u32,
    x0: u32,               // the tile this dispatch covers
    y0: u32,
    bidirectional: u32,    // 1: instant BPT (the camera pass weighs against light tracing too)
}

struct Node {
    lo: vec3<f32>,
    first: u32,            // leaf: first triangle; inner: 0
    hi: vec3<f32>,
    count: u32,            // leaf: triangle count; inner: 0
    miss: u32,             // next node when this one is missed or done (0xffffffff: end)
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct Tri {
    v0: vec3<f32>,
    material: u32,
    v1: vec3<f32>,
    emitter: u32,          // index into emitters, or 0xffffffff
    v2: vec3<f32>,
    flags: u32,            // 1: shading normals in `normals`
}

struct Material {
    reflectance: vec3<f32>,    // diffuse, or specular reflectance
    flags: u32,                // 1: two-sided
    eta: vec3<f32>,            // conductor: η per channel; dielectric: interior/exterior in x
    kind: u32,                 // DIFFUSE, CONDUCTOR, DIELECTRIC
    k: vec3<f32>,              // conductor: absorption
    pad0: u32,
    transmittance: vec3<f32>,  // dielectric: specular transmittance
    pad1: u32,
}

const DIFFUSE: u32 = 0u;
const CONDUCTOR: u32 = 1u;
const DIELECTRIC: u32 = 2u;

struct Emitter {
    radiance: vec3<f32>,
    tri: u32,
    cdf: f32,              // inclusive cumulative pick probability
    pick: f32,             // probability of picking this triangle
    area: f32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> nodes: array<Node>;
@group(0) @binding(2) var<storage, read> tris: array<Tri>;
@group(0) @binding(3) var<storage, read> materials: array<Material>;
@group(0) @binding(4) var<storage, read> emitters: array<Emitter>;
@group(0) @binding(5) var<storage, read_write> sums: array<vec4<f32>>;      // rgb, samples
@group(0) @binding(6) var<storage, read_write> squares: array<vec4<f32>>;   // rgb², rejected
@group(0) @binding(7) var<storage, read> normals: array<vec4<f32>>;         // 3 per triangle
// Binding 8, the light pass's splats (rgb per pixel), and `splat_add` are in splat_*.wgsl.
@group(0) @binding(9) var<storage, read_write> counters: array<atomic<u32>, 2>;  // rays: low, high

// Rays this thread traced since it last counted them (for `bench render --device gpu`).
var<private> rays: u32;

// Adds this thread's rays to the 64-bit counter: the low word, and a carry into the high.
fn count_rays() {
    let old = atomicAdd(&counters[0], rays);
    if (old + rays < old) {
        atomicAdd(&counters[1], 1u);
    }
    rays = 0u;
}

const NONE: u32 = 0xffffffffu;
const PI: f32 = 3.14159265358979;
const INV_PI: f32 = 0.318309886183791;

// Random numbers: a counter hashed with a per-sample key of two words, one from the pixel and
// one from the sample and pass (counter-based, so no state correlates neighbouring pixels or
// samples). One 32-bit key would repeat whole streams: two (pixel, sample) pairs share a key
// with probability 2^-32, i.e. about 1 % of the paths of a 512² × 1024 spp render. `lowbias32`
// is Wellons's integer hash.
var<private> rng_pixel: u32;
var<private> rng_sample: u32;
var<private> rng_n: u32;

fn lowbias32(v: u32) -> u32 {
    var x = v;
    x = x ^ (x >> 16u);
    x = x * 0x7feb352du;
    x = x ^ (x >> 15u);
    x = x * 0x846ca68bu;
    x = x ^ (x >> 16u);
    return x;
}

// Uniform in [0, 1), 24 bits, as the CPU's next_f32.
fn rnd() -> f32 {
    rng_n = rng_n + 1u;
    return f32(lowbias32(rng_pixel ^ lowbias32(rng_sample ^ lowbias32(rng_n))) >> 8u) * (1.0 / 16777216.0);
}

struct Hit {
    t: f32,
    tri: u32,
    b: vec2<f32>,          // barycentrics of v1 and v2
}

fn hit_box(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, inv_d: vec3<f32>, t_max: f32) -> bool {
    let a = (lo - o) * inv_d;
    let b = (hi - o) * inv_d;
    let t0 = max(max(min(a.x, b.x), min(a.y, b.y)), max(min(a.z, b.z), 0.0));
    let t1 = min(min(max(a.x, b.x), max(a.y, b.y)), min(max(a.z, b.z), t_max));
    return t0 <= t1;
}

// Möller–Trumbore; returns (t, u, v), t = -1 for a miss.
fn hit_tri(t: Tri, o: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    let e1 = t.v1 - t.v0;
    let e2 = t.v2 - t.v0;
    let p = cross(d, e2);
    let det = dot(e1, p);
    if (abs(det) < 1e-20) {
        return vec3<f32>(-1.0);
    }
    let inv = 1.0 / det;
    let s = o - t.v0;
    let u = dot(s, p) * inv;
    if (u < 0.0 || u > 1.0) {
        return vec3<f32>(-1.0);
    }
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if (v < 0.0 || u + v > 1.0) {
        return vec3<f32>(-1.0);
    }
    return vec3<f32>(dot(e2, q) * inv, u, v);
}

// Closest hit before t_max (any hit when `first_hit`).
fn intersect(o: vec3<f32>, d: vec3<f32>, t_max: f32, first_hit: bool) -> Hit {
    rays = rays + 1u;
    var best = Hit(t_max, NONE, vec2<f32>(0.0));
    let inv_d = 1.0 / d;
    var i = 0u;
    loop {
        if (i == NONE) {
            break;
        }
        let n = nodes[i];
        if (!hit_box(n.lo, n.hi, o, inv_d, best.t)) {
            i = n.miss;
            continue;
        }
        if (n.count == 0u) {
            i = i + 1u;
            continue;
        }
        for (var k = n.first; k < n.first + n.count; k = k + 1u) {
            let r = hit_tri(tris[k], o, d);
            if (r.x > 0.0 && r.x < best.t) {
                best = Hit(r.x, k, r.yz);
                if (first_hit) {
                    return best;
                }
            }
        }
        i = n.miss;
    }
    return best;
}

fn frame(n: vec3<f32>) -> mat3x3<f32> {
    // Duff et al.'s branchless orthonormal basis.
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    let t = vec3<f32>(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    let bt = vec3<f32>(b, s + n.y * n.y * a, -n.y);
    return mat3x3<f32>(t, bt, n);
}

fn cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    return vec3<f32>(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u.x)));
}

fn power(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    let b2 = b * b;
    if (a2 + b2 > 0.0) {
        return a2 / (a2 + b2);
    }
    return 0.0;
}

// A ray's origin leaving the surface at `p` (geometric normal `ng`) towards `dir`.
fn spawn(p: vec3<f32>, ng: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    let m = max(max(abs(p.x), abs(p.y)), max(abs(p.z), 1.0));
    return p + ng * (select(-1.0, 1.0, dot(ng, dir) >= 0.0) * P.eps_scale * m);
}

// The shading normal at barycentrics `b` (the geometric one without vertex normals).
fn shading_normal(k: u32, t: Tri, ng: vec3<f32>, b: vec2<f32>) -> vec3<f32> {
    if ((t.flags & 1u) == 0u) {
        return ng;
    }
    let n = normals[3u * k].xyz * (1.0 - b.x - b.y) + normals[3u * k + 1u].xyz * b.x + normals[3u * k + 2u].xyz * b.y;
    // Opposite vertex normals can cancel: the geometric normal then, as the CPU.
    let len2 = dot(n, n);
    return select(ng, n * inverseSqrt(len2), len2 > 0.0);
}

// Picks an emitting triangle by its cumulative probabilities.
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

// By the bits: compilers may assume floats are never NaN.
fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}


fn sq(x: f32) -> f32 {
    return x * x;
}

// Densities through a specular lobe are recorded as 0 and count as 1 in MIS ratios: they
// appear in every strategy that can make the path, so they cancel (as the CPU's mis.rs).
fn remap(pdf: f32) -> f32 {
    return select(pdf, 1.0, pdf == 0.0);
}

// The generator of one sample of one pixel: `stream` 0 for the camera pass, 1 for the light
// pass, so that the two are independent and every (seed, pixel, sample) is reproducible.
fn seed_rng(px: u32, py: u32, sample: u32, stream: u32) {
    rng_pixel = lowbias32(P.seed_lo ^ lowbias32(py * P.width + px));
    rng_sample = lowbias32(P.seed_hi ^ lowbias32(sample * 2u + stream + 0x9e3779b9u));
    rng_n = 0u;
}

fn film_area() -> f32 {
    return 4.0 * P.tan_half.x * P.tan_half.y;
}

// A point on an emitting triangle, chosen by power then uniformly by area.
struct LightPoint {
    e: Emitter,
    q: vec3<f32>,
    ng: vec3<f32>,         // geometric normal
    ns: vec3<f32>,         // shading normal: the side that emits
}

fn sample_light_point() -> LightPoint {
    let e = emitters[pick_emitter(rnd())];
    let t = tris[e.tri];
    var u = vec2<f32>(rnd(), rnd());
    if (u.x + u.y > 1.0) {
        u = vec2<f32>(1.0 - u.x, 1.0 - u.y);
    }
    let q = t.v0 + (t.v1 - t.v0) * u.x + (t.v2 - t.v0) * u.y;
    let ng = normalize(cross(t.v1 - t.v0, t.v2 - t.v0));
    return LightPoint(e, q, ng, shading_normal(e.tri, t, ng, u));
}

// Where a ray hit: the point, its normals, and the normal on the side it arrived from (the
// shading normal, flipped for two-sided materials). `front` is false where a one-sided
// material was hit from behind (black).
struct Surface {
    p: vec3<f32>,
    ng: vec3<f32>,
    ns: vec3<f32>,
    n: vec3<f32>,
    front: bool,
    material: Material,
    emitter: u32,
}

fn surface_at(o: vec3<f32>, d: vec3<f32>, h: Hit) -> Surface {
    let tri = tris[h.tri];
    let ng = normalize(cross(tri.v1 - tri.v0, tri.v2 - tri.v0));
    let ns = shading_normal(h.tri, tri, ng, h.b);
    let m = materials[tri.material];
    let facing = dot(ns, d) < 0.0;
    let two_sided = (m.flags & 1u) != 0u;
    return Surface(o + d * h.t, ng, ns, select(-ns, ns, facing), facing || two_sided, m, tri.emitter);
}

// The BSDFs. `n` is the shading normal on the side the walk arrived from (s.n); only the
// diffuse BSDF has values and densities, the others are specular (sampled only).
// f·cos towards `wo`:
fn bsdf_fcos(m: Material, n: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {
    if (m.kind != DIFFUSE) {
        return vec3<f32>(0.0);
    }
    return m.reflectance * (INV_PI * max(dot(n, wo), 0.0));
}

// The density of sampling `wo` (per solid angle); 0 for specular BSDFs.
fn bsdf_pdf(m: Material, n: vec3<f32>, wo: vec3<f32>) -> f32 {
    if (m.kind != DIFFUSE) {
        return 0.0;
    }
    return max(dot(n, wo), 0.0) * INV_PI;
}

struct BsdfSample {
    wo: vec3<f32>,
    weight: vec3<f32>,     // f·cos / density
    pdf: f32,              // 0 for specular
    ok: bool,
}

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

// Samples the BSDF at `s` for a walk arriving from direction `wi` (pointing away from the
// surface). `radiance`: the camera's walk (a dielectric compresses radiance by 1/η² where
// it enters a denser medium; importance is not compressed), as the CPU's TransportMode.
fn bsdf_sample(s: Surface, wi: vec3<f32>, radiance: bool) -> BsdfSample {
    let m = s.material;
    if (m.kind == CONDUCTOR) {
        let c = dot(s.n, wi);
        let f = vec3<f32>(fresnel_conductor_channel(c, m.eta.x, m.k.x), fresnel_conductor_channel(c, m.eta.y, m.k.y),
                          fresnel_conductor_channel(c, m.eta.z, m.k.z));
        return BsdfSample(2.0 * c * s.n - wi, f * m.reflectance, 0.0, c > 0.0);
    }
    if (m.kind == DIELECTRIC) {
        // In the unflipped shading frame: cos_i < 0 means arriving from inside.
        let cos_i = dot(s.ns, wi);
        let r = fresnel_dielectric(cos_i, m.eta.x);
        if (rnd() < r) {
            return BsdfSample(2.0 * cos_i * s.ns - wi, m.reflectance, 0.0, true);
        }
        let inside = cos_i < 0.0;
        let eta = select(m.eta.x, 1.0 / m.eta.x, inside);
        let n = select(s.ns, -s.ns, inside);
        let c = abs(cos_i);
        let sin2_t = max(1.0 - c * c, 0.0) / (eta * eta);
        if (sin2_t >= 1.0) {
            return BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false);
        }
        let wo = -wi / eta + n * (c / eta - sqrt(1.0 - sin2_t));
        let scale = select(1.0, 1.0 / (eta * eta), radiance);
        return BsdfSample(wo, m.transmittance * scale, 0.0, true);
    }
    // Diffuse: by the cosine, f·cos/p = reflectance.
    let local = cosine_hemisphere(vec2<f32>(rnd(), rnd()));
    return BsdfSample(frame(s.n) * local, m.reflectance, local.z * INV_PI, local.z > 0.0);
}

// Light transport's adjoint BSDF with shading normals (Veach's correction, as the CPU's
// shading_normal_correction): |wi·ns||wo·ng| / (|wi·ng||wo·ns|).
fn adjoint_correction(s: Surface, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    let den = abs(dot(wi, s.ng)) * abs(dot(wo, s.ns));
    return select(0.0, abs(dot(wi, s.ns)) * abs(dot(wo, s.ng)) / den, den > 0.0);
}

// Russian roulette: the probability with which a walk of throughput `beta` went on, or 0
// where it stops (the CPU's rule: the largest component, at most 0.95).
fn survival(beta: vec3<f32>) -> f32 {
    let q = min(max(beta.x, max(beta.y, beta.z)), 0.95);
    return select(0.0, q, rnd() < q);
}
