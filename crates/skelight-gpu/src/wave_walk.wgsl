// The kernels of a wave that both passes share, instantiated per pass by wavefront.rs
// (`{prefix}`: wf for the camera, lw for the light; `{paths}` their walks, `{hit}` and `{walk}`
// camera_hit / light_hit and camera_walk / light_walk, `{rays}` the rays they make, `{stream}`
// their random stream, `{path_type}` CameraPath / LightPath).

// A queued walk's state, its random numbers resumed where it left them.
fn {prefix}_resume(path: u32) -> {path_type} {
    let p = {paths}[path];
    seed_rng(p.pixel % P.width, p.pixel / P.width, p.sample, {stream});
    rng_n = p.rng_n;
    return p;
}

// The closest hit of each queued walk's ray (the traversal alone).
@compute @workgroup_size(64)
fn {prefix}_extend(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= atomicLoad(&wf_counts[0])) {
        return;
    }
    let path = wf_queue_in[id.x];
    let p = {paths}[path];
    wf_hits[path] = intersect(p.o, p.d, 3.0e38, false);
    count_rays();
}

// Each queued walk's step at its hit: the ray it makes to trace, its next ray or its end.
@compute @workgroup_size(64)
fn {prefix}_shade(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= atomicLoad(&wf_counts[0])) {
        return;
    }
    let path = wf_queue_in[id.x];
    var p = {prefix}_resume(path);
    var r = {hit}(&p, wf_hits[path]);
    p.rng_n = rng_n;
    {paths}[path] = p;
    if ((p.flags & PATH_ALIVE) != 0u) {
        wf_queue_out[atomicAdd(&wf_counts[1], 1u)] = path;
    }
    if (r.on != 0u) {
        r.path = path;
        {rays}[atomicAdd(&wf_counts[2], 1u)] = r;
    }
}

// The tail of a wave: when few walks are left, each finishes in one thread, so that their
// last bounces do not cost a round of dispatches each.
@compute @workgroup_size(64)
fn {prefix}_tail(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= atomicLoad(&wf_counts[0])) {
        return;
    }
    let path = wf_queue_in[id.x];
    var p = {prefix}_resume(path);
    {walk}(&p);
    {paths}[path] = p;
    count_rays();
}
