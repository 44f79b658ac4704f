#!/usr/bin/env python3
"""Renders bench/sunsky/scene.xml (a floor, a cube and a rough aluminium ball under Mitsuba
3's `sunsky`, sun from place and time) with Mitsuba 3 (scalar_rgb) and with skelight's pt at
the same sample count, twice each with different seeds, and prints the image means, the mean
absolute difference between the two renderers' averages and each renderer's own noise.
Matching means and a difference no larger than the noise say the emitter is the same.

Usage: bench/sunsky/compare.py [SPP]   (needs `pip install mitsuba`; builds skelight)"""
import os
import subprocess
import sys
import tempfile

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
here = os.path.dirname(os.path.abspath(__file__))
root = os.path.join(here, "..", "..")
scene_file = os.path.join(here, "scene.xml")
spp = int(sys.argv[1]) if len(sys.argv) > 1 else 256

subprocess.run(["cargo", "build", "--release", "-q", "-p", "skelight-cli"], cwd=root, check=True)
target = os.environ.get("CARGO_TARGET_DIR", os.path.join(root, "target"))
out = tempfile.mkdtemp()
scene = mi.load_file(scene_file)
theirs, ours = [], []
for seed in (1, 2):
    theirs.append(np.array(mi.render(scene, spp=spp, seed=seed))[..., :3])
    path = os.path.join(out, f"ours{seed}.exr")
    subprocess.run([os.path.join(target, "release", "skelight"), "render", scene_file, "--spp", str(spp),
                    "--seed", str(seed), "-o", path], check=True, capture_output=True)
    ours.append(np.array(mi.Bitmap(path))[..., :3])
m_theirs, m_ours = (theirs[0] + theirs[1]) / 2, (ours[0] + ours[1]) / 2
print(f"image mean RGB: Mitsuba {m_theirs.reshape(-1, 3).mean(0).round(5)}, skelight {m_ours.reshape(-1, 3).mean(0).round(5)}")
print(f"mean |skelight - Mitsuba| per pixel: {np.abs(m_ours - m_theirs).mean():.5f}")
print(f"noise of each average (|run1 - run2| / 2): Mitsuba {np.abs(theirs[0] - theirs[1]).mean() / 2:.5f}, "
      f"skelight {np.abs(ours[0] - ours[1]).mean() / 2:.5f}")
