// The light pass of instant BPT (seed 002, §3): one light path per (pixel, sample) of the
// dispatch, its own random stream; every vertex x_j not specular is joined to the pinhole
// (explicit light paths, the CPU's t = 1) and splatted onto the film with atomic adds. A
// pinhole cannot be hit; a thin lens's aperture could, but that strategy (the CPU's t = 0)
// is left out here, so implicit light paths do not occur.
//
// MIS (see camera_pass.wgsl for the notation): the light walk keeps one float, `prod` =
// Π (C/L)² over x_1 … x_{j−2}, and the origin's term `origin` = [x_1 not specular] + (C_0/L_0)²
// (next-event estimation and the camera hitting the light, relative to light tracing, share
// the product over x_1 … x_{j}); x_{j−1}'s camera-side density needs x_j's BSDF sampled from
// the lens's side, known once the walk has left x_j or the connection is made.

// The camera as seen from scene point `p` (geometric normal `ng`), through a lens point
// sampled on the aperture: the pixel the point projects to, and what a connection needs.
struct LensView {
    visible: bool,         // within the film and in front (the segment's visibility apart)
    pixel: u32,
    pos: vec2<f32>,        // film position (pixels)
    w: vec3<f32>,          // unit direction from p to the lens
    dist2: f32,
    importance: f32,       // W_e · pixels / (density of the lens point seen from p)
    c: f32,                // the camera's density of p per unit area (C of p)
    ray_o: vec3<f32>,      // the segment that must be free: from p's offset origin to the
    ray_dist: f32,         // near plane (0: none)
    ray_d: vec3<f32>,
}

// `lens_view` without the visibility test of its segment (the wavefront traces it apart).
fn lens_view_unoccluded(p: vec3<f32>, ng: vec3<f32>) -> LensView {
    var v: LensView;
    // A thin lens's point uniform on the aperture (its density per unit area cancels against
    // W_e's 1/area); the centre of a pinhole.
    let lens = lens_sample();
    let lens_world = P.cam_pos.xyz + mat3x3<f32>(P.cam_x.xyz, P.cam_y.xyz, P.cam_z.xyz) * lens;
    let to_lens = lens_world - p;
    // p in camera space (the lens lies in its plane z = 0).
    let q = mat3x3<f32>(P.inv_x.xyz, P.inv_y.xyz, P.inv_z.xyz) * (p - P.cam_pos.xyz);
    // Points nearer than the near plane are clipped away.
    if (!(q.z >= P.near_clip)) {
        return v;
    }
    // The film position: where the ray from the lens point through p crosses the plane of
    // focus, seen from the lens centre (the CPU's raster_of); q's own direction for a pinhole.
    let rel = q - lens;
    var x = rel.x / rel.z;
    var y = rel.y / rel.z;
    if (P.aperture_radius > 0.0) {
        x = x + lens.x / P.focus_distance;
        y = y + lens.y / P.focus_distance;
    }
    let sx = (1.0 - x / P.tan_half.x) * 0.5;
    let sy = (1.0 - y / P.tan_half.y) * 0.5;
    if (!(sx >= 0.0 && sx < 1.0 && sy >= 0.0 && sy < 1.0)) {
        return v;
    }
    let px = min(u32(sx * f32(P.width)), P.width - 1u);
    let py = min(u32(sy * f32(P.height)), P.height - 1u);
    v.dist2 = dot(to_lens, to_lens);
    v.w = to_lens * inverseSqrt(v.dist2);
    let cos_lens = -dot(v.w, P.forward.xyz);
    if (!(cos_lens > 0.0)) {
        return v;
    }
    // Only the segment beyond the near plane must be free (as the CPU's near_point).
    let near = lens_world - to_lens * (P.near_clip / q.z);
    let po = spawn(p, ng, v.w);
    let free_dist = distance(near, po);
    if (free_dist > 0.0) {
        v.ray_o = po;
        v.ray_d = (near - po) / free_dist;
        v.ray_dist = free_dist * (1.0 - 1e-4);
    }
    let pdf_dir = 1.0 / (film_area() * cos_lens * cos_lens * cos_lens);
    let we = pdf_dir / cos_lens;                  // 1 / (A cos⁴)
    // A thin lens's W_e carries 1/(aperture area), which its lens point's density cancels.
    v.importance = we * f32(P.width * P.height) * cos_lens / v.dist2;
    v.c = pdf_dir * abs(dot(ng, v.w)) / v.dist2;
    v.pixel = py * P.width + px;
    v.pos = vec2<f32>(sx * f32(P.width), sy * f32(P.height));
    v.visible = true;
    return v;
}

