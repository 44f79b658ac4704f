#!/usr/bin/env bash
# BPT throughput against rs_pbrt's bdpt on the same Cornell box (c01), same resolution,
# same path length, same thread count. Installs rs_pbrt into bench/rs_pbrt/.root if absent.
#   bench/rs_pbrt/run.sh [SPP] [THREADS] [ROUNDS]
# The two renderers run in turn ROUNDS times (default 1). This machine's speed drifts by
# up to a third over seconds, for both alike, so with several rounds each renderer's best
# run (its speed on a quiet machine) is compared, and the median of the rounds' ratios is
# printed beside it.
set -euo pipefail
cd "$(dirname "$0")/../.."
spp=${1:-64}
threads=${2:-$(nproc)}
rounds=${3:-1}
root=bench/rs_pbrt/.root
if [ ! -x "$root/bin/rs_pbrt" ]; then
    cargo install rs_pbrt --version 0.9.12 --root "$root"
fi
cargo build --release -q -p skelight-cli
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed "s/\[SPP\]/[$spp]/" bench/rs_pbrt/c01_cbox_area.pbrt > "$work/c01.pbrt"
ratios=()
best_rs=0
best_ours=0
for round in $(seq "$rounds"); do
    start=$(date +%s.%N)
    (cd "$work" && "$OLDPWD/$root/bin/rs_pbrt" -t "$threads" -i bdpt -p c01.pbrt > rs_pbrt.log 2>&1)
    end=$(date +%s.%N)
    rs=$(awk "BEGIN { print 128 * 128 * $spp / ($end - $start) / 1e6 }")
    ours=$(./target/release/skelight bench render ../shared/conformance/scenes/c01_cbox_area.xml -i bpt \
        --spp "$spp" --max-depth 6 --threads "$threads" 2>&1 | tail -1)
    ms=$(echo "$ours" | sed -E 's/.* ([0-9.]+) Msamples\/s.*/\1/')
    ratio=$(awk "BEGIN { print $ms / $rs }")
    ratios+=("$ratio")
    best_rs=$(awk "BEGIN { print ($rs > $best_rs) ? $rs : $best_rs }")
    best_ours=$(awk "BEGIN { print ($ms > $best_ours) ? $ms : $best_ours }")
    printf 'round %d: rs_pbrt bdpt %.3f Msamples/s (scene parsing included), skelight bpt %.3f Msamples/s, ratio %.2fx\n' \
        "$round" "$rs" "$ms" "$ratio"
done
median=$(printf '%s\n' "${ratios[@]}" | sort -g | awk '{ a[NR] = $1 } END { print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2 }')
printf 'best rs_pbrt %.3f, best skelight %.3f Msamples/s: ratio %.2fx; median of %d rounds %.2fx (%d spp, %d threads)\n' \
    "$best_rs" "$best_ours" "$(awk "BEGIN { print $best_ours / $best_rs }")" "$rounds" "$median" "$spp" "$threads"
