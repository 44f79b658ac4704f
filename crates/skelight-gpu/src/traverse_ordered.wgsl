// The ordered traversal (bvh.rs, `Traversal::Ordered`): each inner node holds both children's
// boxes (Aila and Laine 2009's layout: one 64-byte fetch tests two boxes); the nearer child is
// visited first and the farther waits on a stack with the distance at which its box begins,
// so that it is dropped when a closer hit has been found meanwhile. bvh.rs bounds the tree's
// depth by STACK, so the stack cannot overflow. A node (bvh.rs's PairNode), 4 words: child a's
// lo and index (an inner child's node, counted from PAIR_ROOT, or a leaf's first triangle), its
// hi and count (0 for an inner child, LEAF | triangles for a leaf, none for a missing child); the
// same for child b.

const LEAF: u32 = 0x80000000u;
const STACK: u32 = 32u;    // bvh.rs's MAX_DEPTH

// Where the ray enters and leaves a box, clipped to [0, t_max]: a hit when x <= y.
fn slab(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, inv_d: vec3<f32>, t_max: f32) -> vec2<f32> {
    let a = (lo - o) * inv_d;
    let b = (hi - o) * inv_d;
    let t0 = max(max(min(a.x, b.x), min(a.y, b.y)), max(min(a.z, b.z), 0.0));
    let t1 = min(min(max(a.x, b.x), max(a.y, b.y)), min(max(a.z, b.z), t_max));
    return vec2<f32>(t0, t1);
}

// The closest hit in (t_min, t_max), or any hit when `first_hit` (masks: `hit_leaf`).
fn traverse_ordered(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, first_hit: bool) -> Hit {
    var best = Hit(t_max, NONE, vec2<f32>(0.0));
    let inv_d = 1.0 / d;
    let shear = ray_shear(d);
    var stack_node: array<u32, STACK>;
    var stack_entry: array<f32, STACK>;
    var sp = 0u;
    var i = 0u;
    loop {
        let lo_a = nodes[PAIR_ROOT + 4u * i];
        let hi_a = nodes[PAIR_ROOT + 4u * i + 1u];
        let lo_b = nodes[PAIR_ROOT + 4u * i + 2u];
        let hi_b = nodes[PAIR_ROOT + 4u * i + 3u];
        let index_a = bitcast<u32>(lo_a.w);
        let count_a = bitcast<u32>(hi_a.w);
        let index_b = bitcast<u32>(lo_b.w);
        let count_b = bitcast<u32>(hi_b.w);
        let ea = slab(lo_a.xyz, hi_a.xyz, o, inv_d, best.t);
        let eb = slab(lo_b.xyz, hi_b.xyz, o, inv_d, best.t);
        var a = ea.x <= ea.y;
        var b = eb.x <= eb.y;
        // Leaves at once; inner children after, unless a leaf's hit now lies before their box.
        if (a && (count_a & LEAF) != 0u) {
            if (hit_leaf(index_a, count_a & ~LEAF, o, shear, t_min, first_hit, &best)) {
                return best;
            }
            a = false;
        }
        if (b && (count_b & LEAF) != 0u) {
            if (hit_leaf(index_b, count_b & ~LEAF, o, shear, t_min, first_hit, &best)) {
                return best;
            }
            b = false;
        }
        a = a && ea.x <= best.t;
        b = b && eb.x <= best.t;
        if (a && b) {
            let a_first = ea.x <= eb.x;
            stack_node[sp] = select(index_a, index_b, a_first);
            stack_entry[sp] = select(ea.x, eb.x, a_first);
            sp = sp + 1u;
            i = select(index_b, index_a, a_first);
        } else if (a) {
            i = index_a;
        } else if (b) {
            i = index_b;
        } else {
            // The next waiting child whose box begins before the closest hit so far.
            loop {
                if (sp == 0u) {
                    return best;
                }
                sp = sp - 1u;
                if (stack_entry[sp] <= best.t) {
                    break;
                }
            }
            i = stack_node[sp];
        }
    }
    return best;
}
