"""skelight: a physically based renderer guided by the shape of empty space.

    import skelight, numpy as np
    scene = skelight.load_file("scene.xml", spp=64)   # keyword arguments: Mitsuba's -D
    r = skelight.render(scene, integrator="bpt", spp=64, seed=1)
    img = np.asarray(r)                                 # float32 (H, W, 3), linear RGB
    r.variance, r.spp                                   # per-pixel variance, samples

Shards: ``render(..., shard=(k, n))`` renders a deterministic slice of the samples;
``merge([...])`` gives back the whole render. ``skelight.dask`` runs the shards on a Dask
cluster. See docs/python.md.
"""

from ._skelight import (  # noqa: F401
    LoadError,
    Render,
    Scene,
    SkelightError,
    __version__,
    compare,
    default_scene,
    integrators,
    load_file,
    load_image,
    merge,
    render,
    render_key,
)

__all__ = [
    "LoadError",
    "Render",
    "Scene",
    "SkelightError",
    "compare",
    "default_scene",
    "integrators",
    "load_file",
    "load_image",
    "merge",
    "render",
    "render_key",
]
