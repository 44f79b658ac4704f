#!/usr/bin/env python3
"""Mitsuba 3 on variants of the two conformance scenes whose references are excused in
crates/skelight/tests/conformance.rs (KNOWN_REFERENCE_DIFFERENCES), showing the behaviour of
Mitsuba that makes each reference differ from the physically correct image.

Usage: bench/mitsuba_reference_differences.py [--shared DIR] [--variant llvm_ad_rgb]
           [--spp-c05 4096] [--spp-c13 2048] [--pass-spp 256] [--seed-base 0]
           [--scenes c05_constant_env,c13_mask_twosided] [--json PATH]
Needs `pip install mitsuba numpy` (and Debian's libllvm19 for llvm_ad_rgb, the variant that made
the references; `--variant scalar_rgb` needs nothing else but is slower).

c05_constant_env: Mitsuba's constant emitter tests its shadow rays only up to twice the radius of
  the scene's bounding sphere. When the loader merges the scene's shapes (load_file's default
  optimize=True), the merged bounding box leaves out the `rectangle` floor, so the radius is that
  of the cube and sphere alone, and shadow rays that would meet the floor far away see the sky.
  Variants: the original; the floor as an OBJ quad with the same transform (a mesh, which the
  bounding box then includes); the original loaded with optimize=False (no merging). The two
  variants should agree with each other and be darker than the original on the cube and sphere.
c13_mask_twosided: Mitsuba's path tracer counts passing through a mask's transparent part as a
  bounce towards max_depth. Variants: the original at max_depth 8 (as the reference) and 64; and
  to isolate the mask, the leaf made fully transparent (opacity 0) against the leaf removed,
  at max_depth 8 (they differ: each pass through the leaf costs a bounce) and 64 (they agree).

Each variant is an edit of the conformance XML in memory, written into a temporary folder next to
copies of the files it references. Renders keep the scene's resolution (128 x 128, box filter),
so that image means compare with the reference means in refs/manifest.json. Each variant renders
spp = passes x pass-spp samples per pixel as `passes` renders with seeds seed-base + 0, 1, ...,
the same seeds for every variant of a scene. Standard errors: the box filter puts each sample in
one pixel and every pixel draws its own random numbers, so pixels are independent and the
variance of an image (or region) mean is the sum of the per-pixel variances over N^2; each
pixel's variance is estimated from the spread of its `passes` renders. A change between two
variants is the mean of the per-pass, per-pixel differences (same seeds, so shared paths cancel)
with its SE from the spread of those differences. The SE from the spread of the passes' image
means (fewer degrees of freedom) is written to the JSON too, as a check.
"""
import argparse
import json
import os
import platform
import re
import shutil
import sys
import tempfile
import time

import mitsuba as mi
import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
ap.add_argument("--shared", default=os.path.join(REPO, "..", "shared"),
                help="shared data folder holding conformance/scenes and conformance/refs")
ap.add_argument("--variant", default="llvm_ad_rgb", help="Mitsuba variant (or scalar_rgb)")
ap.add_argument("--spp-c05", type=int, default=4096, help="samples per pixel per c05 variant")
ap.add_argument("--spp-c13", type=int, default=2048, help="samples per pixel per c13 variant")
ap.add_argument("--pass-spp", type=int, default=256, help="samples per pixel of one render")
ap.add_argument("--seed-base", type=int, default=0)
ap.add_argument("--scenes", default="c05_constant_env,c13_mask_twosided")
ap.add_argument("--json", default=os.path.join(REPO, "bench", "mitsuba_reference_differences.json"))
a = ap.parse_args()

t_start = time.perf_counter()
mi.set_variant(a.variant)
import drjit as dr  # noqa: E402  (after set_variant, as Mitsuba wants)

SCENES = os.path.join(a.shared, "conformance", "scenes")
REFS = os.path.join(a.shared, "conformance", "refs")
with open(os.path.join(REFS, "manifest.json")) as f:
    MANIFEST = json.load(f)

# The rectangle is [-1, 1]^2 in the xy plane facing +z, uv (0,0) at (-1,-1): the same as a mesh.
QUAD_OBJ = """# Mitsuba's `rectangle` as a mesh: [-1, 1]^2 in the xy plane, normal +z
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
f 1/1/1 2/2/1 3/3/1
f 1/1/1 3/3/1 4/4/1
"""


