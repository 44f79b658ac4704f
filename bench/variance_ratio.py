#!/usr/bin/env python3
"""Where a guided estimator gains or loses against pt, pixel by pixel, per sample.

usage: .venv-py/bin/python bench/variance_ratio.py SCENE OUT_DIR [--spp N] [--resolution W H]
           [--max-depth D] [--seed S] [--guided NAME:PARAM=V:...] [--block K] [--zoom Z]

Renders SCENE with pt and with the guided estimator (default `skelpt`) at the same sample count
and reads each film's per-pixel variance of the pixel estimate (the sample variance over n, so
both are per sample at equal n). Writes OUT_DIR/variance_ratio.png: log2 of var(guided)/var(pt)
over K×K blocks of pixels (default 4: a single pixel's variance estimate is too noisy to read),
blue where the guided estimator has less variance per sample, red where it has more, white
where they are equal, saturated at 8x either way, black where either is zero; zoomed Z times.
Prints the share of pixels on each side and the share of the summed variance (what MSE sums)
that each image region holds, for both estimators, on a 4x2 grid. The variance estimates of a
heavy-tailed estimator are noisy: use a few thousand samples per pixel.
"""
import argparse
import os
import struct
import zlib

import numpy as np

import skelight


def write_png(path, rgb):
    """An 8-bit RGB PNG written with the standard library (no imaging package needed)."""
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[y].astype(np.uint8).tobytes() for y in range(h))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(png)
    os.replace(tmp, path)


def estimator(spec):
    """`name:key=value:...` as the CLI's `compare` takes it."""
    name, *pairs = spec.split(":")
    return name, dict(p.split("=", 1) for p in pairs)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--spp", type=int, default=2048)
    ap.add_argument("--resolution", type=int, nargs=2, default=None)
    ap.add_argument("--max-depth", type=int, default=None)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--guided", default="skelpt")
    ap.add_argument("--block", type=int, default=4)
    ap.add_argument("--zoom", type=int, default=4)
    args = ap.parse_args()
    scene = skelight.load_file(args.scene)
    if args.resolution:
        scene.set_resolution(*args.resolution)
    if args.max_depth is not None:
        scene.max_depth = args.max_depth
    os.makedirs(args.out, exist_ok=True)
    variances = {}
    for spec in ["pt", args.guided]:
        name, params = estimator(spec)
        r = skelight.render(scene, integrator=name, spp=args.spp, seed=args.seed, params=params or None)
        v = np.asarray(r.variance, dtype=np.float64)[..., :3].mean(axis=2)
        variances[spec] = v
        print(f"{spec}: {r.spp} spp in {r.seconds:.1f} s, summed variance {v.sum():.4e}")
    pt, guided = variances["pt"], variances[args.guided]
    k = max(args.block, 1)
    h, w = (pt.shape[0] // k) * k, (pt.shape[1] // k) * k
    blocks = [v[:h, :w].reshape(h // k, k, w // k, k).sum(axis=(1, 3)) for v in (pt, guided)]
    both_blocks = (blocks[0] > 0) & (blocks[1] > 0)
    block_ratio = np.zeros_like(blocks[0])
    block_ratio[both_blocks] = np.log2(blocks[1][both_blocks] / blocks[0][both_blocks])
    t = np.clip(block_ratio / 3.0, -1.0, 1.0)
    rgb = np.ones(t.shape + (3,))
    rgb[..., 0] -= np.clip(-t, 0, 1)  # blue: less variance
    rgb[..., 1] -= np.abs(t)
    rgb[..., 2] -= np.clip(t, 0, 1)  # red: more variance
    rgb[~both_blocks] = 0.0
    rgb = np.repeat(np.repeat(rgb, k * args.zoom, axis=0), k * args.zoom, axis=1)
    write_png(os.path.join(args.out, "variance_ratio.png"), np.round(rgb * 255))
    both = (pt > 0) & (guided > 0)
    ratio = np.zeros_like(pt)
    ratio[both] = np.log2(guided[both] / pt[both])
    n = both.sum()
    print(f"pixels with less variance per sample: {(ratio[both] < 0).sum() / max(n, 1):.1%}, "
          f"with more: {(ratio[both] > 0).sum() / max(n, 1):.1%}; summed variance {args.guided}/pt "
          f"{guided.sum() / pt.sum():.3f}")
    h, w = pt.shape
    print("region (row, col): share of pt's summed variance, share of the guided one's, their ratio")
    for i in range(2):
        for j in range(4):
            sl = (slice(i * h // 2, (i + 1) * h // 2), slice(j * w // 4, (j + 1) * w // 4))
            a, b = pt[sl].sum(), guided[sl].sum()
            print(f"  ({i}, {j}): {a / pt.sum():6.1%} {b / guided.sum():6.1%}  {b / a if a > 0 else float('nan'):6.2f}")


if __name__ == "__main__":
    main()
