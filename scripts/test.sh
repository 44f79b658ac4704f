#!/usr/bin/env bash
# Runs the whole test suite: formatting, lints, unit tests, and the statistical tests
# against the conformance references in ../shared (release mode: they render images), and
# the Python package's tests in a venv it makes (.venv-py; needs python3 and PyPI).
#   scripts/test.sh           the default tier (what CI runs): every estimator against every
#                             conformance scene, with the samples that see a 2 % bias
#   scripts/test.sh --full    the full tier: 128 to 512 samples, a 0.5 % bias (run it before
#                             resolving an issue that changes an estimator, a BSDF, a light or
#                             the film)
# At the end it prints a time table: each step, each test binary, the 20 slowest tests.
set -euo pipefail
cd "$(dirname "$0")/.."
tier=default
for arg in "$@"; do
    case "$arg" in
        --full) tier=full ;;
        *) echo "usage: scripts/test.sh [--full]" >&2; exit 2 ;;
    esac
done
export SKELIGHT_TEST_TIER=$tier
steps=$(mktemp)
trap 'rm -f "$steps"' EXIT
# step NAME COMMAND...: runs the command, recording its wall time for the table; a failing
# step prints the table so far and ends the run with its status.
step() {
    local name=$1 t0 rc=0
    shift
    t0=$EPOCHREALTIME
    "$@" || rc=$?
    printf '%s\t%s\n' "$name" "$(python3 -c "print($EPOCHREALTIME - $t0)")" >>"$steps"
    if [ "$rc" != 0 ]; then
        echo "FAILED: $name (exit $rc)" >&2
        python3 scripts/time_table.py "$steps" "${junit:-}" || true
        exit "$rc"
    fi
}
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

# One build of the workspace serves the lints, the tests and the Python package: the same
# profile and the same features (Embree's where its library is), so nothing is built twice.
features=()
if [ -n "$embree" ]; then
    features=(--features skelight/embree)
else
    echo "note: libembree-dev not available; the Embree backend is neither built nor tested"
fi
step "cargo fmt --check" cargo fmt --all -- --check
step "clippy (workspace, all targets${embree:+, embree})" cargo clippy --workspace --all-targets --release "${features[@]}" -- -D warnings
# The CLI's render --device gpu (its code without the feature was linted just above).
step "clippy (skelight-cli --features gpu)" cargo clippy --release -p skelight-cli --features gpu "${features[@]}" -- -D warnings
junit=target/nextest/default/junit.xml
rm -f "$junit"
if command -v cargo-nextest >/dev/null; then
    # Per-test processes, both cores busy to the end, and a JUnit report for the table.
    step "build the tests" cargo nextest run --release --workspace --exclude skelight-py "${features[@]}" --no-run
    step "cargo nextest ($tier tier)" cargo nextest run --release --workspace --exclude skelight-py "${features[@]}" --no-fail-fast
else
    echo "note: cargo-nextest not found (cargo install cargo-nextest --locked); cargo test has no per-test times"
    step "build the tests" cargo test --release --workspace --exclude skelight-py "${features[@]}" --no-run
    step "cargo test ($tier tier)" cargo test --release --workspace --exclude skelight-py "${features[@]}"
fi
# The Python package (import skelight) and rendering on a Dask LocalCluster.
step "python package: build and pytest" env SKELIGHT_MATURIN_FEATURES="${features[*]:1}" ./scripts/python.sh
python3 scripts/time_table.py "$steps" "$junit"
