"""Shared fixtures: the conformance scenes in ../shared and the CLI binary."""

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
SHARED = Path(os.environ.get("SKELIGHT_SHARED", ROOT.parent / "shared"))
C01 = SHARED / "conformance" / "scenes" / "c01_cbox_area.xml"


@pytest.fixture(scope="session")
def c01() -> Path:
    if not C01.exists():
        pytest.fail(f"{C01} is missing: the tests read the conformance scenes from ../shared")
    return C01


@pytest.fixture(scope="session")
def cli() -> Path:
    """The release CLI (built here if the cargo tests have not built it)."""
    exe = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target")) / "release" / "skelight"
    if not exe.exists():
        subprocess.run(["cargo", "build", "--release", "-p", "skelight-cli"], cwd=ROOT, check=True)
    return exe


@pytest.fixture(scope="session")
def gpu_render():
    """skelight.render on the GPU, or a skip when the machine has no Vulkan adapter and none
    is required (SKELIGHT_REQUIRE_GPU=1, set by scripts/test.sh where it has Vulkan)."""
    import skelight

    def render(scene, **kwargs):
        try:
            return skelight.render(scene, device="gpu", **kwargs)
        except skelight.SkelightError as e:
            if "no usable GPU adapter" in str(e) and os.environ.get("SKELIGHT_REQUIRE_GPU") != "1":
                pytest.skip(f"no Vulkan adapter: {e}")
            raise

    return render