def replace_once(text, pattern, repl, flags=0):
    out, n = re.subn(pattern, repl, text, flags=flags)
    if n != 1:
        sys.exit(f"scene edit expected one match of {pattern!r}, found {n}: has the scene changed?")
    return out


def c05_floor_as_obj(xml):
    # The floor is the only `rectangle`; keep its transform and BSDF, swap the shape for a mesh.
    return replace_once(xml, r'<shape type="rectangle">',
                        '<shape type="obj"><string name="filename" value="floor_quad.obj"/>')


def c13_leaf_transparent(xml):
    return replace_once(xml, r'<texture name="opacity" type="bitmap">.*?</texture>',
                        '<float name="opacity" value="0"/>', re.S)


def c13_leaf_removed(xml):
    return replace_once(xml, r'<shape type="rectangle">(?:(?!</shape>).)*type="mask".*?</shape>',
                        "", re.S)


def identity(xml):
    return xml


# (variant name, XML edit, load_file's optimize, max_depth or None for the scene's own)
VARIANTS = {
    "c05_constant_env": [
        ("original", identity, True, None),
        ("floor as OBJ quad", c05_floor_as_obj, True, None),
        ("original, optimize=False", identity, False, None),
    ],
    "c13_mask_twosided": [
        ("original, max_depth 8", identity, True, None),
        ("original, max_depth 64", identity, True, 64),
        ("leaf transparent, max_depth 8", c13_leaf_transparent, True, None),
        ("leaf removed, max_depth 8", c13_leaf_removed, True, None),
        ("leaf transparent, max_depth 64", c13_leaf_transparent, True, 64),
        ("leaf removed, max_depth 64", c13_leaf_removed, True, 64),
    ],
}
# (label, variant A, variant B): changes B - A, paired by seed.
CHANGES = {
    "c05_constant_env": [
        ("floor as mesh - original", "original", "floor as OBJ quad"),
        ("optimize=False - original", "original", "original, optimize=False"),
    ],
    "c13_mask_twosided": [
        ("max_depth 64 - 8 (original)", "original, max_depth 8", "original, max_depth 64"),
        ("removed - transparent leaf, depth 8", "leaf transparent, max_depth 8",
         "leaf removed, max_depth 8"),
        ("removed - transparent leaf, depth 64", "leaf transparent, max_depth 64",
         "leaf removed, max_depth 64"),
    ],
}


def load_variant(scene_name, edit, optimize, tmp):
    xml = edit(open(os.path.join(SCENES, scene_name + ".xml")).read())
    folder = os.path.join(tmp, scene_name)
    os.makedirs(folder, exist_ok=True)
    for ref in set(re.findall(r'<string name="filename" value="([^"]+)"', xml)):
        src = os.path.join(SCENES, ref)
        if os.path.exists(src):
            shutil.copy(src, folder)
    with open(os.path.join(folder, "floor_quad.obj"), "w") as f:
        f.write(QUAD_OBJ)
    path = os.path.join(folder, "variant.xml")
    with open(path, "w") as f:
        f.write(xml)
    return mi.load_file(path, optimize=optimize)


def scene_max_depth(scene_name):
    xml = open(os.path.join(SCENES, scene_name + ".xml")).read()
    return int(re.search(r'<integer name="max_depth" value="(\d+)"', xml).group(1))


def render_passes(scene, max_depth, spp, seeds):
    integrator = mi.load_dict({"type": "path", "max_depth": max_depth})
    out = []
    for s in seeds:
        img = mi.render(scene, integrator=integrator, spp=spp, seed=s)
        out.append(np.array(img, dtype=np.float64)[..., :3])
    return np.stack(out)  # passes x H x W x 3


def region_masks(scene):
    """Pixels whose centre sees the cube or sphere, the floor (y = -1), or nothing (sky)."""
    sensor = scene.sensors()[0]
    w, h = (int(v) for v in sensor.film().size())
    if dr.is_jit_v(mi.Float):
        idx = dr.arange(mi.UInt32, w * h)
        pos = mi.Point2f((mi.Float(idx % w) + 0.5) / w, (mi.Float(idx // w) + 0.5) / h)
        ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5))
        si = scene.ray_intersect(ray)
        valid = np.array(si.is_valid()).reshape(h, w)
        y = np.array(si.p.y).reshape(h, w)
    else:
        valid = np.zeros((h, w), bool)
        y = np.zeros((h, w))
        for j in range(h):
            for i in range(w):
                ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f((i + 0.5) / w, (j + 0.5) / h),
                                           mi.Point2f(0.5))
                si = scene.ray_intersect(ray)
                valid[j, i] = bool(si.is_valid())
                y[j, i] = si.p.y
    floor = valid & (y < -1 + 1e-3)
    return {"cube and sphere": valid & ~floor, "floor": floor, "sky": ~valid}


