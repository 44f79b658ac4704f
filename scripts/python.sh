#!/usr/bin/env bash
# Builds the Python package (crates/skelight-py, PyO3 + maturin) into .venv-py, creating the
# venv and installing crates/skelight-py/requirements-test.txt when needed, then runs the
# given command in that venv (default: the Python tests). SKELIGHT_MATURIN_FEATURES (cargo
# features, as scripts/test.sh builds the workspace) lets the build reuse the workspace's.
#   scripts/python.sh                      # build, then pytest crates/skelight-py/tests
#   scripts/python.sh python my_script.py  # build, then run a script with `import skelight`
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv-py
requirements=crates/skelight-py/requirements-test.txt
if ! command -v python3 >/dev/null; then
    echo "python3 not found: the Python package needs CPython 3.9 or newer" >&2
    exit 1
fi
if [ ! -x "$venv/bin/python" ]; then
    echo "creating $venv (Python package build and tests)"
    python3 -m venv "$venv"
fi
# Reinstall only when the pinned requirements changed.
stamp="$venv/.requirements"
if ! cmp -s "$requirements" "$stamp"; then
    "$venv/bin/pip" install -q --disable-pip-version-check -r "$requirements"
    cp "$requirements" "$stamp"
fi
VIRTUAL_ENV="$PWD/$venv" PATH="$PWD/$venv/bin:$PATH" \
    maturin develop --release -q -m crates/skelight-py/Cargo.toml \
    ${SKELIGHT_MATURIN_FEATURES:+--features "$SKELIGHT_MATURIN_FEATURES"}
if [ $# -eq 0 ]; then
    set -- python -m pytest -q -p no:cacheprovider crates/skelight-py/tests
fi
VIRTUAL_ENV="$PWD/$venv" PATH="$PWD/$venv/bin:$PATH" exec "$@"
