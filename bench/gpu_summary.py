#!/usr/bin/env python3
"""Issue 35's device report (`bench/gpu_device.sh measure`'s gpu_device.txt) as the tables the
defaults are chosen from, with the rule that chooses them written down before the figures
exist, so that the choice is the rule's and not the reader's:

    python3 bench/gpu_summary.py gpu_device.txt

Samples/s: for each scene and estimator, every variant (traversal, wavefront) against the
megakernel with the stackless traversal (the defaults today), whose two runs (the `table`
step and the `again` step, four times the samples) give the machine's spread.

The rule (launch.rs's TRAVERSAL and WAVEFRONT constants), for ibpt and for pt apart (the
launch shape can be chosen per estimator: GpuRenderer::open knows which it runs):
- a variant's score is the geometric mean, over the three scenes, of its ratio to the
  default's mean;
- a variant replaces the default when its score is at least 1 + max(5 %, the default's
  largest relative spread over both estimators) and no scene's ratio is below 0.95; among
  several, the highest score. (pt has no light pass: its "wavefront 2" is its "wavefront 1".)
Rays: the traversal alone, closest hit, primary rays on Dabrovic's Sponza against TinyBVH's
published 4-5 Grays/s (Crytek's Sponza, RTX 5080 laptop, binary BVH, no ray-tracing cores):
within 2x means 2.0 Grays/s or more (2.5 against the dev branch's 5).
"""

import math
import re
import sys
from collections import defaultdict

HEADER = re.compile(r"^== (?P<label>.*?) \(t=\d+ s\)$")
RENDER = re.compile(r"^(?P<scene>\S+) (?P<est>pt|ibpt) \(gpu\): .* (?P<rate>[\d.]+) Msamples/s")
RAYS = re.compile(
    r"^(?P<scene>\S+)\s+\d+\s+(?P<rays>incoherent|primary)\s+(?P<traversal>\w+)\s+(?P<closest>[\d.]+)\s+(?P<any>[\d.]+)"
)
DEFAULT = "megakernel, stackless"
MARGIN = 0.05
FLOOR = 0.95
TINYBVH_GRAYS = (4.0, 5.0)


def short(scene):
    """A scene's name from its path (sibenik's configuration, or the folder of scene.xml)."""
    parts = scene.split("/")
    return parts[-2] if parts[-1] in ("scene.xml", "sponza.xml") else parts[-1].split(".")[0]


def variant(label):
    """The launch shape a step's label names, or None for steps that do not time a shape."""
    if label.startswith("traversal "):
        return "megakernel, " + label.split(":")[0].split()[1]
    m = re.match(r"wavefront (\d), (\w+):", label)
    if m:
        return f"wavefront {m.group(1)}, {m.group(2)}"
    if label.startswith(("again:", ".device/")):
        return DEFAULT
    return None


def parse(lines):
    """Msamples/s per (scene, estimator, variant), a list of runs; rays per (scene, kind, traversal)."""
    rates = defaultdict(list)
    rays = {}
    label = None
    for line in lines:
        line = line.rstrip("\n")
        m = HEADER.match(line)
        if m:
            label = m.group("label")
            continue
        if label is None:
            continue
        m = RENDER.match(line)
        if m and variant(label):
            rates[(short(m.group("scene")), m.group("est"), variant(label))].append(float(m.group("rate")))
            continue
        m = RAYS.match(line)
        if m and label.startswith("rays:"):
            key = (short(label.split(": ", 1)[1]), m.group("rays"), m.group("traversal"))
            rays[key] = (float(m.group("closest")), float(m.group("any")))
    return rates, rays


def geomean(xs):
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else float("nan")


def decide(rates):
    """The tables' rows and the rule's choice for each estimator; prints both."""
    scenes = sorted({s for s, _, _ in rates})
    variants = sorted({v for _, _, v in rates if v != DEFAULT})
    spread = 0.0
    for s in scenes:
        for est in ("pt", "ibpt"):
            runs = rates.get((s, est, DEFAULT), [])
            if len(runs) >= 2:
                spread = max(spread, (max(runs) - min(runs)) / (sum(runs) / len(runs)))
    print(f"default ({DEFAULT}): largest spread between its runs {spread * 100:.1f} %")
    threshold = 1 + max(MARGIN, spread)
    print(f"rule: a score of {threshold:.3f} or more, and no scene below {FLOOR}")
    choices = {}
    for est in ("ibpt", "pt"):
        print(f"\n{est}, Msamples/s (ratio to the default's mean)")
        print("variant".ljust(28) + "".join(s.ljust(26) for s in scenes) + "score")
        scores = {}
        for v in [DEFAULT] + variants:
            # pt has no light pass: the light wavefront (2) renders it as the camera's (1).
            measured = v.replace("wavefront 2", "wavefront 1") if est == "pt" else v
            cells, ratios = [], []
            for s in scenes:
                base, runs = rates.get((s, est, DEFAULT)), rates.get((s, est, measured))
                if not runs or not base:
                    cells.append("-".ljust(26))
                    continue
                ratio = (sum(runs) / len(runs)) / (sum(base) / len(base))
                ratios.append(ratio)
                shown = "/".join(f"{r:.4g}" for r in runs)
                cells.append(f"{shown} ({ratio:.2f}x)".ljust(26))
            if scenes and len(ratios) == len(scenes):
                scores[v] = (geomean(ratios), min(ratios))
            print(v.ljust(28) + "".join(cells) + (f"{scores[v][0]:.3f}" if v in scores else "incomplete"))
        eligible = [v for v in variants if v in scores and scores[v][0] >= threshold and scores[v][1] >= FLOOR]
        choices[est] = max(eligible, key=lambda v: scores[v][0]) if eligible else DEFAULT
        kept = "" if eligible else " (no variant passes the rule)"
        print(f"choice for {est}: {choices[est]}{kept}")
    return choices


def report_rays(rays):
    if not rays:
        return
    print("\nthe traversal alone, closest / any hit, Mrays/s")
    for (scene, kind, traversal), (closest, any_hit) in sorted(rays.items()):
        print(f"  {scene:22} {kind:10} {traversal:9} {closest:8.1f} / {any_hit:8.1f}")
    primary = {t: c for (s, k, t), (c, _) in rays.items() if s == "sponza-dabrovic" and k == "primary"}
    if primary:
        best = max(primary, key=primary.get)
        grays = primary[best] / 1000
        lo, hi = TINYBVH_GRAYS
        verdict = "within 2x of both" if grays >= hi / 2 else "within 2x of 4 only" if grays >= lo / 2 else "outside 2x"
        print(
            f"primary rays on Dabrovic's Sponza, best traversal ({best}): {grays:.3g} Grays/s against "
            f"TinyBVH's {lo:.0f}-{hi:.0f} (Crytek's Sponza): {verdict}"
        )


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    try:
        with open(sys.argv[1], encoding="utf-8") as f:
            lines = f.readlines()
    except OSError as e:
        sys.exit(f"{sys.argv[1]}: {e.strerror}")
    for line in lines[:3]:
        if "NVIDIA" in line or "llvmpipe" in line:
            print(line.strip())
            break
    rates, rays = parse(lines)
    if not rates:
        sys.exit(f"{sys.argv[1]}: no `bench render` result in it (not a gpu_device.sh report?)")
    decide(rates)
    report_rays(rays)


if __name__ == "__main__":
    main()
