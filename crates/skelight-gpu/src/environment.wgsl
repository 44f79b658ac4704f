// The environment: a constant radiance (the emitter's), or a lat-long map with Mitsuba 3's
// conventions, as the CPU's EnvMap: bilinear texels shifted half a texel in u, importance
// sampled by a marginal over rows of cells and a conditional per row (tables.rs writes the
// descriptor at P.environment_map: width, height, rows, texel offset, scale, to_world's and
// to_local's columns, the cumulative tables' offsets).

struct EnvSample {
    w: vec3<f32>,          // unit direction towards the environment
    radiance: vec3<f32>,
    pdf: f32,              // per solid angle; 0: no sample
}

fn env_word(k: u32) -> u32 {
    return bitcast<u32>(data[P.environment_map + k]);
}

fn env_matrix(k: u32) -> mat3x3<f32> {
    let a = P.environment_map + k;
    return mat3x3<f32>(data_rgb(a), data_rgb(a + 3u), data_rgb(a + 6u));
}

fn env_texel(x: u32, y: u32) -> vec3<f32> {
    let w = env_word(0u);
    let h = env_word(1u);
    return data_rgb(env_word(3u) + 3u * (min(y, h - 1u) * w + x % w));
}

// The map at lat-long coordinates `uv` (the CPU's eval_uv), scaled.
fn env_eval_uv(uv: vec2<f32>) -> vec3<f32> {
    let w = env_word(0u);
    let h = env_word(1u);
    var u = uv.x - 0.5 / f32(w);
    u = u - floor(u);
    let x = u * f32(w);
    let y = clamp(uv.y, 0.0, 1.0) * f32(max(h - 1u, 1u));
    let x0 = min(u32(x), w - 1u);
    let y0 = min(u32(y), max(h, 2u) - 2u);
    let fx = x - f32(x0);
    let fy = clamp(y - f32(y0), 0.0, 1.0);
    let v = env_texel(x0, y0) * ((1.0 - fx) * (1.0 - fy)) + env_texel(x0 + 1u, y0) * (fx * (1.0 - fy))
        + env_texel(x0, y0 + 1u) * ((1.0 - fx) * fy) + env_texel(x0 + 1u, y0 + 1u) * (fx * fy);
    return v * data[P.environment_map + 4u];
}

// Lat-long coordinates of world direction `d`, and sin θ from the horizontal component
// (accurate next to the poles).
fn env_uv(d: vec3<f32>) -> vec3<f32> {
    let l = normalize(env_matrix(14u) * d);
    let horizontal = sqrt(l.x * l.x + l.z * l.z);
    return vec3<f32>(atan2(l.x, -l.z) * 0.5 * INV_PI, atan2(horizontal, l.y) * INV_PI, horizontal);
}

// Bin i of the cumulative table at `at` (n bins): the largest i with cdf[i] ≤ u.
fn cdf_search(at: u32, n: u32, u: f32) -> u32 {
    var lo = 0u;
    var hi = n - 1u;
    loop {
        if (lo >= hi) {
            break;
        }
        let mid = (lo + hi + 1u) / 2u;
        if (data[at + mid] <= u) {
            lo = mid;
        } else {
            hi = mid - 1u;
        }
    }
    return lo;
}

// The density per unit square of lat-long coordinates of cell (row, col).
fn env_cell_pdf(row: u32, col: u32) -> f32 {
    let w = env_word(0u);
    let rows = env_word(2u);
    let m = env_word(23u);
    let c = env_word(24u) + row * (w + 1u);
    return (data[m + row + 1u] - data[m + row]) * (data[c + col + 1u] - data[c + col]) * f32(w * rows);
}

// Radiance arriving from direction `w` (unit, away from the scene).
fn env_eval(w: vec3<f32>) -> vec3<f32> {
    let e = emitters[P.environment];
    if (P.environment_map == NONE) {
        return e.radiance;
    }
    return env_eval_uv(env_uv(w).xy);
}

// The solid-angle density with which env_sample draws `w`.
fn env_pdf(w: vec3<f32>) -> f32 {
    if (P.environment_map == NONE) {
        return 0.25 * INV_PI;
    }
    let uv = env_uv(w);
    if (!(uv.z > 0.0)) {
        return 0.0;
    }
    let width = env_word(0u);
    let rows = env_word(2u);
    var px = uv.x - 0.5 / f32(width);
    px = px - floor(px);
    let col = min(u32(px * f32(width)), width - 1u);
    let row = min(u32(uv.y * f32(rows)), rows - 1u);
    return env_cell_pdf(row, col) / (2.0 * PI * PI * uv.z);
}

// A direction towards the environment, by its radiance (uniform for a constant one).
fn env_sample(u: vec2<f32>) -> EnvSample {
    let e = emitters[P.environment];
    if (P.environment_map == NONE) {
        return EnvSample(uniform_sphere(u), e.radiance, 0.25 * INV_PI);
    }
    let width = env_word(0u);
    let rows = env_word(2u);
    let m = env_word(23u);
    let row = cdf_search(m, rows, u.y);
    let c = env_word(24u) + row * (width + 1u);
    let col = cdf_search(c, width, u.x);
    let pr = data[m + row + 1u] - data[m + row];
    let pc = data[c + col + 1u] - data[c + col];
    if (!(pr > 0.0) || !(pc > 0.0)) {
        return EnvSample(vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0), 0.0);
    }
    let v_rem = clamp((u.y - data[m + row]) / pr, 0.0, 0.99999994);
    let u_rem = clamp((u.x - data[c + col]) / pc, 0.0, 0.99999994);
    let p = vec2<f32>((f32(col) + u_rem) / f32(width), (f32(row) + v_rem) / f32(rows));
    let uv = vec2<f32>(fract(p.x + 0.5 / f32(width)), p.y);
    let phi = uv.x * 2.0 * PI;
    let theta = uv.y * PI;
    let st = sin(theta);
    let w = normalize(env_matrix(5u) * vec3<f32>(sin(phi) * st, cos(theta), -cos(phi) * st));
    if (!(st > 0.0)) {
        return EnvSample(w, vec3<f32>(0.0), 0.0);
    }
    return EnvSample(w, env_eval_uv(uv), pr * pc * f32(width * rows) / (2.0 * PI * PI * st));
}
