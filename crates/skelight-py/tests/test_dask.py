"""Rendering on a Dask LocalCluster (2 workers, loopback only): 4 shards merge into the
single render, also when a worker is killed in the middle of the run."""

import os
import signal
import time

import numpy as np
import pytest

import skelight
import skelight.dask

distributed = pytest.importorskip("dask.distributed")

# c01 at 96×96 with pt: about 0.6 s of one core per shard of 64 spp; 512 spp make shards
# long enough (~1.5 s) for a worker to be killed while it renders one.
SIZE = (96, 96)


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


def single(c01, spp, seed):
    scene = skelight.load_file(c01)
    scene.set_resolution(*SIZE)
    return np.asarray(skelight.render(scene, spp=spp, seed=seed))


def test_four_shards_equal_the_single_render(client, c01):
    done = []
    r = skelight.dask.render(str(c01), client, spp=64, shards=4, seed=3, resolution=SIZE, threads=1,
                             progress=lambda d, n: done.append(d))
    assert r.spp == 64 and done == [1, 2, 3, 4]
    np.testing.assert_allclose(np.asarray(r), single(c01, 64, 3), rtol=2e-7, atol=0)


def test_one_shard(client, c01):
    r = skelight.dask.render(str(c01), client, spp=8, shards=1, seed=8, resolution=SIZE, threads=1)
    np.testing.assert_allclose(np.asarray(r), single(c01, 8, 8), rtol=2e-7, atol=0)


def test_shipped_scene_file(client, c01, tmp_path):
    # The file is shipped as bytes; its OBJ-free content loads anywhere.
    r = skelight.dask.render(str(c01), client, spp=16, shards=2, seed=4, resolution=SIZE, threads=1, ship=True)
    np.testing.assert_allclose(np.asarray(r), single(c01, 16, 4), rtol=2e-7, atol=0)


def test_shards_on_the_workers_gpus(client, c01, gpu_render):
    """device="gpu" on every worker (lavapipe here): the shards merge into the single GPU
    render (float32 sums on the device, grouped otherwise: within 1e-5)."""
    scene = skelight.load_file(c01)
    scene.set_resolution(32, 32)
    single_gpu = np.asarray(gpu_render(scene, integrator="ibpt", spp=4, seed=6))
    r = skelight.dask.render(str(c01), client, spp=4, shards=2, seed=6, resolution=(32, 32), integrator="ibpt",
                             device="gpu")
    assert r.key.endswith("|device gpu")
    np.testing.assert_allclose(np.asarray(r), single_gpu, rtol=1e-5, atol=1e-7)


def test_a_worker_killed_mid_render(client, c01):
    """Kill the worker rendering a shard: Dask recomputes it elsewhere; every shard counts
    once and the image is the single render's."""
    import threading

    killed = []
    pids = client.run(os.getpid)

    def kill_one():
        deadline = time.time() + 60
        while time.time() < deadline and not killed:
            busy = [(w, tasks) for w, tasks in client.processing().items() if tasks]
            if busy:
                time.sleep(0.4)  # well inside the shard's render
                os.kill(pids[busy[0][0]], signal.SIGKILL)
                killed.append(busy[0])
            time.sleep(0.05)

    t = threading.Thread(target=kill_one)
    t.start()
    r = skelight.dask.render(str(c01), client, spp=512, shards=4, seed=5, resolution=SIZE, threads=1)
    t.join()
    assert killed, "no worker was seen rendering"
    # The shard the killed worker was rendering was sent to a worker again.
    (worker, keys), = killed
    starts = [e for e in client.run_on_scheduler(lambda dask_scheduler: dask_scheduler.story(keys[0]))
              if e[2] == "processing"]
    assert len(starts) >= 2, starts
    assert r.spp == 512
    np.testing.assert_allclose(np.asarray(r), single(c01, 512, 5), rtol=2e-7, atol=0)


def test_reference_resumes_from_its_shards(client, c01, tmp_path):
    out = tmp_path / "ref.exr"
    first = skelight.dask.reference(str(c01), client, str(out), spp=16, shards=4, seed=6, resolution=SIZE,
                                    integrator="pt", threads=1)
    shards = sorted((tmp_path / "ref.exr.shards").glob("*.exr"))
    assert len(shards) == 4 and out.exists()
    # Drop one shard: the rerun renders only that one and gives the same image.
    shards[1].unlink()
    again = skelight.dask.reference(str(c01), client, str(out), spp=16, shards=4, seed=6, resolution=SIZE,
                                    integrator="pt", threads=1)
    assert np.array_equal(np.asarray(first), np.asarray(again))
    np.testing.assert_allclose(skelight.load_image(out), single(c01, 16, 6), rtol=2e-7, atol=0)
    # The kept shards belong to that render: another seed is refused, not mixed in.
    with pytest.raises(skelight.SkelightError, match="another render"):
        skelight.dask.reference(str(c01), client, str(out), spp=16, shards=4, seed=7, resolution=SIZE,
                                integrator="pt", threads=1)
