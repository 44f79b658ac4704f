// The wavefront camera pass (Laine, Karras and Aila 2013, "Megakernels considered harmful"):
// the megakernel's camera walk (camera_pass.wgsl's camera_start / camera_hit) split into
// kernels, each over a queue of the paths still alive, their state in memory between them:
//   wf_start   one thread per (pixel, slice): the camera ray of sample wave·slices + z;
//   wf_args    one thread: the next kernels' workgroup counts from the queues' lengths;
//   wf_extend  the closest hit of each queued path's ray (the traversal alone);
//   wf_shade   emission, next-event estimation's shadow ray, the next ray or the end;
//   wf_shadow  each shadow ray (any hit), adding its contribution when nothing blocks it;
//   wf_finish  one thread per (pixel, slice): the path's radiance into the film.
// The light pass of instant BPT likewise (lw_start, lw_extend, lw_shade, and lw_connect, which
// traces each vertex's segment to the lens and splats), in waves after the camera's. When few
// walks are left (checked every 8 bounces), wf_tail / lw_tail finish each in one thread. The
// kernels both passes share (extend, shade, tail) are wave_walk.wgsl, written once for both.
// The queues compact the live paths, so a kernel's threads all have work and run the same
// code; the cost is the state's traffic (112 bytes a path, 48 a shadow ray) and more
// dispatches. The random numbers are the megakernel's (the counter travels with the path), so
// both render the same image. lib.rs's wavefront.rs encodes the sequence.

@group(1) @binding(0) var<storage, read_write> wf_paths: array<CameraPath>;
@group(1) @binding(1) var<storage, read_write> wf_hits: array<Hit>;
@group(1) @binding(2) var<storage, read_write> wf_shadows: array<ShadowRay>;
@group(1) @binding(3) var<storage, read_write> wf_queue_in: array<u32>;
@group(1) @binding(4) var<storage, read_write> wf_queue_out: array<u32>;
// [0] paths queued in, [1] paths appended out, [2] shadow rays appended, [3] shadow rays to trace.
@group(1) @binding(5) var<storage, read_write> wf_counts: array<atomic<u32>, 4>;
// The light pass's walks and splats (light_pass.wgsl), in a wave of their own.
@group(1) @binding(6) var<storage, read_write> wf_light_paths: array<LightPath>;
@group(1) @binding(7) var<storage, read_write> wf_lens_rays: array<LensRay>;
// Indirect dispatch arguments: the queued paths' (0–2), the shadow rays' (3–5); a group of its
// own, bound to wf_args_main alone (a buffer may not be both written and read as arguments
// by one dispatch).
@group(2) @binding(0) var<storage, read_write> wf_args: array<u32, 6>;

const WF_GROUP: u32 = 64u;

// The wave's path of tile thread (x, y, z), its pixel and sample (`inside`: within the image
// and the dispatch's samples).
struct WavePath {
    path: u32,
    px: u32,
    py: u32,
    k: u32,
    inside: bool,
}

fn wave_path(id: vec3<u32>) -> WavePath {
    let px = P.x0 + id.x;
    let py = P.y0 + id.y;
    let k = P.wave * P.slices + id.z;
    let path = (id.z * P.wf_tile_h + id.y) * P.wf_tile_w + id.x;
    return WavePath(path, px, py, k, px < P.width && py < P.height && k < P.samples);
}

@compute @workgroup_size(8, 8)
fn wf_start(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = wave_path(id);
    if (!w.inside) {
        return;
    }
    seed_rng(w.px, w.py, P.first_sample + w.k, 0u);
    let pos = vec2<f32>(f32(w.px) + rnd(), f32(w.py) + rnd());
    var p = camera_start(pos);
    p.rng_n = rng_n;
    p.pixel = w.py * P.width + w.px;
    p.sample = P.first_sample + w.k;
    wf_paths[w.path] = p;
    if ((p.flags & PATH_ALIVE) != 0u) {
        wf_queue_out[atomicAdd(&wf_counts[1], 1u)] = w.path;
    }
}

// Between the kernels: the paths appended become the queue in (lib.rs swaps the queues' bind
// groups at the same time), the shadow rays appended become those to trace.
@compute @workgroup_size(1)
fn wf_args_main() {
    let paths = atomicExchange(&wf_counts[1], 0u);
    atomicStore(&wf_counts[0], paths);
    let shadows = atomicExchange(&wf_counts[2], 0u);
    atomicStore(&wf_counts[3], shadows);
    wf_args[0] = (paths + WF_GROUP - 1u) / WF_GROUP;
    wf_args[1] = 1u;
    wf_args[2] = 1u;
    wf_args[3] = (shadows + WF_GROUP - 1u) / WF_GROUP;
    wf_args[4] = 1u;
    wf_args[5] = 1u;
}

@compute @workgroup_size(64)
fn wf_shadow(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= atomicLoad(&wf_counts[3])) {
        return;
    }
    let sr = wf_shadows[id.x];
    if (intersect(sr.o, sr.dir, sr.dist, true).tri == NONE) {
        // One shadow ray per path and bounce: no other thread adds to this path now.
        wf_paths[sr.path].l = wf_paths[sr.path].l + sr.c;
    }
    count_rays();
}

@compute @workgroup_size(8, 8)
fn wf_finish(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = wave_path(id);
    if (!w.inside) {
        return;
    }
    let p = wf_paths[w.path];
    let l = p.l;
    let i = id.z * P.width * P.height + w.py * P.width + w.px;
    // Non-finite samples are rejected and counted, as on the CPU.
    if (finite(l.x) && finite(l.y) && finite(l.z)) {
        if (P.filter_radius > 0.0) {
            film_add(p.pos, l, true);
        } else {
            sums[i] = sums[i] + vec4<f32>(l, 1.0);
            squares[i] = squares[i] + vec4<f32>(l * l, 0.0);
        }
    } else {
        squares[i].w = squares[i].w + 1.0;
    }
}

@compute @workgroup_size(8, 8)
fn lw_start(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = wave_path(id);
    if (!w.inside) {
        return;
    }
    var p: LightPath;
    let r = light_start(w.px, w.py, P.first_sample + w.k, &p);
    p.rng_n = rng_n;
    p.pixel = w.py * P.width + w.px;
    p.sample = P.first_sample + w.k;
    wf_light_paths[w.path] = p;
    if ((p.flags & PATH_ALIVE) != 0u) {
        wf_queue_out[atomicAdd(&wf_counts[1], 1u)] = w.path;
    }
    if (r.on != 0u) {
        wf_lens_rays[atomicAdd(&wf_counts[2], 1u)] = r;
    }
}

@compute @workgroup_size(64)
fn lw_connect(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= atomicLoad(&wf_counts[3])) {
        return;
    }
    lens_splat(wf_lens_rays[id.x]);
    count_rays();
}
