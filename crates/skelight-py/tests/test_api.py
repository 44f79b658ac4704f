"""The Python API against the CLI: same images for the same seed, errors as exceptions,
shards that merge into the single render."""

import _thread
import pickle
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import skelight


def small(path, w=64, h=48):
    scene = skelight.load_file(path)
    scene.set_resolution(w, h)
    return scene


def test_scene_info(c01):
    scene = skelight.load_file(c01)
    info = scene.info()
    assert (info["width"], info["height"], info["lights"]) == (128, 128, 1)
    assert info["triangles"] == scene.triangles > 0
    assert info["camera"]["fov_x"] == pytest.approx(40.0, abs=1e-3)
    assert "c01_cbox_area" in repr(scene)


def test_render_matches_cli_bit_for_bit(c01, cli, tmp_path):
    """The same job through the CLI and through Python: identical float32 images."""
    for integrator in ["pt", "bpt"]:
        out = tmp_path / f"{integrator}.exr"
        subprocess.run(
            [cli, "render", c01, "-i", integrator, "--spp", "8", "--seed", "5", "--resolution", "64", "48", "-o", out, "-q"],
            check=True,
            capture_output=True,
        )
        r = skelight.render(small(c01), integrator=integrator, spp=8, seed=5)
        ours = np.asarray(r)
        assert ours.shape == (48, 64, 3) and ours.dtype == np.float32
        assert r.spp == 8 and r.shard is None
        assert np.array_equal(ours, skelight.load_image(out)), integrator
        assert np.isfinite(r.variance).all() and r.variance.mean() > 0


def test_shards_merge_into_the_single_render(c01, cli, tmp_path):
    """4 shards, merged in any order, in Python and by `skelight merge`, give the single
    render: f64 sums added in another order, so equal within one float32 rounding (in
    practice bit-identical)."""
    scene = small(c01)
    single = np.asarray(skelight.render(scene, integrator="bpt", spp=10, seed=2))
    parts = [skelight.render(scene, integrator="bpt", spp=10, seed=2, shard=(k, 4)) for k in range(4)]
    assert [p.samples for p in parts] == [(0, 2), (2, 5), (5, 7), (7, 10)]
    parts = [pickle.loads(pickle.dumps(p)) for p in parts]  # as Dask moves them
    merged = skelight.merge([parts[2], parts[0], parts[3], parts[1]])
    assert merged.spp == 10
    np.testing.assert_allclose(np.asarray(merged), single, rtol=2e-7, atol=0)
    assert (np.asarray(merged) == single).mean() > 0.99
    # The CLI's shards and merge agree with Python's render.
    files = []
    for k in range(4):
        files.append(tmp_path / f"s{k}.exr")
        subprocess.run(
            [cli, "render", c01, "-i", "bpt", "--spp", "10", "--seed", "2", "--resolution", "64", "48",
             "--shard", f"{k}/4", "-o", files[-1], "-q"],
            check=True,
            capture_output=True,
        )
    subprocess.run([cli, "merge", *files, "-o", tmp_path / "m.exr"], check=True, capture_output=True)
    np.testing.assert_allclose(skelight.load_image(tmp_path / "m.exr"), single, rtol=2e-7, atol=0)
    assert np.array_equal(np.asarray(skelight.merge([str(f) for f in files])), skelight.load_image(tmp_path / "m.exr"))


def test_merge_refuses_missing_duplicate_and_foreign_shards(c01):
    scene = small(c01, 16, 16)
    parts = [skelight.render(scene, spp=4, seed=1, shard=(k, 3)) for k in range(3)]
    with pytest.raises(skelight.SkelightError, match=r"shards \[1\] of 3 are missing"):
        skelight.merge([parts[0], parts[2]])
    with pytest.raises(skelight.SkelightError, match="both shard 2/3"):
        skelight.merge(parts + [parts[2]])
    other = skelight.render(scene, spp=4, seed=9, shard=(1, 3))
    with pytest.raises(skelight.SkelightError, match="not a shard of"):
        skelight.merge([parts[0], other, parts[2]])


def test_shard_keys_tell_renders_apart(c01):
    """The key holds the scene's content and every parameter that changes the image: shards
    of bpt with the power heuristic do not merge with the balance heuristic's, nor shards
    of a scene whose colours a define changed; copies at other paths still merge."""
    scene = small(c01, 16, 16)
    a = [skelight.render(scene, integrator="bpt", spp=4, shard=(k, 2)) for k in range(2)]
    b = skelight.render(scene, integrator="bpt", spp=4, shard=(1, 2), params={"heuristic": "power"})
    with pytest.raises(skelight.SkelightError, match="not a shard of"):
        skelight.merge([a[0], b])
    assert a[0].key == skelight.render_key(scene, integrator="bpt", spp=4, shard=(0, 2))
    other = small(c01, 16, 16)
    other.max_depth = 3
    c = skelight.render(other, integrator="bpt", spp=4, shard=(1, 2))
    with pytest.raises(skelight.SkelightError, match="not a shard of"):
        skelight.merge([a[0], c])


