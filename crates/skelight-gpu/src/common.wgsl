// What both passes share: the scene's buffers, random numbers, BVH traversal, sampling and
// the diffuse BSDF. The kernels (camera_pass.wgsl, light_pass.wgsl) and the BVH traversals
// (traverse_stackless.wgsl, traverse_ordered.wgsl, and a `traverse` that picks one: lib.rs,
// bvh.rs) are appended to this file into one module. Conventions follow the CPU: Mitsuba's max_depth counts
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
    eps_scale: f32,        // self-intersection offset per unit of (1 + coordinate magnitude)
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
    bidirectional: u32,    // 1: instant BPT (the camera pass weighs against light tracing too); 2: light tracing alone
    filter_radius: f32,    // the tent filter's radius (pixels); 0: the box filter
    environment: u32,      // the environment's emitter, or NONE
    environment_map: u32,  // its lat-long map's descriptor in `data`, or NONE: constant
    aperture_radius: f32,  // the thin lens's (0: a pinhole)
    focus_distance: f32,
    slices: u32,           // the dispatch's depth: thread z takes samples z, z + slices, …
    wave: u32,             // the wavefront camera pass: which group of `slices` samples this wave takes
    wf_tile_w: u32,        // the tile its path buffers are laid out by (paths = w · h · slices)
    wf_tile_h: u32,
    pad5: u32,
    pad6: u32,
    pad7: u32,
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
    reflectance: vec3<f32>,    // diffuse reflectance, or a conductor's/dielectric's specular
    flags: u32,                // TWO_SIDED, BECKMANN, NONLINEAR
    eta: vec3<f32>,            // conductor: η per channel; dielectric: interior/exterior in x;
                               // plastics: (η, internal diffuse reflectance, specular weight);
                               // Phong: specular weight in x
    kind: u32,                 // DIFFUSE … ROUGH_DIFFUSE
    k: vec3<f32>,              // conductor: absorption
    alpha: f32,                // microfacet roughness, Phong exponent, Oren–Nayar σ
    transmittance: vec3<f32>,  // dielectric: transmittance; plastic, Phong: specular reflectance
    table: u32,                // rough plastic: where its transmittance table starts in `data`
    texture: u32,              // the texture of `reflectance` (a descriptor in `data`), or NONE
    bump: u32,                 // a bump map's height texture, or NONE
    bump_scale: f32,
    mask: u32,                 // an opacity mask's texture (channel mean), or NONE: opaque
}

const DIFFUSE: u32 = 0u;
const CONDUCTOR: u32 = 1u;
const DIELECTRIC: u32 = 2u;
const ROUGH_CONDUCTOR: u32 = 3u;
const PLASTIC: u32 = 4u;
const ROUGH_PLASTIC: u32 = 5u;
const PHONG: u32 = 6u;
const ROUGH_DIFFUSE: u32 = 7u;
const COATED_DIFFUSE: u32 = 8u;
const ROUGH_DIELECTRIC: u32 = 9u;

const TWO_SIDED: u32 = 1u;
const BECKMANN: u32 = 2u;     // microfacets: Beckmann, else GGX
const NONLINEAR: u32 = 4u;    // plastics: Mitsuba's `nonlinear` internal scattering
const TEXTURED_SPECULAR: u32 = 8u;  // the texture replaces `transmittance` (phong's specular)

struct Emitter {
    radiance: vec3<f32>,   // area lights: radiance; point and spot lights: intensity
    tri: u32,              // area lights: the triangle; NONE for point and spot lights
    position: vec3<f32>,   // point and spot lights
    cdf: f32,              // inclusive cumulative pick probability
    axis: vec3<f32>,       // spot lights: the beam's axis
    pick: f32,             // probability of picking this emitter
    area: f32,             // area lights: the triangle's area
    cos_cutoff: f32,       // spot lights: where the beam ends (−1: a point light)
    cutoff: f32,           // spot lights: the falloff's angles, radians
    beam_width: f32,
}

