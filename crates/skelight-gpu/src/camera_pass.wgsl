// The camera pass: one thread per pixel, `samples` camera paths per dispatch. It is the CPU's
// `pt` (next-event estimation at non-specular vertices, power-heuristic MIS between it and
// emitter hits, Russian roulette from rr_depth), and with P.bidirectional the path-tracing half of instant BPT
// (seed 002, §3): the same paths, weighted against light tracing as well.
//
// MIS (seed 002 §3.2, in the notation of the CPU's mis.rs): a path x_0 … x_k runs from a
// light (x_0) to the lens (x_k); L_i and C_i are the densities per unit area of x_i when
// sampled from the light's side and from the camera's. The camera walk visits
// y_1 = x_{k−1}, y_2, … and keeps one float, `prod` = Π (L/C)² over its vertices whose both
// densities are known (y_j's L needs y_{j+1}'s BSDF sampled from the light's side, known once
// the walk has left y_{j+1}). Strategies, with their density relative to an emitter hit:
// next-event estimation L_0/C_0 (x_1 not specular), light tracing Π_{i<k} L_i/C_i (x_{k−1}
// not specular); the light hitting a pinhole has density 0, and a thin lens's aperture is not
// a strategy here either (light paths pass through it; the weights omit it, still summing
// to 1 over the strategies used).

// What the environment sends along a camera walk that leaves the scene after y_m (m ≥ 0
// surface vertices) in direction `d` sampled with solid-angle density `pdf_dir` (0: through
// a delta lobe), weighted against next-event estimation (L_0/C_0 per solid angle) and light
// tracing (y_m's light-side density: the disk's, projected), with the walk's MIS state.
fn environment_hit(m: i32, pdf_dir: f32, d: vec3<f32>, bidir: bool, prod: f32, c_prev: f32, n_prev: vec3<f32>,
                   delta_prev: bool, delta_first: bool) -> vec3<f32> {
    let e = emitters[P.environment];
    let radiance = env_eval(d);
    if (m == 0) {
        return radiance;   // seen directly: no other strategy finds it
    }
    let nee = sq(e.pick * env_pdf(d) / remap(pdf_dir));
    var inv_w = 1.0;
    if (!delta_prev) {
        inv_w = inv_w + nee;
    }
    if (bidir && !delta_first) {
        let l_prev = abs(dot(n_prev, d)) / e.area;
        inv_w = inv_w + prod * sq(l_prev / remap(c_prev)) * nee;
    }
    return radiance / inv_w;
}

// A camera walk between two of its rays, with its one-float MIS state: what the megakernel
// keeps in registers and the wavefront kernels (wavefront.wgsl) in memory, 112 bytes.
struct CameraPath {
    o: vec3<f32>,          // the next ray
    pdf_dir: f32,          // its direction's solid-angle density (0: through a delta lobe)
    d: vec3<f32>,
    m: i32,                // the current vertex is y_m (m segments from the lens)
    beta: vec3<f32>,
    prod: f32,             // the MIS product over y_1 … y_{m−2}
    l: vec3<f32>,          // radiance so far
    c_prev: f32,           // y_{m−1}'s camera-side density
    prev_p: vec3<f32>,
    flags: u32,            // PATH_*
    n_prev: vec3<f32>,     // y_{m−1}'s geometric normal
    rng_n: u32,            // the wavefront's copy of the generator's counter
    pos: vec2<f32>,        // the film position
    pixel: u32,
    sample: u32,
}

const PATH_ALIVE: u32 = 1u;
const PATH_DELTA_PREV: u32 = 2u;    // y_{m−1} is specular
const PATH_DELTA_FIRST: u32 = 4u;   // y_1 is

// Next-event estimation's shadow ray and what it brings if nothing blocks it.
struct ShadowRay {
    o: vec3<f32>,
    dist: f32,
    dir: vec3<f32>,
    on: u32,               // 0: no shadow ray
    c: vec3<f32>,
    path: u32,             // the wavefront's path index
}

// The camera ray through film position `pos` (pixels); the generator seeded.
fn camera_start(pos: vec2<f32>) -> CameraPath {
    var p: CameraPath;
    p.pos = pos;
    p.flags = select(PATH_ALIVE, 0u, P.max_depth == 0);   // no segment at all: black, as the CPU
    // The direction through the film point from the lens centre, per unit depth; a thin
    // lens's ray leaves a lens point towards where that one crosses the plane of focus (the
    // CPU's sample_ray). The lens point is the path's camera vertex; the ray starts at the
    // near plane.
    var dl = vec3<f32>((1.0 - 2.0 * pos.x / f32(P.width)) * P.tan_half.x,
                       (1.0 - 2.0 * pos.y / f32(P.height)) * P.tan_half.y, 1.0);
    let lens = lens_sample();
    if (P.aperture_radius > 0.0) {
        dl = dl * P.focus_distance - lens;
    }
    let to_world = mat3x3<f32>(P.cam_x.xyz, P.cam_y.xyz, P.cam_z.xyz);
    p.o = P.cam_pos.xyz + to_world * (lens + dl * (P.near_clip / dl.z));
    p.d = normalize(to_world * dl);
    // Per solid angle at the lens point, pinhole or thin lens alike: 1 / (A cos³).
    let cos_cam = dot(p.d, P.forward.xyz);
    p.pdf_dir = 1.0 / (film_area() * cos_cam * cos_cam * cos_cam);
    p.prev_p = P.cam_pos.xyz + to_world * lens;
    p.beta = vec3<f32>(1.0);
    p.prod = 1.0;
    return p;
}