def stats(passes, mask=None):
    """Mean RGB over the pixels (all, or mask) and its SE, from a passes x H x W x 3 stack."""
    x = passes if mask is None else passes[:, mask]
    x = x.reshape(x.shape[0], -1, 3)
    p, n = x.shape[0], x.shape[1]
    mean = x.mean((0, 1))
    se_pixels = np.sqrt(x.var(0, ddof=1).sum(0) / p) / n
    se_passes = x.mean(1).std(0, ddof=1) / np.sqrt(p)
    return mean, se_pixels, se_passes


def fmt(v, se=None, digits=5):
    if se is None:
        return "(" + ", ".join(f"{x:.{digits}f}" for x in v) + ")"
    return "(" + ", ".join(f"{x:.{digits}f}±{e:.{digits}f}" for x, e in zip(v, se)) + ")"


def reference_image(scene_name):
    return np.array(mi.Bitmap(os.path.join(REFS, scene_name + ".exr")), dtype=np.float64)[..., :3]


results = {
    "script": "bench/mitsuba_reference_differences.py",
    "command": " ".join(["python3"] + sys.argv),
    "mitsuba_version": mi.__version__,
    "drjit_version": dr.__version__,
    "variant": a.variant,
    "integrator": "path",
    "python": platform.python_version(),
    "machine": f"{platform.machine()}, {os.cpu_count()} logical CPUs",
    "pass_spp": a.pass_spp,
    "se_method": "per-pixel variance across passes (independent pixels), summed; "
                 "se_between_passes: spread of the passes' image means",
    "scenes": {},
}