fn lens_view(p: vec3<f32>, ng: vec3<f32>) -> LensView {
    var v = lens_view_unoccluded(p, ng);
    if (v.visible && v.ray_dist > 0.0 && intersect(v.ray_o, v.ray_d, v.ray_dist, true).tri != NONE) {
        v.visible = false;
    }
    return v;
}

// The splat's MIS weight from the sum of the strategies' squared densities relative to light
// tracing's: 1 when light tracing renders alone (the CPU's `lt`, which checks this pass's
// throughput apart from its weights).
fn light_weight(inv_w: f32) -> f32 {
    return select(1.0 / inv_w, 1.0, P.bidirectional == 2u);
}

// A light walk between two of its rays, with its one-float MIS state: what the megakernel
// keeps in registers and the wavefront kernels (wavefront.wgsl) in memory, 112 bytes.
struct LightPath {
    o: vec3<f32>,          // the next ray
    pdf_dir: f32,          // its direction's solid-angle density (0: through a delta lobe)
    d: vec3<f32>,
    j: i32,                // the current vertex is x_j
    beta: vec3<f32>,
    prod: f32,             // the MIS product over x_1 … x_{j−2}
    prev_p: vec3<f32>,
    l_prev: f32,           // x_{j−1}'s light-side density
    n_prev: vec3<f32>,     // x_{j−1}'s geometric normal (zero at a point-like light)
    origin: f32,           // the origin's MIS term
    first: f32,            // for x_1's light-side density: the emission's density towards it, or
                           // a distant light's area
    l0_mis: f32,           // L_0 for the MIS
    flags: u32,            // PATH_ALIVE, LIGHT_*
    rng_n: u32,            // the wavefront's copy of the generator's counter
    pixel: u32,            // the wavefront's (pixel, sample), which key the generator
    sample: u32,
    pad0: u32,
    pad1: u32,
}

const LIGHT_DELTA: u32 = 2u;     // the light point is a delta (point, spot, directional)
const LIGHT_DISTANT: u32 = 4u;   // a directional light or the environment

// A light-path vertex joined to the lens: the splat it makes if its segment is free.
struct LensRay {
    o: vec3<f32>,
    dist: f32,             // 0: nothing to test
    dir: vec3<f32>,
    on: u32,               // 0: no splat
    c: vec3<f32>,
    pixel: u32,
    pos: vec2<f32>,
    path: u32,             // the wavefront's path index
    pad: u32,
}

// The splat of `view` with contribution `c`, its segment to test.
fn lens_ray(view: LensView, c: vec3<f32>) -> LensRay {
    return LensRay(view.ray_o, view.ray_dist, view.ray_d, 1u, c, view.pixel, view.pos, 0u, 0u);
}

// x_1's light-side density per unit area (first_hit_density from what the walk keeps).
fn first_density(p: ptr<function, LightPath>, w: vec3<f32>, at: vec3<f32>, ng: vec3<f32>) -> f32 {
    if (((*p).flags & LIGHT_DISTANT) != 0u) {
        return abs(dot(ng, w)) / (*p).first;
    }
    let to = at - (*p).prev_p;
    return (*p).first * abs(dot(ng, w)) / dot(to, to);
}