@group(0) @binding(0) var<uniform> P: Params;
// The BVH's nodes in either layout or both (bvh.rs), as 16-byte words which the traversals
// decode: a stackless node is 3 words, from 0; an ordered one 4, from word PAIR_ROOT.
override PAIR_ROOT: u32 = 0u;
@group(0) @binding(1) var<storage, read> nodes: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> tris: array<Tri>;
@group(0) @binding(3) var<storage, read> materials: array<Material>;
@group(0) @binding(4) var<storage, read> emitters: array<Emitter>;
// One slice of width × height per thread z of a dispatch (P.slices), summed when read back.
@group(0) @binding(5) var<storage, read_write> sums: array<vec4<f32>>;      // rgb, samples
@group(0) @binding(6) var<storage, read_write> squares: array<vec4<f32>>;   // rgb², rejected
// Six per triangle: its vertices' normals with their u in w, their three v, dp/du, dp/dv.
@group(0) @binding(7) var<storage, read> attributes: array<vec4<f32>>;
// Binding 8, the light pass's splats (rgb per pixel), and `splat_add` are in splat_*.wgsl.
@group(0) @binding(9) var<storage, read_write> counters: array<atomic<u32>, 2>;  // rays: low, high
@group(0) @binding(10) var<storage, read> data: array<f32>;                  // textures, tables

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

// The watertight test of Woop, Benthin and Wald (2013), as the CPU's geometry/triangle.rs:
// the vertices are sheared into the ray's frame, where a shared edge's edge function is
// computed identically (up to sign) by both its triangles, so no ray slips between them
// (Möller–Trumbore's barycentrics leave cracks, which the thin gaps of interiors such as
// veach-door's door show). Per-ray constants: the axis permutation and the shear.
struct RayShear {
    kx: u32,
    ky: u32,
    kz: u32,
    s: vec3<f32>,          // (sx, sy, sz)
}

fn ray_shear(d: vec3<f32>) -> RayShear {
    let a = abs(d);
    var kz = 2u;
    if (a.x > a.y && a.x > a.z) {
        kz = 0u;
    } else if (a.y > a.z) {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    if (d[kz] < 0.0) {
        let t = kx;
        kx = ky;
        ky = t;
    }
    let sz = 1.0 / d[kz];
    return RayShear(kx, ky, kz, vec3<f32>(d[kx] * sz, d[ky] * sz, sz));
}

// Returns (t, b1, b2), t = -1 for a miss.
fn hit_tri(t: Tri, o: vec3<f32>, r: RayShear) -> vec3<f32> {
    let a = t.v0 - o;
    let b = t.v1 - o;
    let c = t.v2 - o;
    let ax = a[r.kx] - r.s.x * a[r.kz];
    let ay = a[r.ky] - r.s.y * a[r.kz];
    let bx = b[r.kx] - r.s.x * b[r.kz];
    let by = b[r.ky] - r.s.y * b[r.kz];
    let cx = c[r.kx] - r.s.x * c[r.kz];
    let cy = c[r.ky] - r.s.y * c[r.kz];
    let u = cx * by - cy * bx;
    let w = bx * ay - by * ax;
    let v = ax * cy - ay * cx;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) {
        return vec3<f32>(-1.0);
    }
    let det = u + v + w;
    if (det == 0.0) {
        return vec3<f32>(-1.0);
    }
    let t_scaled = r.s.z * (u * a[r.kz] + v * b[r.kz] + w * c[r.kz]);
    let inv = 1.0 / det;
    return vec3<f32>(t_scaled * inv, v * inv, w * inv);
}

// Whether an opacity mask lets the ray through at barycentrics `b` of triangle k: as the
// CPU's AlphaFilter, a mask of opacity a is hit with probability a, the threshold a hash of
// the ray (so that one ray always gets one answer).
// `Tri::flags`: vertex normals; an opacity mask on the material (as flatten.rs).
const SMOOTH: u32 = 1u;
const MASKED: u32 = 2u;