names = [s for s in a.scenes.split(",") if s]
rows, change_rows, region_rows, notes = [], [], [], []
with tempfile.TemporaryDirectory(prefix="mitsuba-refdiff-") as tmp:
    for name in names:
        spp = a.spp_c05 if name.startswith("c05") else a.spp_c13
        npass = max(2, spp // a.pass_spp)
        seeds = [a.seed_base + i for i in range(npass)]
        ref = MANIFEST[name]
        ref_img = reference_image(name)
        default_depth = scene_max_depth(name)
        res = {"reference": {"mean": ref["mean"], "spp": ref["spp"], "renderer": ref["renderer"]},
               "spp": npass * a.pass_spp, "passes": npass, "seeds": seeds, "variants": {},
               "changes": {}}
        imgs, masks = {}, None
        for vname, edit, optimize, depth in VARIANTS[name]:
            t = time.perf_counter()
            scene = load_variant(name, edit, optimize, tmp)
            depth = depth or default_depth
            w, h = (int(v) for v in scene.sensors()[0].film().size())
            bs = scene.bbox().bounding_sphere()
            imgs[vname] = render_passes(scene, depth, a.pass_spp, seeds)
            if name.startswith("c05") and masks is None:
                masks = region_masks(scene)
            mean, se, se_passes = stats(imgs[vname])
            dt = time.perf_counter() - t
            entry = {"edit": edit.__name__, "load_optimize": optimize, "max_depth": depth,
                     "resolution": [w, h], "bounding_sphere_radius": float(bs.radius),
                     "mean": mean.tolist(), "se": se.tolist(), "se_between_passes": se_passes.tolist(),
                     "seconds": round(dt, 1)}
            ztext = ""
            if edit is identity and optimize and depth == default_depth:
                # The reference's configuration. Its own noise, scaled from ours by the sample
                # counts, counts in the comparison.
                se_ref = se * np.sqrt(res["spp"] / ref["spp"])
                z = (mean - np.array(ref["mean"])) / np.sqrt(se**2 + se_ref**2)
                entry["z_vs_reference"] = z.tolist()
                ztext = " ".join(f"{v:+.1f}" for v in z)
            rows.append((name, vname, depth, bs.radius, fmt(mean, se), fmt(ref["mean"]),
                         ztext, dt))
            if masks is not None:
                entry["regions"] = {}
                for rname, m in masks.items():
                    rm, rse, _ = stats(imgs[vname], m)
                    entry["regions"][rname] = {"pixels": int(m.sum()), "mean": rm.tolist(),
                                               "se": rse.tolist()}
            res["variants"][vname] = entry
            print(f"  {name} / {vname}: {dt:.1f} s", file=sys.stderr, flush=True)
        if masks is not None:
            res["reference"]["regions"] = {
                r: {"pixels": int(m.sum()), "mean": ref_img[m].mean(0).tolist()}
                for r, m in masks.items()}
            for rname, m in masks.items():
                for vname in imgs:
                    v = res["variants"][vname]["regions"][rname]
                    region_rows.append((name, rname, int(m.sum()), vname, fmt(v["mean"], v["se"])))
                region_rows.append((name, rname, int(m.sum()), "reference (manifest spp)",
                                    fmt(res["reference"]["regions"][rname]["mean"])))
        for label, va, vb in CHANGES[name]:
            d = imgs[vb] - imgs[va]
            parts = {"image": None}
            if masks is not None:
                parts.update((k, m) for k, m in masks.items() if k != "sky")
            res["changes"][label] = {}
            for part, m in parts.items():
                dm, dse, dse_p = stats(d, m)
                base, _, _ = stats(imgs[va], m)
                rel = 100 * dm / base
                res["changes"][label][part] = {
                    "from": va, "to": vb, "delta": dm.tolist(), "se": dse.tolist(),
                    "se_between_passes": dse_p.tolist(), "relative_percent": rel.tolist(),
                    "delta_over_se": (dm / dse).tolist()}
                change_rows.append((name, label, part, fmt(dm, dse, 6),
                                    " ".join(f"{r:+.3f}" for r in rel),
                                    " ".join(f"{v:+.0f}" for v in dm / dse)))
        if name.startswith("c05"):
            diff = imgs["original, optimize=False"] - imgs["floor as OBJ quad"]
            res["optimize_false_minus_floor_as_mesh"] = {
                "max_abs_pixel": float(np.abs(diff).max()), "mean": diff.mean((0, 1, 2)).tolist()}
            notes.append(f"{name}: 'original, optimize=False' - 'floor as OBJ quad', seed for "
                         f"seed: largest pixel difference {np.abs(diff).max():.1e}, image mean "
                         f"{fmt(diff.mean((0, 1, 2)), digits=8)}")
        results["scenes"][name] = res

wall = time.perf_counter() - t_start
results["wall_seconds"] = round(wall, 1)

print(f"Mitsuba {mi.__version__} {a.variant}, path integrator; {os.cpu_count()} CPUs; "
      f"SE = one standard error")
for name in names:
    r = results["scenes"][name]
    print(f"{name}: {r['spp']} spp per variant = {r['passes']} passes x {a.pass_spp} spp, "
          f"seeds {r['seeds'][0]}..{r['seeds'][-1]}; reference: {r['reference']['spp']} spp")
print()
print(f"{'scene':18} {'variant':31} {'depth':>5} {'bsph r':>6}  {'Mitsuba mean RGB ± SE':50} "
      f"{'reference mean (manifest)':27} {'z vs ref':>16} {'s':>5}")
print("(z vs ref: only for the reference's own configuration; bsph r: radius of "
      "scene.bbox().bounding_sphere())")
for n, v, d, r, m, ref, z, dt in rows:
    print(f"{n:18} {v:31} {d:5} {r:6.3f}  {m:50} {ref:27} {z:>16} {dt:5.0f}")
print()
print(f"{'scene':18} {'change (paired seeds)':37} {'pixels':16} {'Δ mean RGB ± SE':56} "
      f"{'Δ %':>22} {'Δ/SE':>14}")
for n, l, p, dm, rel, z in change_rows:
    print(f"{n:18} {l:37} {p:16} {dm:56} {rel:>22} {z:>14}")
for note in notes:
    print(note)
if region_rows:
    print()
    print(f"{'scene':18} {'region (pixel centres)':16} {'pixels':>6}  {'variant':31} {'mean RGB ± SE'}")
    for n, rname, cnt, v, m in region_rows:
        print(f"{n:18} {rname:16} {cnt:6}  {v:31} {m}")
print()
print(f"wall time {wall:.0f} s; JSON: {a.json}")

with open(a.json, "w") as f:
    json.dump(results, f, indent=1)
    f.write("\n")
