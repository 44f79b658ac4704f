#!/usr/bin/env python3
"""Normalised comparison of one of our renders with a pg2015 authors' reference (PNG or EXR).

usage: .venv-bench/bin/python bench/compare_pg2015.py OURS.exr REFERENCE.png   (needs mitsuba)
       .venv-py/bin/python    bench/compare_pg2015.py OURS.exr REFERENCE.exr   (needs skelight's package)

A reference PNG is clamp(L^(1/2.2)) in 8 bits (Bonez's output): it is linearised with gamma 2.2;
pixels whose block holds a saturated byte (>= 250) are left out. A reference EXR (the corridor's)
is stored bottom-up and holds the sum over the render's iterations: it is flipped and divided by
the IterationCount of reference.bnz.xml beside it. Either is box-downsampled to our resolution
(an integer factor). Prints the scale k = sum(ref) / sum(ours) per channel over the kept pixels
(k = 1 when emission units and materials match) and, on a 4x2 grid of regions (4x4 for an EXR),
each region's ratio ref / (k * ours), which shows where the two differ beyond scale.
"""
import os
import re
import sys

import numpy as np


def load_exr(path):
    import skelight

    return np.asarray(skelight.load_image(path), dtype=np.float64)[..., :3]


def load_mitsuba(path, raw=False):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    b = mi.Bitmap(path)
    if raw:
        return np.array(b, dtype=np.float64)[..., :3]
    if b.pixel_format() != mi.Bitmap.PixelFormat.RGB:
        b = b.convert(mi.Bitmap.PixelFormat.RGB, b.component_format(), srgb_gamma=False)
    return np.array(b, dtype=np.float64)


def iteration_count(reference):
    xml = os.path.join(os.path.dirname(reference), "reference.bnz.xml")
    m = re.search(r'<IterationCount value="(\d+)"', open(xml).read())
    if not m:
        sys.exit(f"{xml}: no IterationCount")
    return int(m.group(1))


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    ours_path, ref_path = sys.argv[1], sys.argv[2]
    exr = ref_path.lower().endswith(".exr")
    ours = load_exr(ours_path) if exr else load_mitsuba(ours_path)
    h, w = ours.shape[:2]
    if exr:
        raw = load_exr(ref_path)[::-1] / iteration_count(ref_path)
        lin = raw
    else:
        raw = load_mitsuba(ref_path, raw=True)
        lin = (raw / 255.0) ** 2.2
    fy, fx = raw.shape[0] // h, raw.shape[1] // w
    assert fy == fx and raw.shape[0] == fy * h and raw.shape[1] == fx * w, (raw.shape, ours.shape)
    block = lambda a: a.reshape(h, fy, w, fx, -1)
    ref = block(lin).mean(axis=(1, 3))
    saturated = np.zeros((h, w), bool) if exr else (block(raw) >= 250).any(axis=(1, 3, 4))
    keep = ~saturated
    k = ref[keep].sum(axis=0) / ours[keep].sum(axis=0)
    print(f"{ours_path} against {ref_path}: {w}x{h}, {saturated.mean() * 100:.1f} % of pixels left out (saturated)")
    print("scale k = ref / ours (R, G, B):", " ".join(f"{v:.4f}" for v in k))
    rows = 4 if exr else 2
    print(f"regions (4 columns x {rows} rows), ref / (k * ours), luminance-weighted mean of RGB:")
    for ry in range(rows):
        cells = []
        for rx in range(4):
            ys, xs = slice(ry * h // rows, (ry + 1) * h // rows), slice(rx * w // 4, (rx + 1) * w // 4)
            m = keep[ys, xs]
            r, o = ref[ys, xs][m].sum(), (ours[ys, xs][m] * k).sum()
            cells.append(f"{r / o:6.3f}" if o > 0 else "   -  ")
        print("   ", " ".join(cells))


if __name__ == "__main__":
    main()
