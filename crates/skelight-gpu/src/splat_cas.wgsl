// Splats for adapters without float atomics: a float kept as bits, added by compare and
// swap (lavapipe has float atomics too; this is the fallback).
@group(0) @binding(8) var<storage, read_write> splats: array<atomic<u32>>;

fn splat_add(k: u32, v: f32) {
    var old = atomicLoad(&splats[k]);
    loop {
        let r = atomicCompareExchangeWeak(&splats[k], old, bitcast<u32>(bitcast<f32>(old) + v));
        if (r.exchanged) {
            break;
        }
        old = r.old_value;
    }
}
