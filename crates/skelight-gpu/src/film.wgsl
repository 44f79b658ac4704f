// The film. Under the box filter a camera sample counts for its own pixel (the camera pass
// sums a thread's pixel without atomics) and a light splat lands in one pixel. Under the tent
// filter both spread over the pixels whose centres lie within the radius, weighted by the
// tent's product over the two axes, as the CPU's Film::add and splat; camera samples then add
// with atomics too, after the light splats in the same buffer: per pixel Σ w·L (rgb),
// Σ w·L² (rgb) and Σ w. Light splats are divided by the filter's coverage of each pixel on
// the CPU when read back (Film::add_pixel_splats).

fn tent(x: f32) -> f32 {
    return max(1.0 - abs(x) / P.filter_radius, 0.0);
}

// Adds `c` at film position `pos` (pixels) to every pixel of the tent's footprint: a camera
// sample (weighted sums) or a light splat.
fn film_add(pos: vec2<f32>, c: vec3<f32>, camera: bool) {
    let r = P.filter_radius;
    let lo = max(vec2<i32>(ceil(pos - r - 0.5)), vec2<i32>(0));
    let hi = min(vec2<i32>(floor(pos + r - 0.5)), vec2<i32>(i32(P.width) - 1, i32(P.height) - 1));
    for (var y = lo.y; y <= hi.y; y = y + 1) {
        for (var x = lo.x; x <= hi.x; x = x + 1) {
            let w = tent(f32(x) + 0.5 - pos.x) * tent(f32(y) + 0.5 - pos.y);
            if (w <= 0.0) {
                continue;
            }
            let i = u32(y) * P.width + u32(x);
            if (camera) {
                let k = 3u * P.width * P.height + 7u * i;
                splat_add(k, w * c.x);
                splat_add(k + 1u, w * c.y);
                splat_add(k + 2u, w * c.z);
                splat_add(k + 3u, w * c.x * c.x);
                splat_add(k + 4u, w * c.y * c.y);
                splat_add(k + 5u, w * c.z * c.z);
                splat_add(k + 6u, w);
            } else {
                splat_add(3u * i, w * c.x);
                splat_add(3u * i + 1u, w * c.y);
                splat_add(3u * i + 2u, w * c.z);
            }
        }
    }
}

// A light splat at film position `pos` in pixel `pixel`.
fn splat(pixel: u32, pos: vec2<f32>, c: vec3<f32>) {
    if (!(finite(c.x) && finite(c.y) && finite(c.z))) {
        return;
    }
    if (P.filter_radius > 0.0) {
        film_add(pos, c, false);
        return;
    }
    splat_add(3u * pixel, c.x);
    splat_add(3u * pixel + 1u, c.y);
    splat_add(3u * pixel + 2u, c.z);
}
