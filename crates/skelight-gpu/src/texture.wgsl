// Textures, as the CPU's texture.rs: a descriptor of 17 words in `data` (tables.rs writes it)
// — kind, width, height, texel offset, the 2×3 uv transform, scale, a checkerboard's two
// colours — and a bitmap's texels as linear RGB, row by row from the top, repeated outside
// [0, 1)², bilinear or nearest.

const TEX_BILINEAR: u32 = 0u;
const TEX_NEAREST: u32 = 1u;
const TEX_CHECKER: u32 = 2u;

fn data_rgb(at: u32) -> vec3<f32> {
    return vec3<f32>(data[at], data[at + 1u], data[at + 2u]);
}

// Texel (x, y) of a w × h bitmap at `texels`, coordinates wrapped (whole numbers as floats,
// so that far-away uv cannot overflow an integer).
fn texel(texels: u32, w: u32, h: u32, x: f32, y: f32) -> vec3<f32> {
    let fw = f32(w);
    let fh = f32(h);
    let xi = min(u32(max(x - floor(x / fw) * fw, 0.0)), w - 1u);
    let yi = min(u32(max(y - floor(y / fh) * fh, 0.0)), h - 1u);
    return data_rgb(texels + 3u * (yi * w + xi));
}

fn texture_eval(t: u32, uv: vec2<f32>) -> vec3<f32> {
    let kind = bitcast<u32>(data[t]);
    let p = vec2<f32>(data[t + 4u] * uv.x + data[t + 5u] * uv.y + data[t + 6u],
                      data[t + 7u] * uv.x + data[t + 8u] * uv.y + data[t + 9u]);
    let scale = data[t + 10u];
    if (kind == TEX_CHECKER) {
        let f = p - floor(p);
        return scale * select(data_rgb(t + 14u), data_rgb(t + 11u), (f.x > 0.5) == (f.y > 0.5));
    }
    let w = bitcast<u32>(data[t + 1u]);
    let h = bitcast<u32>(data[t + 2u]);
    let texels = bitcast<u32>(data[t + 3u]);
    let x = p.x * f32(w) - 0.5;
    let y = p.y * f32(h) - 0.5;
    if (!finite(x) || !finite(y)) {
        return vec3<f32>(0.0);
    }
    if (kind == TEX_NEAREST) {
        return scale * texel(texels, w, h, floor(x + 0.5), floor(y + 0.5));
    }
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let v = texel(texels, w, h, x0, y0) * ((1.0 - fx) * (1.0 - fy)) + texel(texels, w, h, x0 + 1.0, y0) * (fx * (1.0 - fy))
        + texel(texels, w, h, x0, y0 + 1.0) * ((1.0 - fx) * fy) + texel(texels, w, h, x0 + 1.0, y0 + 1.0) * (fx * fy);
    return scale * v;
}