// The light path of (pixel, sample): its light point, the splat of that point seen by the
// camera (k = 1), and its first ray.
fn light_start(px: u32, py: u32, sample: u32, p: ptr<function, LightPath>) -> LensRay {
    var r: LensRay;
    seed_rng(px, py, sample, 1u);
    if (P.emitters == 0u || P.max_depth == 0) {
        return r;
    }
    let lp = sample_light_point();
    // The light point's density: for the throughput (per unit area, on a distant light's
    // disk), and L_0 for the MIS (the environment's per solid angle).
    let l0 = origin_density(lp);
    (*p).l0_mis = nee_density(lp);
    // The light point seen by the camera (k = 1): only the camera hitting it competes.
    // Point-like lights cannot be seen (the CPU's connect_to_camera skips them too).
    if (!lp.delta && !lp.distant) {
        let view0 = lens_view_unoccluded(lp.q, lp.ng);
        if (view0.visible) {
            let inv_w = 1.0 + sq(view0.c / l0);
            r = lens_ray(view0, emitted(lp, view0.w) * (abs(dot(lp.ng, view0.w)) / l0 * view0.importance * light_weight(inv_w)));
        }
    }
    let emission = sample_emission(lp);
    let d0 = emission.xyz;
    (*p).pdf_dir = emission.w;
    // Radiance × |cos_g| over the densities of the point and the direction.
    (*p).beta = emitted(lp, d0) * (light_cos(lp, d0) / (l0 * (*p).pdf_dir));
    if (!((*p).pdf_dir > 0.0) || !(max((*p).beta.x, max((*p).beta.y, (*p).beta.z)) > 0.0)) {
        return r;
    }
    (*p).o = spawn(lp.q, lp.ng, d0);
    (*p).d = d0;
    (*p).prev_p = lp.q;
    (*p).prod = 1.0;
    (*p).l_prev = l0;
    (*p).n_prev = lp.ng;
    (*p).first = select(emission_pdf(lp, d0), lp.e.area, lp.distant);
    (*p).flags = PATH_ALIVE | select(0u, LIGHT_DELTA, lp.delta) | select(0u, LIGHT_DISTANT, lp.distant);
    return r;
}