fn masked_out(tri: Tri, k: u32, b: vec2<f32>, o: vec3<f32>, d: vec3<f32>) -> bool {
    let mask = materials[tri.material].mask;
    let c = texture_eval(mask, uv_at(k, b));
    let a = (c.x + c.y + c.z) / 3.0;
    if (a >= 1.0) {
        return false;
    }
    if (a <= 0.0) {
        return true;
    }
    let ob = bitcast<vec3<u32>>(o);
    let db = bitcast<vec3<u32>>(d);
    let h = lowbias32(ob.x ^ lowbias32(ob.y ^ lowbias32(ob.z ^ lowbias32(db.x ^ lowbias32(db.y ^ lowbias32(db.z ^ lowbias32(k)))))));
    return f32(h >> 8u) * (1.0 / 16777216.0) >= a;
}

// A leaf's triangles `first`..`first + count` against the ray: `best` becomes the closest hit
// in (t_min, best.t). True when an any-hit search (`first_hit`) may stop: an unmasked
// triangle was hit. Masked triangles count as opaque here (so the mask's texture lookup stays
// out of the traversal's innermost loop) except that one never ends an any-hit search early:
// `intersect` tests the mask on the closest of them afterwards.
fn hit_leaf(first: u32, count: u32, o: vec3<f32>, shear: RayShear, t_min: f32, first_hit: bool, best: ptr<function, Hit>) -> bool {
    for (var k = first; k < first + count; k = k + 1u) {
        let tri = tris[k];
        let r = hit_tri(tri, o, shear);
        if (r.x > t_min && r.x < (*best).t) {
            *best = Hit(r.x, k, r.yz);
            if (first_hit && (tri.flags & MASKED) == 0u) {
                return true;
            }
        }
    }
    return false;
}

// At most this many masked surfaces let one ray through (a bound, so that no ray loops forever;
// the layer past it counts as hit).
const MASK_LAYERS: u32 = 64u;

