"""Rendering across machines on Dask.

One render is split into shards (deterministic slices of its sample indices, see
``skelight.render(..., shard=(k, n))``); each shard is a Dask task, and the finished shards
are merged into the whole render, which equals the single render of the same seed and spp
(up to the order of f64 sums; with ``device="gpu"``, up to the device's float32 sums). Dask does the scheduling: a task that raises is retried
(``retries``), and a task on a worker that dies is recomputed on another worker. Results are
keyed by shard index and ``skelight.merge`` refuses a shard given twice, so a shard that
ran twice is never counted twice.

    from dask.distributed import Client
    import skelight.dask
    client = Client("tcp://scheduler:8786")        # or Client(LocalCluster(...))
    r = skelight.dask.render("scenes/door.xml", client, spp=4096, shards=64, integrator="bpt")
    r.save("door.exr")

The scene file must be readable at the same path on every worker (a shared file system),
or ``ship=True`` sends the file's bytes with each task (for self-contained files: the
meshes and textures it names must still be shared). Workers need ``skelight`` installed
(``pip install`` the wheel built by maturin, docs/python.md).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import uuid
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Tuple

import skelight


def _scene_on_worker(scene_path: str, scene_bytes: Optional[bytes]) -> str:
    """The scene's path on this worker: as given, or the shipped bytes written once to a
    temporary folder named by their hash (atomically: temporary name, then rename)."""
    if scene_bytes is None:
        return scene_path
    digest = hashlib.sha256(scene_bytes).hexdigest()[:16]
    folder = Path(tempfile.gettempdir()) / "skelight-scenes" / digest
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / Path(scene_path).name
    if not path.exists():
        # A unique temporary name: several tasks of one worker may write it at once.
        with tempfile.NamedTemporaryFile(dir=folder, prefix=f".{path.name}.", delete=False) as tmp:
            tmp.write(scene_bytes)
        os.replace(tmp.name, path)
    return str(path)


def render_shard(
    scene_path: str,
    index: int,
    count: int,
    spp: int,
    seed: int = 0,
    integrator: str = "pt",
    params: Optional[Dict[str, Any]] = None,
    resolution: Optional[Tuple[int, int]] = None,
    max_depth: Optional[int] = None,
    defines: Optional[Dict[str, Any]] = None,
    threads: int = 0,
    scene_bytes: Optional[bytes] = None,
    device: str = "cpu",
) -> skelight.Render:
    """Renders shard ``index`` of ``count`` (what each Dask task runs) on the worker's CPU or,
    with ``device="gpu"``, its first Vulkan adapter."""
    scene = skelight.load_file(_scene_on_worker(scene_path, scene_bytes), **(defines or {}))
    if resolution is not None:
        scene.set_resolution(*resolution)
    if max_depth is not None:
        scene.max_depth = max_depth
    return skelight.render(
        scene,
        integrator=integrator,
        spp=spp,
        seed=seed,
        params=params,
        shard=(index, count),
        threads=threads,
        device=device,
    )


def _run(
    scene_path: str,
    client: Any,
    spp: int,
    shards: int,
    done: Dict[int, skelight.Render],
    on_result: Optional[Callable[[skelight.Render], None]] = None,
    progress: Optional[Callable[[int, int], None]] = None,
    ship: bool = False,
    retries: int = 2,
    **job: Any,
) -> skelight.Render:
    """Submits the shards not in ``done``, collects them into ``done`` as they finish (keyed
    by shard index: a shard that ran twice is kept once) and merges all of them. Keys are
    unique per call, so a rerun never gets back a failed run's futures; on an error the
    remaining tasks are cancelled."""
    from dask.distributed import as_completed

    if not 1 <= shards <= spp:
        raise skelight.SkelightError(f"shards = {shards}: use 1 to spp ({spp}) shards")
    scene_path = str(scene_path)
    scene_bytes = Path(scene_path).read_bytes() if ship else None
    token = uuid.uuid4().hex
    futures = [
        client.submit(
            render_shard,
            scene_path,
            k,
            shards,
            spp=spp,
            scene_bytes=scene_bytes,
            key=f"skelight-shard-{token}-{k}-of-{shards}",
            retries=retries,
            pure=False,
            **job,
        )
        for k in range(shards)
        if k not in done
    ]
    if progress is not None and done:
        progress(len(done), shards)
    try:
        for _, r in as_completed(futures, with_results=True):
            if on_result is not None:
                on_result(r)
            done[r.shard[0]] = r
            if progress is not None:
                progress(len(done), shards)
    finally:
        client.cancel([f for f in futures if not f.done()])
    return skelight.merge([done[k] for k in range(shards)])


def render(
    scene_path: str,
    client: Any,
    spp: int,
    shards: int,
    seed: int = 0,
    integrator: str = "pt",
    params: Optional[Dict[str, Any]] = None,
    resolution: Optional[Tuple[int, int]] = None,
    max_depth: Optional[int] = None,
    defines: Optional[Dict[str, Any]] = None,
    threads: int = 0,
    ship: bool = False,
    retries: int = 2,
    progress: Optional[Callable[[int, int], None]] = None,
    device: str = "cpu",
) -> skelight.Render:
    """Renders ``scene_path`` with ``spp`` samples per pixel in ``shards`` Dask tasks and
    returns the merged ``skelight.Render``. ``threads`` is each task's thread count (0: all
    the worker's cores; give 1 with several single-threaded workers per machine); ``ship``
    sends the scene file's bytes with each task; ``retries`` is how often Dask reruns a task
    that raised; ``progress(done, shards)`` is called as shards finish. ``device="gpu"``
    renders every shard on its worker's GPU (pt, ibpt or lt; all shards of one render on one
    kind of device, whose random numbers they share)."""
    return _run(scene_path, client, spp, shards, {}, progress=progress, ship=ship, retries=retries, seed=seed,
                integrator=integrator, params=params, resolution=resolution, max_depth=max_depth, defines=defines,
                threads=threads, device=device)


def reference(scene_path: str, client: Any, output: str, spp: int, shards: int, integrator: str = "bpt",
              **options: Any) -> skelight.Render:
    """A long render that survives being stopped: each finished shard is written to
    ``OUTPUT.shards/`` as it arrives, a rerun with the same arguments renders only the
    shards not there yet, and the merge is written to ``output`` (EXR, and a PNG beside
    it). ``options`` are ``render``'s. Remove ``OUTPUT.shards/`` to start afresh;
    ``skelight merge`` also reads the shards."""
    folder = Path(f"{output}.shards")
    folder.mkdir(parents=True, exist_ok=True)
    name = lambda k: folder / f"shard-{k:05d}-of-{shards:05d}.exr"  # noqa: E731
    done = {k: skelight.Render.load(str(name(k))) for k in range(shards) if name(k).exists()}
    if done and Path(scene_path).exists():
        # Shards kept from another render (other defines, parameters, seed) must not count.
        scene = skelight.load_file(scene_path, **(options.get("defines") or {}))
        if options.get("resolution") is not None:
            scene.set_resolution(*options["resolution"])
        if options.get("max_depth") is not None:
            scene.max_depth = options["max_depth"]
        expected = skelight.render_key(scene, integrator=integrator, spp=spp, seed=options.get("seed", 0),
                                       params=options.get("params"), shard=(0, shards),
                                       device=options.get("device", "cpu"))
        stale = [k for k, r in done.items() if r.key != expected]
        if stale:
            raise skelight.SkelightError(
                f"{folder} holds shards of another render ({done[stale[0]].key}, not {expected}); "
                "remove it or choose another output")
    merged = _run(scene_path, client, spp, shards, done, on_result=lambda r: r.save(str(name(r.shard[0]))),
                  integrator=integrator, **options)
    merged.save(str(output))
    return merged
