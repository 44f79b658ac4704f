// Splats with the adapter's float atomics (VK_EXT_shader_atomic_float).
@group(0) @binding(8) var<storage, read_write> splats: array<atomic<f32>>;

fn splat_add(k: u32, v: f32) {
    atomicAdd(&splats[k], v);
}
