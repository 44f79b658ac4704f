// Path tracing on the GPU: one thread per pixel, `samples` samples per dispatch, the same
// estimator as the CPU's `pt` (next-event estimation, power-heuristic MIS on emitter hits,
// Russian roulette from rr_depth, Mitsuba's max_depth counting segments) over the feature
// subset `flatten.rs` accepts. The BVH is binary, flattened depth-first with a miss link per
// node, traversed without a stack.

struct Params {
    cam_pos: vec4<f32>,
    cam_x: vec4<f32>,      // world images of the camera's local axes (to_world's columns)
    cam_y: vec4<f32>,
    cam_z: vec4<f32>,
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
    pad: u32,
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
    reflectance: vec3<f32>,
    flags: u32,            // 1: two-sided
}

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

const NONE: u32 = 0xffffffffu;
const PI: f32 = 3.14159265358979;
const INV_PI: f32 = 0.318309886183791;

var<private> rng: u32;

fn hash(v: u32) -> u32 {
    let s = v * 747796405u + 2891336453u;
    let w = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (w >> 22u) ^ w;
}

// Uniform in [0, 1), 24 bits, as the CPU's next_f32.
fn rnd() -> f32 {
    rng = rng * 747796405u + 2891336453u;
    let s = rng;
    let w = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return f32(((w >> 22u) ^ w) >> 8u) * (1.0 / 16777216.0);
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
    return normalize(n);
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

fn radiance(px: u32, py: u32, sample: u32) -> vec3<f32> {
    rng = hash(P.seed_lo ^ hash(P.seed_hi ^ hash((py * P.width + px) ^ hash(sample))));
    let pos = vec2<f32>(f32(px) + rnd(), f32(py) + rnd());
    let local = vec3<f32>((1.0 - 2.0 * pos.x / f32(P.width)) * P.tan_half.x,
                          (1.0 - 2.0 * pos.y / f32(P.height)) * P.tan_half.y, 1.0);
    let to_world = mat3x3<f32>(P.cam_x.xyz, P.cam_y.xyz, P.cam_z.xyz);
    var o = P.cam_pos.xyz + to_world * (local * P.near_clip);
    var d = normalize(to_world * local);
    var l = vec3<f32>(0.0);
    var beta = vec3<f32>(1.0);
    var prev_pdf = 0.0;          // 0: the camera (no MIS on what it sees)
    var depth = 0;
    loop {
        let h = intersect(o, d, 3.0e38, false);
        if (h.tri == NONE) {
            break;
        }
        depth = depth + 1;
        let tri = tris[h.tri];
        let p = o + d * h.t;
        let ng = normalize(cross(tri.v1 - tri.v0, tri.v2 - tri.v0));
        let ns = shading_normal(h.tri, tri, ng, h.b);
        // Emission and the BSDF's side follow the shading normal, the light's density
        // the geometric one, as on the CPU.
        let cos_o = -dot(ns, d);
        if (tri.emitter != NONE && cos_o > 0.0) {
            let e = emitters[tri.emitter];
            var w = 1.0;
            if (prev_pdf > 0.0) {
                w = power(prev_pdf, e.pick / e.area * h.t * h.t / abs(dot(ng, d)));
            }
            l = l + beta * e.radiance * w;
        }
        if (P.max_depth >= 0 && depth >= P.max_depth) {
            break;
        }
        let m = materials[tri.material];
        var n = ns;
        if (cos_o <= 0.0) {
            if ((m.flags & 1u) == 0u) {
                break;   // the back of a one-sided BSDF is black
            }
            n = -ns;
        }
        let f = m.reflectance * INV_PI;
        // Next-event estimation: a triangle by power, a point uniformly on it.
        if (P.emitters > 0u) {
            let e = emitters[pick_emitter(rnd())];
            let et = tris[e.tri];
            var u = vec2<f32>(rnd(), rnd());
            if (u.x + u.y > 1.0) {
                u = vec2<f32>(1.0 - u.x, 1.0 - u.y);
            }
            let q = et.v0 + (et.v1 - et.v0) * u.x + (et.v2 - et.v0) * u.y;
            let eg = normalize(cross(et.v1 - et.v0, et.v2 - et.v0));
            let es = shading_normal(e.tri, et, eg, u);
            let to = q - p;
            let dist2 = dot(to, to);
            let dist = sqrt(dist2);
            let wi = to / dist;
            let cos_l = abs(dot(eg, wi));
            let cos_s = dot(n, wi);
            if (dot(es, wi) < 0.0 && cos_l > 0.0 && cos_s > 0.0) {
                // Aimed at q from the offset origin itself (as the CPU's spawn_ray_to): the
                // offset would otherwise shift the ray beside q, into a small emitter's
                // own triangles at grazing angles.
                let po = spawn(p, ng, wi);
                let shadow_dist = distance(q, po);
                let shadow = intersect(po, (q - po) / shadow_dist, shadow_dist * (1.0 - 1e-4), true);
                if (shadow.tri == NONE) {
                    let pdf_light = e.pick / e.area * dist2 / cos_l;
                    let pdf_bsdf = cos_s * INV_PI;
                    l = l + beta * f * cos_s * e.radiance * (power(pdf_light, pdf_bsdf) / pdf_light);
                }
            }
        }
        // Continue along a cosine-distributed direction: f·cos/p = reflectance.
        let local_wo = cosine_hemisphere(vec2<f32>(rnd(), rnd()));
        if (local_wo.z <= 0.0) {
            break;
        }
        let wo = frame(n) * local_wo;
        beta = beta * m.reflectance;
        if (max(beta.x, max(beta.y, beta.z)) <= 0.0) {
            break;
        }
        prev_pdf = local_wo.z * INV_PI;
        o = spawn(p, ng, wo);
        d = wo;
        if (depth >= P.rr_depth) {
            let q = min(max(beta.x, max(beta.y, beta.z)), 0.95);
            if (rnd() >= q) {
                break;
            }
            beta = beta / q;
        }
        if (depth > 4096) {
            break;
        }
    }
    return l;
}

// By the bits: compilers may assume floats are never NaN.
fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let px = P.x0 + id.x;
    let py = P.y0 + id.y;
    if (px >= P.width || py >= P.height) {
        return;
    }
    let i = py * P.width + px;
    var sum = sums[i];
    var sq = squares[i];
    for (var s = 0u; s < P.samples; s = s + 1u) {
        let l = radiance(px, py, P.first_sample + s);
        // Non-finite samples are rejected and counted, as on the CPU.
        if (finite(l.x) && finite(l.y) && finite(l.z)) {
            sum = sum + vec4<f32>(l, 1.0);
            sq = sq + vec4<f32>(l * l, 0.0);
        } else {
            sq.w = sq.w + 1.0;
        }
    }
    sums[i] = sum;
    squares[i] = sq;
}