// The walk's step at the hit `h` of its ray (NONE: it left the scene): emission found there,
// next-event estimation's shadow ray, and the next ray by BSDF sampling and Russian roulette,
// or the walk's end (PATH_ALIVE cleared).
fn camera_hit(p: ptr<function, CameraPath>, h: Hit) -> ShadowRay {
    var sr: ShadowRay;
    let bidir = P.bidirectional != 0u;
    let d = (*p).d;
    let m_prev = (*p).m;
    let delta_prev = ((*p).flags & PATH_DELTA_PREV) != 0u;
    let delta_first = ((*p).flags & PATH_DELTA_FIRST) != 0u;
    (*p).flags = (*p).flags & ~PATH_ALIVE;   // set again below if the walk goes on
    if (h.tri == NONE) {
        // The ray leaves the scene: the environment, x_0, ends a path of k = m + 1
        // segments (the loop traced it only if k ≤ max_depth).
        if (P.environment != NONE) {
            (*p).l = (*p).l + (*p).beta * environment_hit(m_prev, (*p).pdf_dir, d, bidir, (*p).prod, (*p).c_prev,
                                                      (*p).n_prev, delta_prev, delta_first);
        }
        return sr;
    }
    // Light tracing alone (the CPU's lt) takes from the camera only the environment seen
    // directly, which light paths cannot reach.
    if (P.bidirectional == 2u) {
        return sr;
    }
    let m = m_prev + 1;
    (*p).m = m;
    let s = surface_at((*p).o, d, h);
    let dist2 = dot(s.p - (*p).prev_p, s.p - (*p).prev_p);
    let cos_g = abs(dot(s.ng, d));
    let c_here = (*p).pdf_dir * cos_g / dist2;
    // y_{m−1}'s |cos| on the segment to y_m: its densities from this side are per unit
    // area there.
    let cos_prev = abs(dot((*p).n_prev, d));
    let prod = (*p).prod;
    let c_prev = (*p).c_prev;
    let beta = (*p).beta;
    // Emitter hit: y_m = x_0, the path has k = m segments.
    let cos_e = -dot(s.ns, d);
    if (s.emitter != NONE && cos_e > 0.0) {
        let e = emitters[s.emitter];
        let l0 = e.pick / e.area;
        var inv_w = 1.0;
        if (m == 1) {
            // Seen directly: only light tracing's light point joined to the lens competes.
            if (bidir) {
                inv_w = inv_w + sq(l0 / c_here);
            }
        } else {
            let nee = sq(l0 / remap(c_here));
            if (!delta_prev) {
                inv_w = inv_w + nee;
            }
            if (bidir && !delta_first) {
                // y_{m−1}'s light-side density: the emission's (cosine) towards it.
                let l_prev = cos_e * INV_PI * cos_prev / dist2;
                inv_w = inv_w + prod * sq(l_prev / remap(c_prev)) * nee;
            }
        }
        (*p).l = (*p).l + beta * e.radiance / inv_w;
    }
    if ((P.max_depth >= 0 && m >= P.max_depth) || !s.front) {
        return sr;
    }
    let wi = -d;
    // Next-event estimation: y_m = x_1 joined to a light point x_0 (k = m + 1).
    if (P.emitters > 0u && has_smooth(s.material)) {
        let lp = sample_light_point();
        let c = connect_to_light(lp, s.p);
        let wl = c.w;
        let le = emitted(lp, -wl);
        let fcos = bsdf_eval(s, wi, wl, true);
        if (max(le.x, max(le.y, le.z)) > 0.0 && c.g > 0.0 && max(fcos.x, max(fcos.y, fcos.z)) > 0.0) {
            // Aimed at q from the offset origin itself (as the CPU's spawn_ray_to): the
            // offset would otherwise shift the ray beside q, into a small emitter's
            // own triangles at grazing angles. A directional light's ray is unbounded.
            let po = spawn(s.p, s.ng, wl);
            var shadow_dir = wl;
            var shadow_dist = c.dist;
            if (!lp.distant) {
                shadow_dist = distance(lp.q, po);
                shadow_dir = (lp.q - po) / shadow_dist;
            }
            let l0 = nee_density(lp);
            var inv_w = 1.0;
            // The camera's walk hitting the light (area lights only).
            if (!lp.delta) {
                inv_w = inv_w + sq(bsdf_pdf(s, wi, wl) * c.g / l0);
            }
            if (bidir && !delta_first) {
                // Light tracing: L/C of y_m (the light pass's first hit) and y_{m−1}
                // (y_m's BSDF sampled from the light point's side).
                var r = prod * sq(first_hit_density(lp, -wl, s.p, s.ng) / remap(c_here));
                if (m >= 2) {
                    r = r * sq((bsdf_pdf(s, wl, wi) * cos_prev / dist2) / remap(c_prev));
                }
                inv_w = inv_w + r;
            }
            sr = ShadowRay(po, shadow_dist * (1.0 - 1e-4), shadow_dir, 1u, beta * fcos * le * (c.g / (l0 * inv_w)), 0u);
        }
    }
    let bs = bsdf_sample(s, wi, true);
    if (!bs.ok) {
        return sr;
    }
    let wo = bs.wo;
    var beta_next = beta * bs.weight;
    if (!(max(beta_next.x, max(beta_next.y, beta_next.z)) > 0.0)) {
        return sr;
    }
    let delta = bs.pdf == 0.0;
    // y_{m−1}'s light-side density is y_m's BSDF sampled from wo towards it (0 through
    // a delta lobe, which counts as 1).
    if (m >= 2) {
        let back = select(bsdf_pdf(s, wo, wi), 0.0, delta);
        (*p).prod = prod * sq(remap(back * cos_prev / dist2) / remap(c_prev));
    }
    var flags = (*p).flags & PATH_DELTA_FIRST;
    if (m == 1 && delta) {
        flags = PATH_DELTA_FIRST;
    }
    if (delta) {
        flags = flags | PATH_DELTA_PREV;
    }
    (*p).c_prev = c_here;
    (*p).n_prev = s.ng;
    (*p).prev_p = s.p;
    (*p).pdf_dir = bs.pdf;
    (*p).o = spawn(s.p, s.ng, wo);
    (*p).d = wo;
    if (m >= P.rr_depth) {
        let q = survival(beta_next);
        if (q == 0.0) {
            (*p).flags = flags;
            return sr;
        }
        beta_next = beta_next / q;
    }
    (*p).beta = beta_next;
    (*p).flags = select(flags | PATH_ALIVE, flags, m > 4096);
    return sr;
}

