#!/usr/bin/env bash
# Issue 35's measurement on a data-centre GPU (H100/H200): samples/s, rays/s and device memory
# of GPU pt and ibpt on sibenik (the seeds' two-lights configuration), veach-door and
# veach-ajar, against CPU ibpt on this machine's 2 cores at the same settings.
#
#   bench/gpu_device.sh prepare    here: builds the CLI with the GPU feature, strips it, and
#                                  gathers it, the three scenes and the Vulkan loader into
#                                  .device/ and .gl/ (both git-ignored through .git/info/exclude)
#   device `run`, carry [".device", ".gl"], command "bench/gpu_device.sh measure"
#                                  there: GPU pt and ibpt; the report comes back as
#                                  $OUT/gpu_device.txt
#   bench/gpu_device.sh baseline   here: CPU ibpt and pt with 2 threads, the same scenes and
#                                  settings (run it on a quiet machine, twice, alternating)
#   bench/gpu_device.sh local      here: the `measure` step on whatever Vulkan adapter this
#                                  machine has (lavapipe), at 1 spp: a dry run of the script
#
# The images are reduced to 512×288 (sibenik 512×256) and keep their own max depth; samples/s
# does not depend on the sample count, which is chosen so that each GPU run takes seconds.
set -euo pipefail
cd "$(dirname "$0")/.."

SCENES=(
    ".device/a/b/sibenik-two-lights.toml:512:256"
    ".device/shared/scenes/veach-door/scene.xml:512:288"
    ".device/shared/scenes/veach-ajar/scene.xml:512:288"
)

run_all() {
    local bin=$1 device=$2 spp=$3 out=$4
    shift 4
    for entry in "${SCENES[@]}"; do
        IFS=: read -r scene w h <<<"$entry"
        for estimator in "$@"; do
            echo "== $scene $estimator --device $device --spp $spp" | tee -a "$out"
            "$bin" bench render "$scene" --device "$device" -i "$estimator" --spp "$spp" \
                --resolution "$w" "$h" "${THREADS[@]}" 2>&1 | grep -v XDG_RUNTIME_DIR | tee -a "$out" || true
        done
    done
}

case "${1:-}" in
    prepare)
        cargo build --release -p skelight-cli --features gpu
        mkdir -p .device/a/b .device/shared/scenes
        cp target/release/skelight .device/skelight
        strip .device/skelight
        for s in sibenik veach-door veach-ajar; do
            rm -rf ".device/shared/scenes/$s"
            cp -r "../shared/scenes/$s" .device/shared/scenes/
        done
        # What travels is limited to 64 MiB with the working tree (26 MiB): no reference images.
        rm -f .device/shared/scenes/*/*.exr
        # The TOML names its mesh as ../../shared/scenes/sibenik/…: two folders down it resolves.
        cp scenes/sibenik-two-lights.toml .device/a/b/
        mkdir -p .gl /tmp/amd64/partial
        o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
        # shellcheck disable=SC2086
        apt-get $o update -qq
        # shellcheck disable=SC2086
        (cd .gl && apt-get $o download libvulkan1)
        touch .git/info/exclude
        for d in /.device/ /.gl/; do
            grep -qxF "$d" .git/info/exclude || echo "$d" >>.git/info/exclude
        done
        du -sh .device .gl
        echo "the working tree: $(git ls-files -z | du -ch --files0-from=- | tail -1)"
        ;;
    measure)
        for f in .gl/*.deb; do dpkg -x "$f" /; done
        ldconfig
        icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
        [ -e "$icd" ] && export VK_DRIVER_FILES=$icd
        out=${OUT:-/tmp}/gpu_device.txt
        : >"$out"
        (nvidia-smi -L || true) | tee -a "$out"
        THREADS=()
        run_all .device/skelight gpu "${SPP:-64}" "$out" pt ibpt
        ;;
    local)
        out=/tmp/gpu_device_local.txt
        : >"$out"
        THREADS=()
        run_all .device/skelight gpu 1 "$out" pt ibpt
        ;;
    baseline)
        out=/tmp/gpu_device_baseline.txt
        : >"$out"
        THREADS=(--threads 2)
        run_all .device/skelight cpu "${SPP:-4}" "$out" ibpt pt
        ;;
    *)
        sed -n '2,20p' "$0"
        exit 2
        ;;
esac