// Closest hit before t_max (any hit when `first_hit`), opacity masks honoured: when the hit is
// a masked triangle that lets the ray through, the traversal goes on from just past it (the
// same ray, so the mask's hash and the watertight test see the same origin and direction).
fn intersect(o: vec3<f32>, d: vec3<f32>, t_max: f32, first_hit: bool) -> Hit {
    rays = rays + 1u;
    var t_min = 0.0;
    var hit = traverse(o, d, t_min, t_max, first_hit);
    for (var layer = 0u; layer < MASK_LAYERS; layer = layer + 1u) {
        if (hit.tri == NONE) {
            break;
        }
        let tri = tris[hit.tri];
        if ((tri.flags & MASKED) == 0u || !masked_out(tri, hit.tri, hit.b, o, d)) {
            break;
        }
        t_min = hit.t;
        hit = traverse(o, d, t_min, t_max, first_hit);
    }
    return hit;
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

fn uniform_sphere(u: vec2<f32>) -> vec3<f32> {
    let z = 1.0 - 2.0 * u.x;
    let r = sqrt(max(1.0 - z * z, 0.0));
    let phi = 2.0 * PI * u.y;
    return vec3<f32>(r * cos(phi), r * sin(phi), z);
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

// A ray's origin leaving the surface at `p` (geometric normal `ng`) towards `dir`: offset by
// (1 + max|p|) × eps_scale, the CPU's ray_epsilon (f32 intersection error grows with the
// coordinates' magnitude).
fn spawn(p: vec3<f32>, ng: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    let m = 1.0 + max(max(abs(p.x), abs(p.y)), abs(p.z));
    return p + ng * (select(-1.0, 1.0, dot(ng, dir) >= 0.0) * P.eps_scale * m);
}

// The shading normal at barycentrics `b` (the geometric one without vertex normals).
fn shading_normal(k: u32, t: Tri, ng: vec3<f32>, b: vec2<f32>) -> vec3<f32> {
    if ((t.flags & SMOOTH) == 0u) {
        return ng;
    }
    let a = 6u * k;
    let n = attributes[a].xyz * (1.0 - b.x - b.y) + attributes[a + 1u].xyz * b.x + attributes[a + 2u].xyz * b.y;
    // Opposite vertex normals can cancel: the geometric normal then, as the CPU.
    let len2 = dot(n, n);
    return select(ng, n * inverseSqrt(len2), len2 > 0.0);
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

// A point of the thin lens's aperture in camera space (z = 0), uniform over the disk by
// Shirley and Chiu's concentric map (as the CPU's sampling::concentric_disk); a pinhole's
// centre without drawing random numbers.
fn lens_sample() -> vec3<f32> {
    if (P.aperture_radius <= 0.0) {
        return vec3<f32>(0.0);
    }
    let a = 2.0 * rnd() - 1.0;
    let b = 2.0 * rnd() - 1.0;
    if (a == 0.0 && b == 0.0) {
        return vec3<f32>(0.0);
    }
    var r = b;
    var phi = 0.5 * PI - 0.25 * PI * (a / b);
    if (a * a > b * b) {
        r = a;
        phi = 0.25 * PI * (b / a);
    }
    return vec3<f32>(r * cos(phi), r * sin(phi), 0.0) * P.aperture_radius;
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
    var ns = shading_normal(h.tri, tri, ng, h.b);
    var m = materials[tri.material];
    if (m.texture != NONE || m.bump != NONE) {
        let uv = uv_at(h.tri, h.b);
        if (m.texture != NONE) {
            if ((m.flags & TEXTURED_SPECULAR) != 0u) {
                m.transmittance = texture_eval(m.texture, uv);
            } else {
                m.reflectance = texture_eval(m.texture, uv);
            }
        }
        if (m.bump != NONE) {
            ns = bumped(m, h.tri, ns, uv);
        }
    }
    let facing = dot(ns, d) < 0.0;
    let two_sided = (m.flags & TWO_SIDED) != 0u;
    return Surface(o + d * h.t, ng, ns, select(-ns, ns, facing), facing || two_sided, m, tri.emitter);
}

fn uv_at(k: u32, b: vec2<f32>) -> vec2<f32> {
    let a = 6u * k;
    let w = vec3<f32>(1.0 - b.x - b.y, b.x, b.y);
    return vec2<f32>(dot(vec3<f32>(attributes[a].w, attributes[a + 1u].w, attributes[a + 2u].w), w),
                     dot(attributes[a + 3u].xyz, w));
}

// A bump map's normal (the CPU's Perturbation::Bump): the height's uv gradient by central
// differences tilts the surface spanned by dp/du and dp/dv, kept on the side of `n`.
fn bumped(m: Material, k: u32, n: vec3<f32>, uv: vec2<f32>) -> vec3<f32> {
    let h = 1.0 / 1024.0;
    let height = vec3<f32>(1.0 / 3.0);
    let hu = (dot(texture_eval(m.bump, uv + vec2<f32>(h, 0.0)), height) - dot(texture_eval(m.bump, uv - vec2<f32>(h, 0.0)), height)) / (2.0 * h) * m.bump_scale;
    let hv = (dot(texture_eval(m.bump, uv + vec2<f32>(0.0, h)), height) - dot(texture_eval(m.bump, uv - vec2<f32>(0.0, h)), height)) / (2.0 * h) * m.bump_scale;
    let pu = attributes[6u * k + 4u].xyz + n * hu;
    let pv = attributes[6u * k + 5u].xyz + n * hv;
    let c = cross(pu, pv);
    let len2 = dot(c, c);
    if (!(len2 > 0.0) || !finite(len2)) {
        return n;
    }
    let b = c * inverseSqrt(len2);
    return select(b, -b, dot(b, n) < 0.0);
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

// `bench rays --device gpu`: one thread per ray, the traversal alone (no shading, no opacity
// masks, as the CPU's `bench rays`), so that rays per second compare with the CPU's
// accelerators and with published traversal kernels. Each ray is two vec4: origin and t_max,
// direction and 1 for any hit (else closest). An any-hit search gives the distance of the
// hit it stopped at, not the closest.
@group(0) @binding(11) var<storage, read> bench_rays: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read_write> bench_hits: array<f32>;   // per ray: the hit's distance, t_max if none

@compute @workgroup_size(64)
fn rays_main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>) {
    let i = id.x + id.y * n.x * 64u;
    if (2u * i + 1u >= arrayLength(&bench_rays)) {
        return;
    }
    let a = bench_rays[2u * i];
    let b = bench_rays[2u * i + 1u];
    let hit = traverse(a.xyz, b.xyz, 0.0, a.w, b.w > 0.5);
    bench_hits[i] = hit.t;
}
