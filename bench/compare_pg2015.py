#!/usr/bin/env python3
"""Normalised comparison of one of our renders with a pg2015 authors' reference PNG.

usage: .venv-bench/bin/python bench/compare_pg2015.py OURS.exr REFERENCE.png

The reference PNG is clamp(L^(1/2.2)) in 8 bits (Bonez's output): it is linearised with
gamma 2.2 and box-downsampled to our resolution (an integer factor); pixels whose block holds
a saturated byte (>= 250) are left out. Prints the scale k = sum(ref) / sum(ours) per channel
over the kept pixels (k = 1 when emission units and materials match) and, on a 4x2 grid of
regions, each region's ratio ref / (k * ours), which shows where the two differ beyond scale.
"""
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def load(path, srgb_png=False):
    b = mi.Bitmap(path)
    if b.pixel_format() != mi.Bitmap.PixelFormat.RGB:
        b = b.convert(mi.Bitmap.PixelFormat.RGB, b.component_format(), srgb_gamma=False)
    return np.array(b, dtype=np.float64)


def main():
    ours = load(sys.argv[1])
    raw = np.array(mi.Bitmap(sys.argv[2]), dtype=np.float64)[..., :3]
    h, w = ours.shape[:2]
    fy, fx = raw.shape[0] // h, raw.shape[1] // w
    assert fy == fx and raw.shape[0] == fy * h and raw.shape[1] == fx * w, (raw.shape, ours.shape)
    lin = (raw / 255.0) ** 2.2
    block = lambda a: a.reshape(h, fy, w, fx, -1)
    ref = block(lin).mean(axis=(1, 3))
    saturated = (block(raw) >= 250).any(axis=(1, 3, 4))
    keep = ~saturated
    k = ref[keep].sum(axis=0) / ours[keep].sum(axis=0)
    print(f"{sys.argv[1]} against {sys.argv[2]}: {w}x{h}, {saturated.mean() * 100:.1f} % of pixels left out (saturated)")
    print("scale k = ref / ours (R, G, B):", " ".join(f"{v:.3f}" for v in k))
    print("regions (4 columns x 2 rows), ref / (k * ours), luminance-weighted mean of RGB:")
    for ry in range(2):
        cells = []
        for rx in range(4):
            ys, xs = slice(ry * h // 2, (ry + 1) * h // 2), slice(rx * w // 4, (rx + 1) * w // 4)
            m = keep[ys, xs]
            r, o = ref[ys, xs][m].sum(), (ours[ys, xs][m] * k).sum()
            cells.append(f"{r / o:6.3f}" if o > 0 else "   -  ")
        print("   ", " ".join(cells))


if __name__ == "__main__":
    main()
