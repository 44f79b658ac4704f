#!/usr/bin/env bash
# Runs the whole test suite: formatting, lints, unit tests, and the statistical tests
# against the conformance references in ../shared (release mode: they render images).
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
cargo fmt --all -- --check
cargo clippy --all-targets --release -- -D warnings
cargo test --release --workspace