// The walk's step at the hit `h` of its ray: the splat of x_j joined to the lens, and the
// next ray by BSDF sampling and Russian roulette, or the walk's end (PATH_ALIVE cleared).
fn light_hit(p: ptr<function, LightPath>, h: Hit) -> LensRay {
    var r: LensRay;
    let alive = (*p).flags;
    (*p).flags = (*p).flags & ~PATH_ALIVE;   // set again below if the walk goes on
    if (h.tri == NONE) {
        return r;
    }
    let j = (*p).j + 1;
    (*p).j = j;
    let d = (*p).d;
    let s = surface_at((*p).o, d, h);
    if (!s.front) {
        return r;
    }
    let delta_light = (alive & LIGHT_DELTA) != 0u;
    let distant = (alive & LIGHT_DISTANT) != 0u;
    let dist2 = dot(s.p - (*p).prev_p, s.p - (*p).prev_p);
    let cos_g = abs(dot(s.ng, d));
    // x_j's light-side density per unit area (x_1's from the light point's sampling).
    let l_here = select((*p).pdf_dir * cos_g / dist2, first_density(p, d, s.p, s.ng), j == 1);
    // x_{j−1}'s |cos| on the segment to x_j.
    let cos_prev = abs(dot((*p).n_prev, d));
    // x_{j−1}'s camera-side densities convert from solid angle by this: per unit area, or
    // per solid angle at the environment (x_0); 0 where the camera cannot hit x_0
    // (point-like and directional lights, whose normal is zero or which are delta).
    let to_prev = select(cos_prev / dist2, select(1.0, 0.0, delta_light), j == 1 && distant);
    let wi = -d;
    let beta = (*p).beta;
    // Explicit light path: x_j joined to the lens (j + 1 segments).
    if (P.max_depth < 0 || j + 1 <= P.max_depth) {
        let view = lens_view_unoccluded(s.p, s.ng);
        if (view.visible) {
            let fcos = bsdf_eval(s, wi, view.w, false) * adjoint_correction(s, wi, view.w);
            if (max(fcos.x, max(fcos.y, fcos.z)) > 0.0) {
                // x_{j−1}'s camera-side density: x_j's BSDF sampled from the lens's side.
                let c_prev = bsdf_pdf(s, view.w, wi) * to_prev;
                var inv_w = 1.0;
                if (j == 1) {
                    inv_w = 1.0 + sq(view.c / l_here) * (1.0 + sq(c_prev / (*p).l0_mis));
                } else {
                    inv_w = 1.0 + (*p).prod * sq(c_prev / remap((*p).l_prev)) * sq(view.c / remap(l_here)) * (*p).origin;
                }
                r = lens_ray(view, beta * fcos * (view.importance * light_weight(inv_w)));
            }
        }
    }
    // A further vertex would make paths longer than max_depth.
    if (P.max_depth >= 0 && j + 2 > P.max_depth) {
        return r;
    }
    let bs = bsdf_sample(s, wi, false);
    if (!bs.ok) {
        return r;
    }
    let wo = bs.wo;
    var beta_next = beta * bs.weight * adjoint_correction(s, wi, wo);
    if (!(max(beta_next.x, max(beta_next.y, beta_next.z)) > 0.0)) {
        return r;
    }
    let delta = bs.pdf == 0.0;
    // x_{j−1}'s camera-side density: x_j's BSDF sampled from wo towards it (0 through a
    // delta lobe).
    let c_prev = select(bsdf_pdf(s, wo, wi), 0.0, delta) * to_prev;
    if (j == 1) {
        // Next-event estimation needs x_1 not specular; the camera hitting x_0, an area light.
        (*p).origin = select(1.0, 0.0, delta) + select(sq(remap(c_prev) / (*p).l0_mis), 0.0, delta_light);
    } else {
        (*p).prod = (*p).prod * sq(remap(c_prev) / remap((*p).l_prev));
    }
    (*p).l_prev = l_here;
    (*p).n_prev = s.ng;
    (*p).prev_p = s.p;
    (*p).pdf_dir = bs.pdf;
    (*p).o = spawn(s.p, s.ng, wo);
    (*p).d = wo;
    // Russian roulette counts the light point among the vertices, as the CPU.
    if (j + 1 > P.rr_depth) {
        let q = survival(beta_next);
        if (q == 0.0) {
            return r;
        }
        beta_next = beta_next / q;
    }
    (*p).beta = beta_next;
    (*p).flags = select(alive, alive & ~PATH_ALIVE, j > 4096);
    return r;
}

// Traces a splat's segment and splats when it is free.
fn lens_splat(r: LensRay) {
    if (r.on != 0u && (r.dist <= 0.0 || intersect(r.o, r.dir, r.dist, true).tri == NONE)) {
        splat(r.pixel, r.pos, r.c);
    }
}

// The rest of a light walk in one thread, each splat's segment traced as soon as it is made
// (the megakernel's walk, and the wavefront's tail).
fn light_walk(p: ptr<function, LightPath>) {
    loop {
        if (((*p).flags & PATH_ALIVE) == 0u) {
            break;
        }
        lens_splat(light_hit(p, intersect((*p).o, (*p).d, 3.0e38, false)));
    }
}

fn light_path(px: u32, py: u32, sample: u32) {
    var p: LightPath;
    lens_splat(light_start(px, py, sample, &p));
    light_walk(&p);
}

@compute @workgroup_size(8, 8)
fn light_main(@builtin(global_invocation_id) id: vec3<u32>) {
    let px = P.x0 + id.x;
    let py = P.y0 + id.y;
    if (px >= P.width || py >= P.height) {
        return;
    }
    for (var k = id.z; k < P.samples; k = k + P.slices) {
        light_path(px, py, P.first_sample + k);
    }
    count_rays();
}