// The rest of a walk in one thread, each shadow ray traced as soon as it is made (the
// megakernel's walk, and the wavefront's tail).
fn camera_walk(p: ptr<function, CameraPath>) {
    loop {
        if (((*p).flags & PATH_ALIVE) == 0u) {
            break;
        }
        let h = intersect((*p).o, (*p).d, 3.0e38, false);
        let sr = camera_hit(p, h);
        if (sr.on != 0u && intersect(sr.o, sr.dir, sr.dist, true).tri == NONE) {
            (*p).l = (*p).l + sr.c;
        }
    }
}

// Radiance along the camera ray through film position `pos` (pixels); the generator seeded.
fn camera_radiance(pos: vec2<f32>) -> vec3<f32> {
    var p = camera_start(pos);
    camera_walk(&p);
    return p.l;
}

// The camera samples of thread (px, py, z): samples z, z + P.slices, … of the dispatch, summed
// into slice z of the film. With `light` (instant BPT's fused kernel) each camera sample is
// followed by its light path, so one dispatch and no barrier separate the two passes.
fn camera_samples(px: u32, py: u32, z: u32, light: bool) {
    let i = z * P.width * P.height + py * P.width + px;
    var sum = sums[i];
    var sq_sum = squares[i];
    for (var k = z; k < P.samples; k = k + P.slices) {
        seed_rng(px, py, P.first_sample + k, 0u);
        let pos = vec2<f32>(f32(px) + rnd(), f32(py) + rnd());
        let l = camera_radiance(pos);
        // Non-finite samples are rejected and counted, as on the CPU.
        if (finite(l.x) && finite(l.y) && finite(l.z)) {
            if (P.filter_radius > 0.0) {
                film_add(pos, l, true);
            } else {
                sum = sum + vec4<f32>(l, 1.0);
                sq_sum = sq_sum + vec4<f32>(l * l, 0.0);
            }
        } else {
            sq_sum.w = sq_sum.w + 1.0;
        }
        if (light) {
            light_path(px, py, P.first_sample + k);
        }
    }
    sums[i] = sum;
    squares[i] = sq_sum;
    count_rays();
}

// Set by the pipeline: instant BPT in one kernel, the camera pass and the light pass of each
// sample in turn (launch.rs's `fused`; measured slower, off by default).
override FUSED: bool = false;

@compute @workgroup_size(8, 8)
fn camera_main(@builtin(global_invocation_id) id: vec3<u32>) {
    let px = P.x0 + id.x;
    let py = P.y0 + id.y;
    if (px >= P.width || py >= P.height) {
        return;
    }
    camera_samples(px, py, id.z, FUSED);
}
