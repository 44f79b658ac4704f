#!/usr/bin/env bash
# Issue 35's measurement on a data-centre GPU (H100/H200): samples/s, rays/s and device memory
# of GPU pt and ibpt on sibenik (the seeds' two-lights configuration), veach-door and
# veach-ajar, against CPU ibpt on this machine's 2 cores at the same settings.
#
#   bench/gpu_device.sh prepare    here: builds the CLI with the GPU feature, strips it, and
#                                  packs it and the four scenes into .device/bundle.tar.xz
#                                  (10 MB: the working tree and what is carried travel within
#                                  64 MiB), the Vulkan loader into .gl/ (both git-ignored
#                                  through .git/info/exclude)
#   device `run`, carry [".device", ".gl"], command "bench/gpu_device.sh measure"
#                                  there: checks that the adapter is the GPU (else stops at
#                                  once), then GPU pt and ibpt on the three scenes, a sweep of
#                                  the megakernels' launch shape, and four small veach-door
#                                  renders (two seeds of pt and ibpt) to compare with the CPU
#                                  here; everything comes back under $OUT (gpu_device.txt)
#   python3 bench/gpu_summary.py FILES_AT/gpu_device.txt
#                                  here: the tables, and the launch-shape defaults chosen by
#                                  the rule written in it before the figures came
#   bench/gpu_device.sh baseline   here: CPU ibpt and pt with 2 threads, the same scenes and
#                                  settings (run it on a quiet machine, twice, alternating)
#   bench/gpu_device.sh local      here: the `measure` step on whatever Vulkan adapter this
#                                  machine has (lavapipe), at 1 spp: a dry run of the script
#
# The images are reduced to 512×288 (sibenik 512×256) and keep their own max depth; samples/s
# does not depend on the sample count, which is chosen so that each GPU run takes seconds.
# `measure` keeps to DEADLINE seconds (default 330) and skips what would run past it, so that
# the device call (timeout_s 420) always returns its report.
set -euo pipefail
cd "$(dirname "$0")/.."

