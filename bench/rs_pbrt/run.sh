#!/usr/bin/env bash
# BPT throughput against rs_pbrt's bdpt on the same Cornell box (c01), same resolution,
# same path length, same thread count. Installs rs_pbrt into bench/rs_pbrt/.root if absent.
#   bench/rs_pbrt/run.sh [SPP] [THREADS]
set -euo pipefail
cd "$(dirname "$0")/../.."
spp=${1:-64}
threads=${2:-$(nproc)}
root=bench/rs_pbrt/.root
if [ ! -x "$root/bin/rs_pbrt" ]; then
    cargo install rs_pbrt --version 0.9.12 --root "$root"
fi
work=$(mktemp -d)
sed "s/\[SPP\]/[$spp]/" bench/rs_pbrt/c01_cbox_area.pbrt > "$work/c01.pbrt"
start=$(date +%s.%N)
(cd "$work" && "$OLDPWD/$root/bin/rs_pbrt" -t "$threads" -i bdpt -p c01.pbrt > rs_pbrt.log 2>&1)
end=$(date +%s.%N)
secs=$(awk "BEGIN { print $end - $start }")
rs=$(awk "BEGIN { print 128 * 128 * $spp / $secs / 1e6 }")
printf 'rs_pbrt bdpt: %d spp in %.2f s (%.3f Msamples/s, scene parsing included)\n' "$spp" "$secs" "$rs"
cargo build --release -q -p skelight-cli
ours=$(./target/release/skelight bench render ../shared/conformance/scenes/c01_cbox_area.xml -i bpt \
    --spp "$spp" --max-depth 6 --threads "$threads" 2>&1 | tail -1)
echo "skelight $ours"
ms=$(echo "$ours" | sed -E 's/.* ([0-9.]+) Msamples\/s.*/\1/')
printf 'ratio skelight / rs_pbrt: %.2fx\n' "$(awk "BEGIN { print $ms / $rs }")"
rm -rf "$work"
