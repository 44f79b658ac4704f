#!/usr/bin/env bash
# Runs the whole test suite: formatting, lints, unit tests, and the statistical tests
# against the conformance references in ../shared (release mode: they render images), and
# the Python package's tests in a venv it makes (.venv-py; needs python3 and PyPI).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v cargo >/dev/null; then
    echo "cargo not found: install Rust (https://rustup.rs) first" >&2
    exit 1
fi
if [ ! -d ../shared/conformance ]; then
    echo "../shared/conformance is missing: the tests read the conformance scenes from there" >&2
    exit 1
fi
# The Embree backend is optional; its tests need Debian's libembree-dev, installed here
# when this script may (root with apt), skipped with a note otherwise.
embree=""
if [ -e /usr/include/embree3/rtcore.h ]; then
    embree=1
elif [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing libembree-dev for the Embree backend tests"
    if (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libembree-dev) >/dev/null 2>&1; then
        embree=1
    fi
fi

# The GPU crate's tests run on any Vulkan adapter: Mesa's lavapipe (a CPU implementation)
# where there is no GPU, installed here when this script may.
if [ ! -e /usr/share/vulkan/icd.d/lvp_icd.x86_64.json ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing mesa-vulkan-drivers (lavapipe) for the GPU tests"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mesa-vulkan-drivers libvulkan1) >/dev/null 2>&1 || true
fi
if ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1; then
    export SKELIGHT_REQUIRE_GPU=1   # an adapter is expected: its absence is a failure
else
    echo "note: no Vulkan driver; the GPU tests will say so and pass"
fi

cargo fmt --all -- --check
cargo clippy --all-targets --release -- -D warnings
cargo test --release --workspace --exclude skelight-py   # its tests are in Python, below
# The Python package (import skelight) and rendering on a Dask LocalCluster.
./scripts/python.sh
cargo clippy --release -p skelight-cli --features gpu -- -D warnings   # render --device gpu
if [ -n "$embree" ]; then
    cargo clippy --all-targets --release --features embree -p skelight -p skelight-cli -p skelight-shape -- -D warnings
    cargo test --release -p skelight --features embree --lib geometry
else
    echo "note: libembree-dev not available; Embree backend tests skipped"
fi
