#!/usr/bin/env bash
# Same seed, same bits: renders a fixed set of small images (64×64, 16 spp, seed 7) with every
# registered CPU estimator, and GPU pt/ibpt where the build has the GPU and Vulkan an adapter,
# into OUT, with OUT/hashes.txt (the SHA-256 of each EXR: skelight writes them byte for byte
# deterministically). Given BEFORE (an earlier OUT), it compares each image with its namesake
# and fails unless every one has the same bits; GPU ibpt's light splats are added by float
# atomics in any order, so there it asks for a relMSE under 1e-10 (rounding) instead.
# Run it before and after a refactoring that must not change an image (issue 54):
#   bench/same_bits.sh /tmp/before; ...; bench/same_bits.sh /tmp/after /tmp/before
# The guided estimators' 16 spp are passes enough that their guides are learnt and used.
# Needs ../shared beside the repository; SKELIGHT (default target/release/skelight) names the
# binary (build it with --features gpu for the GPU lines).
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: bench/same_bits.sh OUT [BEFORE]" >&2; exit 2; }
dest=$1 before=${2:-}
mkdir -p "$dest"
cd "$(dirname "$0")/.."
bin=${SKELIGHT:-target/release/skelight}
shared=../shared
scenes=(
    "$shared/conformance/scenes/c01_cbox_area.xml"
    "$shared/conformance/scenes/c07_roughconductor.xml"
    "$shared/conformance/scenes/c14_thinlens.xml"
    "$shared/scenes/veach-door/scene.xml"
    "scenes/door-corner.toml"
)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# The registry's names, as its own error message lists them (so a new estimator is included).
estimators=$("$bin" render -i '?' --spp 1 -q -o "$out/none.exr" 2>&1 | sed -n 's/.*available: //p' | tr -d ',' || true)
[ -n "$estimators" ] || { echo "could not read the estimators from $bin" >&2; exit 1; }
render() { # name scene args...
    local name=$1 scene=$2
    shift 2
    if "$bin" render "$scene" --resolution 64 64 --spp 16 --seed 7 --threads 2 -q -o "$dest/$name.exr" "$@" >/dev/null 2>"$out/err"; then
        echo "$(sha256sum <"$dest/$name.exr" | cut -c1-16)  $name" >>"$dest/hashes.txt"
    else
        echo "unavailable       $name ($(head -c 120 "$out/err" | tr '\n' ' '))" >>"$dest/hashes.txt"
    fi
}
: >"$dest/hashes.txt"
for scene in "${scenes[@]}"; do
    stem=$(basename "$(dirname "$scene")")-$(basename "${scene%.*}")
    for e in $estimators; do
        render "$stem.$e" "$scene" -i "$e"
    done
    for e in pt ibpt; do
        render "$stem.gpu-$e" "$scene" -i "$e" --device gpu
    done
done
cat "$dest/hashes.txt"
[ -n "$before" ] || exit 0
failed=0
while read -r hash name _; do
    old=$(awk -v n="$name" '$2 == n { print $1 }' "$before/hashes.txt")
    if [ "$hash" = "$old" ]; then
        continue
    elif [ "$hash" != unavailable ] && [ -n "$old" ] && [ "$old" != unavailable ] && [[ $name == *.gpu-ibpt ]]; then
        relmse=$("$bin" diff "$dest/$name.exr" "$before/$name.exr" | awk '/max over RGB/ { print $6 }')
        if python3 -c "import sys; sys.exit(0 if float('$relmse') < 1e-10 else 1)"; then
            continue
        fi
        echo "DIFFERS: $name (relMSE $relmse)"
    else
        echo "DIFFERS: $name ($old before, $hash now)"
    fi
    failed=1
done <"$dest/hashes.txt"
[ "$failed" = 0 ] && echo "every image as before" || exit 1