def test_gpu_device_shards_and_time_budget(c01, gpu_render):
    """device="gpu": its shards merge into its single render (float32 sums on the device,
    grouped otherwise: within 1e-5), its key names the device so a CPU shard never joins
    them, and a time budget renders whole batches from sample 0."""
    scene = small(c01, 24, 24)
    whole = gpu_render(scene, integrator="ibpt", spp=6, seed=2)
    parts = [gpu_render(scene, integrator="ibpt", spp=6, seed=2, shard=(k, 3)) for k in range(3)]
    np.testing.assert_allclose(np.asarray(skelight.merge(parts)), np.asarray(whole), rtol=1e-5, atol=1e-7)
    assert parts[0].key == skelight.render_key(scene, integrator="ibpt", spp=6, seed=2, shard=(0, 3), device="gpu")
    assert parts[0].key.endswith("|device gpu")
    cpu = skelight.render(scene, integrator="ibpt", spp=6, seed=2, shard=(2, 3))
    with pytest.raises(skelight.SkelightError, match="not a shard of"):
        skelight.merge([parts[0], parts[1], cpu])
    timed = gpu_render(scene, integrator="pt", seed=2, time=0.5)
    counted = gpu_render(scene, integrator="pt", seed=2, spp=timed.spp)
    np.testing.assert_allclose(np.asarray(timed), np.asarray(counted), rtol=1e-5, atol=1e-7)
    curves = skelight.compare(scene, np.asarray(whole), ["gpu:ibpt", "pt"], time=0.3, seed=2)
    assert list(curves) == ["gpu:ibpt", "pt"]
    final = gpu_render(scene, integrator="ibpt", seed=2, spp=int(curves["gpu:ibpt"]["spp"][-1]))
    np.testing.assert_allclose(curves["gpu:ibpt"]["image"], np.asarray(final), rtol=1e-5, atol=1e-7)
    with pytest.raises(skelight.SkelightError, match="the GPU renders pt, ibpt, lt, not bpt"):
        skelight.render(scene, integrator="bpt", spp=1, device="gpu")
    with pytest.raises(skelight.SkelightError, match="pt has no parameter 'rr_depth'"):
        skelight.render(scene, integrator="pt", spp=1, device="gpu", params={"rr_depth": 3})
    with pytest.raises(skelight.SkelightError, match="give 'cpu' or 'gpu'"):
        skelight.render(scene, spp=1, device="tpu")


def test_learning_estimators_refuse_shards(c01):
    """skelbpt and adaptive skelpt learn from earlier passes, which a shard never sees."""
    scene = small(c01, 16, 16)
    for integrator, params in [("skelbpt", {}), ("skelpt", {})]:
        with pytest.raises(skelight.SkelightError, match="learns from its earlier passes"):
            skelight.render(scene, integrator=integrator, spp=4, shard=(0, 2), params=params)
    parts = [skelight.render(scene, integrator="skelpt", spp=4, shard=(k, 2), params={"adaptive": False})
             for k in range(2)]
    whole = skelight.render(scene, integrator="skelpt", spp=4, params={"adaptive": False})
    np.testing.assert_allclose(np.asarray(skelight.merge(parts)), np.asarray(whole), rtol=2e-7, atol=0)


def test_scene_changes_refused_while_rendering(c01):
    """Changing the scene from a progress callback would deadlock; it raises instead."""
    scene = small(c01, 32, 32)

    def resize(p):
        scene.set_resolution(8, 8)

    with pytest.raises(skelight.SkelightError, match="being rendered"):
        skelight.render(scene, spp=64, progress=resize)
    scene.set_resolution(8, 8)
    assert scene.width == 8


