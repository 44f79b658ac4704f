#!/usr/bin/env python3
"""Mitsuba 3 path-tracing throughput on a scene, for `skelight bench render` to be compared with.

Usage: bench/mitsuba_pt.py SCENE.xml --spp N --max-depth D [--variant llvm_ad_rgb] [-D name=value ...]
Needs `pip install mitsuba numpy` (and Debian's libllvm19 for the llvm variant). The first render
compiles kernels, so the time of a second, identical render is reported.
"""
import argparse
import time

import mitsuba as mi

ap = argparse.ArgumentParser()
ap.add_argument("scene")
ap.add_argument("--spp", type=int, default=16)
ap.add_argument("--max-depth", type=int, default=8)
ap.add_argument("--variant", default="llvm_ad_rgb")
ap.add_argument("-D", action="append", default=[], help="name=value scene parameter")
a = ap.parse_args()

mi.set_variant(a.variant)
scene = mi.load_file(a.scene, **dict(kv.split("=", 1) for kv in a.D))
integrator = mi.load_dict({"type": "path", "max_depth": a.max_depth})
size = scene.sensors()[0].film().size()
mi.render(scene, integrator=integrator, spp=a.spp, seed=0)  # warm-up: JIT compilation
t = time.time()
img = mi.render(scene, integrator=integrator, spp=a.spp, seed=1)
import drjit as dr
dr.eval(img)
dr.sync_thread()
dt = time.time() - t
samples = a.spp * size[0] * size[1]
mean = [float(x) for x in mi.TensorXf(img).numpy().reshape(-1, 3).mean(0)]
print(f"mitsuba {a.variant}: {size[0]}×{size[1]} {a.spp} spp, max depth {a.max_depth}, "
      f"{dt:.3f} s, {samples / dt / 1e6:.3f} Msamples/s, mean {mean}")
