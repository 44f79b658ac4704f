#!/usr/bin/env python3
"""Time-to-error speed-ups from a `skelight compare` report's errors.csv, for several metrics.

usage: bench/speedups.py DIR [METRIC…]   (metrics: columns of errors.csv; default rmse relmse)

For each metric, the target is the first estimator's final error; each estimator's time to
reach it is interpolated log-log between its measurements ("-" if never reached), and the
speed-up is the first estimator's time over that. MSE speed-ups equal RMSE ones (same target).
"""
import csv
import math
import sys


def time_to(points, metric, target):
    prev = None
    for p in points:
        e, t = float(p[metric]), float(p["seconds"])
        if e <= target:
            if prev is None or prev[0] <= 0 or e <= 0:
                return t
            (e0, t0) = prev
            f = (math.log(target) - math.log(e0)) / (math.log(e) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t) - math.log(t0)))
        prev = (e, t)
    return None


def main():
    folder = sys.argv[1]
    metrics = sys.argv[2:] or ["rmse", "relmse"]
    series = {}
    with open(f"{folder}/errors.csv") as f:
        for row in csv.DictReader(f):
            series.setdefault(row["integrator"], []).append(row)
    names = list(series)
    for metric in metrics:
        base = series[names[0]]
        target = float(base[-1][metric])
        t_base = time_to(base, metric, target)
        print(f"{metric}: target {target:.4e} ({names[0]}'s final)")
        for n in names:
            t = time_to(series[n], metric, target)
            final = float(series[n][-1][metric])
            speed = f"{t_base / t:.2f}x" if t else "-"
            print(f"  {n:28} final {final:.4e}  time to target {t if t is None else round(t, 1)!s:>6} s  speed-up {speed}")


if __name__ == "__main__":
    main()
