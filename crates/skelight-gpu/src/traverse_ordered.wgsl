// The ordered traversal (bvh.rs, `Traversal::Ordered`): each inner node holds both children's
// boxes (Aila and Laine 2009's layout: one 64-byte fetch tests two boxes); the nearer child is
// visited first and the farther waits on a stack with the distance at which its box begins,
// so that it is dropped when a closer hit has been found meanwhile. bvh.rs bounds the tree's
// depth by STACK, so the stack cannot overflow.

struct Node {
    lo_a: vec3<f32>,
    index_a: u32,          // inner child: its node; leaf: its first triangle
    hi_a: vec3<f32>,
    count_a: u32,          // inner child: 0; leaf: LEAF | its triangle count (0: no child)
    lo_b: vec3<f32>,
    index_b: u32,
    hi_b: vec3<f32>,
    count_b: u32,
}

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
fn traverse(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, first_hit: bool) -> Hit {
    var best = Hit(t_max, NONE, vec2<f32>(0.0));
    let inv_d = 1.0 / d;
    let shear = ray_shear(d);
    var stack_node: array<u32, STACK>;
    var stack_entry: array<f32, STACK>;
    var sp = 0u;
    var i = 0u;
    loop {
        let n = nodes[i];
        let ea = slab(n.lo_a, n.hi_a, o, inv_d, best.t);
        let eb = slab(n.lo_b, n.hi_b, o, inv_d, best.t);
        var a = ea.x <= ea.y;
        var b = eb.x <= eb.y;
        // Leaves at once; inner children after, unless a leaf's hit now lies before their box.
        if (a && (n.count_a & LEAF) != 0u) {
            if (hit_leaf(n.index_a, n.count_a & ~LEAF, o, shear, t_min, first_hit, &best)) {
                return best;
            }
            a = false;
        }
        if (b && (n.count_b & LEAF) != 0u) {
            if (hit_leaf(n.index_b, n.count_b & ~LEAF, o, shear, t_min, first_hit, &best)) {
                return best;
            }
            b = false;
        }
        a = a && ea.x <= best.t;
        b = b && eb.x <= best.t;
        if (a && b) {
            let a_first = ea.x <= eb.x;
            stack_node[sp] = select(n.index_a, n.index_b, a_first);
            stack_entry[sp] = select(ea.x, eb.x, a_first);
            sp = sp + 1u;
            i = select(n.index_b, n.index_a, a_first);
        } else if (a) {
            i = n.index_a;
        } else if (b) {
            i = n.index_b;
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