SCENES=(
    ".device/a/b/sibenik-two-lights.toml:512:256"
    ".device/shared/scenes/veach-door/scene.xml:512:288"
    ".device/shared/scenes/veach-ajar/scene.xml:512:288"
)
# The traversal alone (`rays`) on these and on Dabrovic's Sponza (82 573 triangles), the
# nearest to the Crytek Sponza of the published compute-shader figure (TinyBVH).
RAY_SCENES=(
    "${SCENES[@]}"
    ".device/shared/scenes/sponza-dabrovic/sponza.xml:0:0"
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
        stage=$(mktemp -d)
        mkdir -p "$stage/a/b" "$stage/shared/scenes"
        cp target/release/skelight "$stage/skelight"
        strip "$stage/skelight"
        for s in sibenik veach-door veach-ajar sponza-dabrovic; do
            cp -r "../shared/scenes/$s" "$stage/shared/scenes/"
        done
        # No reference images: they are not needed there.
        rm -f "$stage"/shared/scenes/*/*.exr
        # The TOML names its mesh as ../../shared/scenes/sibenik/…: two folders down it resolves.
        cp scenes/sibenik-two-lights.toml "$stage/a/b/"
        rm -rf .device
        mkdir -p .device
        tar -C "$stage" -cJf .device/bundle.tar.xz .
        rm -rf "$stage"
        mkdir -p .gl /tmp/amd64/partial
        o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
        if ! ls .gl/libglvnd0_*.deb >/dev/null 2>&1; then
            # shellcheck disable=SC2086
            apt-get $o update -qq
            # shellcheck disable=SC2086
            (cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
        fi
        touch .git/info/exclude
        for d in /.device/ /.gl/; do
            grep -qxF "$d" .git/info/exclude || echo "$d" >>.git/info/exclude
        done
        du -sh .device .gl
        echo "the working tree: $(git ls-files -z | du -ch --files0-from=- | tail -1)"
        ;;
    measure | local)
        began=$(date +%s)
        deadline=${DEADLINE:-330}
        out=${OUT:-/tmp/gpu_local}
        mkdir -p "$out"
        report=$out/gpu_device.txt
        : >"$report"
        tar -C .device -xJf .device/bundle.tar.xz
        if [ "$1" = measure ]; then
            for f in .gl/*.deb; do dpkg -x "$f" /; done
            ldconfig
            icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
            [ -e "$icd" ] && export VK_DRIVER_FILES=$icd
            (nvidia-smi -L || true) | tee -a "$report"
            spp=${SPP:-64} check=1024 r=1
        else
            # A dry run on lavapipe: one sample, images an eighth of the size.
            spp=1 check=2 r=8
            trap 'find .device -mindepth 1 -maxdepth 1 ! -name bundle.tar.xz -exec rm -rf {} +' EXIT
        fi
        THREADS=()
        left() { echo $((deadline - ($(date +%s) - began))); }
        # one LABEL SECONDS COMMAND…: runs COMMAND if SECONDS remain before the deadline.
        one() {
            local label=$1 limit=$2
            shift 2
            if [ "$(left)" -lt "$limit" ]; then
                echo "== $label: skipped ($(left) s left)" | tee -a "$report"
                return
            fi
            echo "== $label (t=$(($(date +%s) - began)) s)" | tee -a "$report"
            timeout "$limit" "$@" 2>&1 | grep -v XDG_RUNTIME_DIR | tee -a "$report" || true
        }
        bin=.device/skelight door=.device/shared/scenes/veach-door/scene.xml
        # 1. The adapter: stop at once if Vulkan did not find the GPU.
        one adapter 60 "$bin" bench render "$door" --device gpu -i pt --spp 1 --resolution 64 36
        if [ "$1" = measure ] && ! grep -q "^GPU: .*NVIDIA" "$report"; then
            echo "no NVIDIA adapter: stopping" | tee -a "$report"
            cat "$icd" 2>&1 | tee -a "$report"
            VK_LOADER_DEBUG=error,warn,driver "$bin" bench render "$door" --device gpu -i pt --spp 1 \
                --resolution 64 36 2>&1 | tail -40 | tee -a "$report"
            exit 3
        fi
        steps=" ${STEPS:-table traversal wavefront rays check again} "
        # 2. The table: GPU pt and ibpt per scene, default launch shape.
        [[ $steps == *" table "* ]] && for entry in "${SCENES[@]}"; do
            IFS=: read -r scene w h <<<"$entry"
            for estimator in pt ibpt; do
                one "$scene $estimator $spp spp" 60 "$bin" bench render "$scene" --device gpu \
                    -i "$estimator" --spp "$spp" --resolution $((w / r)) $((h / r))
            done
        done
        # 2b. The ordered traversal (bvh.rs: nearest child first, a stack, two boxes per node)
        # and the hybrid (ordered closest hits, stackless shadow rays) against the table's
        # stackless one, same scenes and shape.
        [[ $steps == *" traversal "* ]] && for entry in "${SCENES[@]}"; do
            IFS=: read -r scene w h <<<"$entry"
            for traversal in hybrid ordered; do
                for estimator in pt ibpt; do
                    SKELIGHT_GPU_TRAVERSAL=$traversal one "traversal $traversal: $scene $estimator $spp spp" 60 \
                        "$bin" bench render "$scene" --device gpu -i "$estimator" --spp "$spp" \
                        --resolution $((w / r)) $((h / r))
                done
            done
        done
        # 2c. The wavefront (wavefront.wgsl) against the table's megakernels: the camera pass
        # alone (1; ibpt's light pass stays a megakernel) and both passes (2), with the stackless
        # and the hybrid traversal.
        [[ $steps == *" wavefront "* ]] && for entry in "${SCENES[@]}"; do
            IFS=: read -r scene w h <<<"$entry"
            for variant in 1:pt:stackless 1:ibpt:stackless 2:ibpt:stackless 1:pt:hybrid 1:ibpt:hybrid; do
                IFS=: read -r wavefront estimator traversal <<<"$variant"
                SKELIGHT_GPU_WAVEFRONT=$wavefront SKELIGHT_GPU_TRAVERSAL=$traversal one \
                    "wavefront $wavefront, $traversal: $scene $estimator $spp spp" 60 "$bin" bench render "$scene" \
                    --device gpu -i "$estimator" --spp "$spp" --resolution $((w / r)) $((h / r))
            done
        done
        # 3. Four renders for the CPU comparison here: pt and ibpt, seeds 1 and 2, 160×90.
        [[ $steps == *" check "* ]] && for estimator in pt ibpt; do
            for seed in ${CHECK_SEEDS:-1 2}; do
                one "check $estimator seed $seed" 60 "$bin" render "$door" --device gpu -i "$estimator" \
                    --spp "$check" --resolution 160 90 --seed "$seed" -q -o "$out/door_${estimator}_$seed.exr"
                rm -f "$out/door_${estimator}_$seed.png" # at most 8 files come back
            done
        done
        # 4. The launch shape: workgroup, samples per dispatch, tile (at 1024×576).
        [[ $steps == *" shape "* ]] && for wg in 8x4 16x8 16x16 32x1 32x2; do
            for estimator in pt ibpt; do
                SKELIGHT_GPU_WORKGROUP=$wg one "shape: workgroup $wg, door $estimator" 40 "$bin" bench render \
                    "$door" --device gpu -i "$estimator" --spp "$spp" --resolution $((512 / r)) $((288 / r))
            done
        done
        [[ $steps == *" shape "* ]] && for n in 1 4; do
            SKELIGHT_GPU_SAMPLES_PER_DISPATCH=$n one "shape: $n samples per dispatch, door ibpt" 40 "$bin" \
                bench render "$door" --device gpu -i ibpt --spp "$spp" --resolution $((512 / r)) $((288 / r))
        done
        [[ $steps == *" shape "* ]] && for tile in 512 1024; do
            SKELIGHT_GPU_TILE=$tile one "shape: tile $tile, door ibpt at 1024×576" 40 "$bin" bench render \
                "$door" --device gpu -i ibpt --spp "$spp" --resolution $((1024 / r)) $((576 / r))
        done
        # 5. Threads per pixel (slices) and the fused instant-BPT kernel, per scene; at 160×90
        # too, where a dispatch has fewest threads.
        [[ $steps == *" slices "* ]] && for entry in "${SCENES[@]}" "$door:160:90"; do
            IFS=: read -r scene w h <<<"$entry"
            for shape in 1:0 2:0 4:0 8:0 1:1 4:1 8:1; do
                IFS=: read -r slices fused <<<"$shape"
                SKELIGHT_GPU_SLICES=$slices SKELIGHT_GPU_FUSED=$fused one "slices $slices fused $fused: $scene ibpt" \
                    30 "$bin" bench render "$scene" --device gpu -i ibpt --spp "$spp" --resolution $((w / r)) $((h / r))
            done
            for slices in 1 4 8; do
                SKELIGHT_GPU_SLICES=$slices one "slices $slices: $scene pt" 30 "$bin" bench render "$scene" \
                    --device gpu -i pt --spp "$spp" --resolution $((w / r)) $((h / r))
            done
        done
        # The same samples as step 3's seed 1 through 4 slices and the fused kernel: equal up to
        # the order of float sums.
        [[ $steps == *" slices "* ]] && SKELIGHT_GPU_SLICES=4 SKELIGHT_GPU_FUSED=1 one "check ibpt seed 1, slices 4, fused" \
            60 "$bin" render "$door" --device gpu -i ibpt --spp "$check" --resolution 160 90 --seed 1 -q \
            -o "$out/door_ibpt_1_fused.exr" && rm -f "$out/door_ibpt_1_fused.png"
        # 6. Rays per second of the traversal alone (no shading), both traversals: the CPU's
        # incoherent rays and primary rays, with the work per ray and the rays whose hits differ.
        [[ $steps == *" rays "* ]] && for entry in "${RAY_SCENES[@]}"; do
            IFS=: read -r scene _ _ <<<"$entry"
            one "rays: $scene" 60 "$bin" bench rays "$scene" --device gpu --rays $((4000000 / r / r)) --rounds 5
        done
        # 7. The smallest image (fewest threads per dispatch), default shape.
        [[ $steps == *" small "* ]] && for estimator in pt ibpt; do
            one "small: door $estimator at 160×90" 30 "$bin" bench render "$door" --device gpu -i "$estimator" \
                --spp "$spp" --resolution 160 90
        done
        # 8. The table again, four times the samples, while time remains.
        [[ $steps == *" again "* ]] && for entry in "${SCENES[@]}"; do
            IFS=: read -r scene w h <<<"$entry"
            for estimator in pt ibpt; do
                one "again: $scene $estimator $((4 * spp)) spp" 40 "$bin" bench render "$scene" \
                    --device gpu -i "$estimator" --spp $((4 * spp)) --resolution $((w / r)) $((h / r))
            done
        done
        echo "done at t=$(($(date +%s) - began)) s" | tee -a "$report"
        true
        ;;
    baseline)
        out=/tmp/gpu_device_baseline.txt
        : >"$out"
        [ -x .device/skelight ] || tar -C .device -xJf .device/bundle.tar.xz
        THREADS=(--threads 2)
        run_all .device/skelight cpu "${SPP:-4}" "$out" ibpt pt
        for entry in "${RAY_SCENES[@]}"; do
            IFS=: read -r scene _ _ <<<"$entry"
            .device/skelight bench rays "$scene" --rays 4000000 --rounds 3 --threads 2 | tee -a "$out"
        done
        ;;
    *)
        sed -n '2,28p' "$0"
        exit 2
        ;;
esac
