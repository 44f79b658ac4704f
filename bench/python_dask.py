"""Python and Dask benchmarks (issue 34): run with `scripts/python.sh python bench/python_dask.py`.

1. Overhead of the Python call against the CLI on a small render: the same job (c01,
   64×48, pt, 16 spp) as a `skelight render` process and as `skelight.render()`, timed
   alternately; also the whole `python -c` process.
2. Scaling of a sharded render on a Dask LocalCluster with 1 and 2 single-threaded workers
   (this machine has 2 cores), against one in-process render with 1 and 2 threads.
3. Per-shard overhead: many 1-spp shards of a tiny image, so that the time per shard is
   the cost of a task (submit, scene load, render set-up, pickling the film, merge), for
   c01 (36 triangles) and veach-door (scene load included).

Prints a Markdown summary; numbers go to docs/benchmarks.md.
"""

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import skelight
import skelight.dask

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
C01 = SHARED / "conformance" / "scenes" / "c01_cbox_area.xml"
DOOR = SHARED / "scenes" / "veach-door" / "scene.xml"
CLI = ROOT / "target" / "release" / "skelight"


def timed(f):
    t = time.perf_counter()
    out = f()
    return time.perf_counter() - t, out


def overhead(rounds=7):
    args = [str(CLI), "render", str(C01), "--spp", "16", "--resolution", "64", "48", "-o", "/tmp/skl-bench.exr", "-q"]
    code = (
        "import skelight; s = skelight.load_file(%r); s.set_resolution(64, 48); "
        "skelight.render(s, spp=16).save('/tmp/skl-bench-py.exr')" % str(C01)
    )
    cli, py_call, py_proc = [], [], []
    for _ in range(rounds):
        cli.append(timed(lambda: subprocess.run(args, check=True, capture_output=True))[0])
        scene = skelight.load_file(C01)
        scene.set_resolution(64, 48)
        py_call.append(timed(lambda: skelight.render(scene, spp=16))[0])
        py_proc.append(timed(lambda: subprocess.run([sys.executable, "-c", code], check=True))[0])
    med = statistics.median
    print("## Python call against the CLI (c01 64×48, pt, 16 spp; median of %d, alternated)" % rounds)
    print(f"- `skelight render` process: {med(cli)*1e3:.1f} ms (range {min(cli)*1e3:.1f}–{max(cli)*1e3:.1f})")
    print(f"- `skelight.render()` call, scene loaded: {med(py_call)*1e3:.1f} ms (range {min(py_call)*1e3:.1f}–{max(py_call)*1e3:.1f})")
    print(f"- `python -c 'import skelight; load; render; save'`: {med(py_proc)*1e3:.1f} ms (range {min(py_proc)*1e3:.1f}–{max(py_proc)*1e3:.1f})")


def cluster(workers):
    from dask.distributed import Client, LocalCluster

    c = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None)
    return c, Client(c)


def scaling(spp=256, shards=8, size=(192, 192)):
    scene = skelight.load_file(C01)
    scene.set_resolution(*size)
    print(f"\n## Sharded render: c01 {size[0]}×{size[1]}, pt, {spp} spp in {shards} shards")
    inproc = {}
    for threads in (1, 2):
        inproc[threads] = timed(lambda: skelight.render(scene, spp=spp, threads=threads))[0]
        print(f"- in process, {threads} thread(s): {inproc[threads]:.2f} s")
    for workers in (1, 2):
        c, client = cluster(workers)
        try:
            client.submit(lambda: None).result()  # workers up
            # Distinct seeds: Dask would hand back a finished shard of the same job.
            runs = [timed(lambda: skelight.dask.render(str(C01), client, spp=spp, shards=shards, resolution=size, threads=1,
                                                       seed=seed))[0]
                    for seed in range(2)]
            print(f"- Dask, {workers} worker(s) × 1 thread: {min(runs):.2f} s (runs {', '.join(f'{r:.2f}' for r in runs)}); "
                  f"{inproc[1] / min(runs):.2f}× the 1-thread in-process render")
        finally:
            client.close()
            c.close()


def per_shard(scene_path, label, shards=32):
    c, client = cluster(1)
    try:
        client.submit(lambda: None).result()
        # Tiny shards: 16×16 pixels, 1 spp each; their render time is negligible.
        runs = [timed(lambda: skelight.dask.render(str(scene_path), client, spp=shards, shards=shards, resolution=(16, 16),
                                                   threads=1, seed=seed))[0]
                for seed in range(2)]
        load = timed(lambda: skelight.load_file(scene_path))[0]
        print(f"- {label}: {min(runs) / shards * 1e3:.1f} ms per shard ({shards} shards of 1 spp at 16×16 on 1 worker; "
              f"loading the scene takes {load*1e3:.1f} ms of it)")
    finally:
        client.close()
        c.close()


if __name__ == "__main__":
    if not CLI.exists():
        sys.exit(f"{CLI} missing: cargo build --release -p skelight-cli")
    print(f"machine: {os.cpu_count()} cores; skelight {skelight.__version__}\n")
    overhead()
    scaling()
    print("\n## Per-shard overhead (task submit, scene load, set-up, film pickled and merged)")
    per_shard(C01, "c01")
    per_shard(DOOR, "veach-door")
