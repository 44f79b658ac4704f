#!/bin/bash
# Regenerates the skeleton pictures and reports in this folder (resolution 128, the seeds'
# default): ./docs/skeletons/make.sh from the repository root, with ../shared beside it.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release -q -p skelight-cli
S=../shared/scenes
run() {
    local name=$1
    shift
    local out=docs/skeletons/$name
    mkdir -p "$out"
    /usr/bin/time -f "$name: %e s wall, %M KB peak" ./target/release/skelight skeleton "$@" --resolution 128 -o /tmp/skelight-docs-$name -q
    cp /tmp/skelight-docs-$name/{report.txt,skeleton_view.png,skeleton_filtered_view.png,mapping_filtered.png,labels.png} "$out"/
}
# Closed buildings: only the space they enclose (not the shell of air in the grid margin).
run veach-door $S/veach-door/scene.xml --enclosed-only
run veach-ajar $S/veach-ajar/scene.xml --enclosed-only
run corridor $S/corridor/scene.xml --enclosed-only
# Open to the sky or through windows: everything in the box.
run sponza-dabrovic $S/sponza-dabrovic/sponza.xml
run sibenik scenes/sibenik-two-lights.toml
# The classroom stands on a 220 m ground plane: analyse the room's box only.
run classroom $S/classroom/scene.xml --bounds=-4.7,-0.2,-6.2,4.7,3.3,6.2