def test_errors_are_exceptions_naming_the_file(tmp_path, c01):
    with pytest.raises(skelight.LoadError, match="missing.xml"):
        skelight.load_file(tmp_path / "missing.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text('<scene version="3.0.0">\n  <shape type="obj">\n    <string name="filename" value="nope.obj"/>\n  </shape>\n</scene>\n')
    with pytest.raises(skelight.LoadError, match=r"nope\.obj"):
        skelight.load_file(bad)
    broken = tmp_path / "broken.xml"
    broken.write_text('<scene version="3.0.0">\n  <shape type="rectangle">\n</scene>\n')
    with pytest.raises(skelight.LoadError, match=r"broken\.xml:\d+"):
        skelight.load_file(broken)
    scene = small(c01, 16, 16)
    with pytest.raises(skelight.SkelightError, match="unknown estimator 'nope'"):
        skelight.render(scene, integrator="nope", spp=1)
    with pytest.raises(skelight.SkelightError, match="strength"):
        skelight.render(scene, integrator="skelpt", spp=1, params={"strength": -1})
    with pytest.raises(skelight.SkelightError):
        skelight.render(scene, spp=0)
    with pytest.raises(skelight.SkelightError, match="shard"):
        skelight.render(scene, spp=2, shard=(0, 3))
    with pytest.raises(skelight.SkelightError):
        scene.set_resolution(0, 10)


def test_progress_callback_and_its_exception(c01):
    scene = small(c01, 32, 32)
    seen = []
    skelight.render(scene, spp=200, progress=seen.append)
    assert seen and seen[-1]["spp"] == 200 and seen[-1]["target"] == 200
    assert all(a["spp"] < b["spp"] for a, b in zip(seen, seen[1:]))

    def stop(p):
        raise ValueError("enough")

    with pytest.raises(ValueError, match="enough"):
        skelight.render(scene, spp=200, progress=stop)


def test_ctrl_c_stops_a_render(c01):
    """KeyboardInterrupt while the GIL is released: the render stops within a pass."""
    scene = small(c01, 64, 64)
    # A shell starts background jobs with SIGINT ignored, and then Python installs no handler
    # and interrupt_main does nothing: install Python's own for the test.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Timer(0.5, _thread.interrupt_main).start()
        start = time.time()
        with pytest.raises(KeyboardInterrupt):
            skelight.render(scene, time=60.0)
        assert time.time() - start < 10
    finally:
        signal.signal(signal.SIGINT, previous)


def test_skeleton_arrays(c01):
    sk = skelight.load_file(c01).skeleton(resolution=48)
    n = len(sk["nodes"])
    assert sk["nodes"].shape == (n, 3) and sk["radii"].shape == (n,) and n > 0
    assert sk["edges"].ndim == 2 and sk["edges"].shape[1] == 2 and (sk["edges"] < n).all()
    assert sk["mapping"].shape == sk["labels"].shape and sk["mapping"].ndim == 3
    assert max(sk["mapping"].shape) == 48 and sk["mapping"].max() <= n
    assert (sk["radii"] > 0).all() and sk["voxel"] > 0


def test_compare_returns_error_curves(c01):
    scene = small(c01, 32, 32)
    reference = np.asarray(skelight.render(scene, integrator="bpt", spp=256, seed=7))
    curves = skelight.compare(scene, reference, ["pt", "bpt"], time=0.4)
    assert list(curves) == ["pt", "bpt"]
    for c in curves.values():
        assert len(c["seconds"]) == len(c["relmse"]) >= 1
        assert np.all(np.diff(c["spp"]) > 0) and c["image"].shape == (32, 32, 3)
    with pytest.raises(skelight.SkelightError, match="reference"):
        skelight.compare(scene, reference[:8], ["pt"], time=0.1)
    assert "pt" in skelight.compare(scene, reference.astype(np.float64), ["pt"], time=0.1)
    broken = reference.copy()
    broken[3, 4, 1] = np.nan
    with pytest.raises(skelight.SkelightError, match="NaN"):
        skelight.compare(scene, broken, ["pt"], time=0.1)


def test_integrators_listed_with_parameters():
    listed = skelight.integrators()
    assert {"pt", "bpt", "skelpt", "skelbpt", "icbpt"} <= set(listed)
    assert "strength" in listed["skelpt"]["params"]


def test_debug_writes_what_the_estimator_shows(c01, tmp_path):
    """`debug=` is `render --debug`'s twin: bpt's strategy images add up to the render."""
    scene = small(c01, 16, 12)
    scene.max_depth = 3
    out = tmp_path / "dbg"
    full = skelight.render(scene, "bpt", spp=2, seed=3, debug=str(out))
    csv = (out / "strategies.csv").read_text().splitlines()
    assert csv[0].startswith("s,t,segments") and len(csv) > 3
    parts = sum(skelight.load_image(p) for p in out.glob("s*_t*.exr"))
    assert np.allclose(parts, np.asarray(full), rtol=1e-4, atol=1e-4)
    with pytest.raises(skelight.SkelightError, match="spp"):
        skelight.render(scene, "bpt", time=0.5, debug=str(out))
