#!/usr/bin/env python3
"""Equal-time variance of estimators on the caustic under a glass ball (seed 002's claim).

Usage: bench/caustic_study.py SCENE.xml [--time 30] [--integrators pt,ibpt] [-D name=value ...]
                              [--out DIR] [--rows 104:116] [--cols 48:80] [--threshold 4] [--reuse]

Each estimator renders the scene twice for the same wall time with different seeds. With two
independent unbiased renders a and b, mean((a - b)^2) / 2 estimates the variance of one
render per pixel, so no converged reference is needed (a path-traced reference would itself
be noisiest exactly on the caustic). The caustic region is the set of pixels of a box around
it (--rows, --cols; the defaults frame the caustic under the ball of c09_glass and of
scenes/caustic-small-light.xml) whose luminance in the per-pixel median of all renders
exceeds --threshold times the box's median. --reuse analyses the renders already in DIR.
Prints per-estimator variance on the caustic and on the whole image, and the equal-time
ratios against the first estimator; writes them to DIR/variance.csv with the renders.
Needs a release build of skelight and `pip install mitsuba` (only to read EXR files).
"""
import argparse
import os
import re
import subprocess
import sys

import mitsuba as mi
import numpy as np

ap = argparse.ArgumentParser()
ap.add_argument("scene")
ap.add_argument("--time", type=float, default=30.0, help="seconds per render")
ap.add_argument("--integrators", default="pt,ibpt")
ap.add_argument("-D", action="append", default=[], help="name=value scene parameter")
ap.add_argument("--out", default="caustic-study")
ap.add_argument("--rows", default="104:116", help="rows of the box holding the caustic")
ap.add_argument("--cols", default="48:80", help="columns of the box holding the caustic")
ap.add_argument("--threshold", type=float, default=4.0, help="times the box's median luminance")
ap.add_argument("--skelight", default="target/release/skelight")
ap.add_argument("--reuse", action="store_true", help="analyse the renders already in --out")
a = ap.parse_args()

mi.set_variant("scalar_rgb")
os.makedirs(a.out, exist_ok=True)
names = a.integrators.split(",")
images, spp = {}, {}
previous = {}
csv_path = os.path.join(a.out, "variance.csv")
if a.reuse and os.path.exists(csv_path):
    for line in open(csv_path).read().splitlines()[1:]:
        f = line.split(",")
        previous[f[0]] = [int(f[1]), int(f[2])]
for name in names:
    for seed in (1, 2):
        path = os.path.join(a.out, f"{name}_seed{seed}.exr")
        if a.reuse and os.path.exists(path):
            spp.setdefault(name, []).append(previous.get(name, [-1, -1])[seed - 1])
        else:
            cmd = [a.skelight, "render", a.scene, "-i", name, "--time", f"{a.time:g}", "--seed", str(seed), "-o", path]
            cmd += [arg for kv in a.D for arg in ("-D", kv)]
            run = subprocess.run(cmd, capture_output=True, text=True)
            if run.returncode != 0:
                sys.exit(f"{' '.join(cmd)} failed:\n{run.stderr}")
            done = re.search(r"done: (\d+) spp", run.stdout + run.stderr)
            spp.setdefault(name, []).append(int(done.group(1)) if done else -1)
        images.setdefault(name, []).append(np.array(mi.Bitmap(path), dtype=np.float64)[:, :, :3])
        print(f"{name} seed {seed}: {spp[name][-1]} spp in {a.time:g} s", flush=True)


def luminance(img):
    return img @ np.array([0.2126, 0.7152, 0.0722])


# The per-pixel median of all renders: a firefly in one render neither pulls a pixel into
# the region nor keeps one out, so the region does not favour the estimator without them.
median_image = luminance(np.median([img for imgs in images.values() for img in imgs], axis=0))
r0, r1 = (int(x) for x in a.rows.split(":"))
c0, c1 = (int(x) for x in a.cols.split(":"))
box = np.zeros_like(median_image, dtype=bool)
box[r0:r1, c0:c1] = True
caustic = box & (median_image > a.threshold * np.median(median_image[box]))
print(f"caustic region: {caustic.sum()} pixels of rows {r0}-{r1 - 1}, columns {c0}-{c1 - 1}; "
      f"median-image luminance {median_image[caustic].mean():.4g} (box median {np.median(median_image[box]):.4g})")

lines = ["integrator,spp_seed1,spp_seed2,variance_caustic,variance_image,mean_caustic"]
results = {}
for name in names:
    a_img, b_img = (luminance(x) for x in images[name])
    half_sq = (a_img - b_img) ** 2 / 2.0
    results[name] = (half_sq[caustic].mean(), half_sq.mean())
    m = ((a_img + b_img) / 2.0)[caustic].mean()
    lines.append(f"{name},{spp[name][0]},{spp[name][1]},{results[name][0]:.6e},{results[name][1]:.6e},{m:.6e}")
with open(os.path.join(a.out, "variance.csv"), "w") as f:
    f.write("\n".join(lines) + "\n")
print("\n".join(lines))
base = names[0]
for name in names[1:]:
    c = results[base][0] / results[name][0]
    w = results[base][1] / results[name][1]
    print(f"equal time, {base} variance / {name} variance: caustic {c:.2f}x, whole image {w:.2f}x")
