// The stackless traversal (bvh.rs, `Traversal::Stackless`): one box per node of 3 words (lo
// and first triangle; hi and triangle count, 0 for an inner node; the miss link), depth-first
// with a miss link per node, children in a fixed order (the left first).

fn hit_box(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, inv_d: vec3<f32>, t_max: f32) -> bool {
    let a = (lo - o) * inv_d;
    let b = (hi - o) * inv_d;
    let t0 = max(max(min(a.x, b.x), min(a.y, b.y)), max(min(a.z, b.z), 0.0));
    let t1 = min(min(max(a.x, b.x), max(a.y, b.y)), min(max(a.z, b.z), t_max));
    return t0 <= t1;
}

// The closest hit in (t_min, t_max), or any hit when `first_hit` (masks: `hit_leaf`).
fn traverse_stackless(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, first_hit: bool) -> Hit {
    var best = Hit(t_max, NONE, vec2<f32>(0.0));
    let inv_d = 1.0 / d;
    let shear = ray_shear(d);
    var i = 0u;
    loop {
        if (i == NONE) {
            break;
        }
        let lo = nodes[3u * i];
        let hi = nodes[3u * i + 1u];
        if (!hit_box(lo.xyz, hi.xyz, o, inv_d, best.t)) {
            i = bitcast<u32>(nodes[3u * i + 2u].x);
            continue;
        }
        let count = bitcast<u32>(hi.w);
        if (count == 0u) {
            i = i + 1u;
            continue;
        }
        if (hit_leaf(bitcast<u32>(lo.w), count, o, shear, t_min, first_hit, &best)) {
            return best;
        }
        i = bitcast<u32>(nodes[3u * i + 2u].x);
    }
    return best;
}

