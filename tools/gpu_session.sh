#!/usr/bin/env bash
# Issue 44's GPU figures in one call of a lent NVIDIA machine, most needed
# first, each part under its own time limit (docs/PERFORMANCE.md, "What a
# GPU session runs"). That machine has no Rust: build here, carry the
# binaries. Here, from the repository root:
#
#   cargo build --release -p snowpack-app --bin snowpack
#   cargo build --release -p snowpack --example capture_cost
#   mkdir -p .gpu && cp "$CARGO_TARGET_DIR"/release/snowpack "$CARGO_TARGET_DIR"/release/examples/capture_cost .gpu/
#   grep -qx '/.gpu/' .git/info/exclude || echo /.gpu/ >> .git/info/exclude
#   # and the Vulkan loader debs into .gl, as the device README says.
#
# There: `bash tools/gpu_session.sh` with carry [".gl", ".gpu"] and a
# timeout of 560 s. Everything comes back as three files under $OUT
# (reports.md, csv.txt, log.txt): the device returns at most eight.
# QUICK=1 runs every part `--quick` (a dry run on a software adapter here).
set -u
out=${OUT:-/tmp/gpu-session}
mkdir -p "$out"
log="$out/log.txt"
for f in .gl/*.deb; do dpkg -x "$f" / >>"$log" 2>&1; done
ldconfig
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -f "$icd" ] && export VK_DRIVER_FILES="$icd"
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.max.mem --format=csv >>"$log" 2>&1
export RUST_LOG=warn

# One part: its name, its time limit (s), then the command. Its report and
# CSV files are appended to reports.md and csv.txt, its output to log.txt.
part() {
    local name=$1 limit=$2
    shift 2
    local dir=/tmp/gpu-session-$name
    rm -rf "$dir"
    local start=$SECONDS
    timeout "$limit" "$@" --out "$dir" >>"$log" 2>&1
    local rc=$?
    echo "== $name: exit $rc after $((SECONDS - start)) s" | tee -a "$log"
    if [ -f "$dir/report.md" ]; then
        printf '\n\n<!-- %s -->\n' "$name" >>"$out/reports.md"
        cat "$dir/report.md" >>"$out/reports.md"
    fi
    for c in "$dir"/*.csv; do
        [ -f "$c" ] && { echo "== $name/$(basename "$c")"; cat "$c"; } >>"$out/csv.txt"
    done
}

export SNOWPACK_BACKEND=vulkan
bench=(.gpu/snowpack bench --backend vulkan)
[ "${QUICK:-0}" = 1 ] && bench+=(--quick)
# The passes over noise hills, 512² to 4096²: what the window's ground and
# the rest of issue 44 bought, against the H200 table of 2026-11-26.
part passes 120 "${bench[@]}" --only passes
# The display's two kernels side by side, over flat ground and hills.
part display 90 "${bench[@]}" --only display
# The capture by compute against drawn.
part capture 90 "${bench[@]}" --only capture
# The techniques up to 16,384 spheres.
part techniques 120 "${bench[@]}" --only techniques
# The coat against skinning.
part coat 45 "${bench[@]}" --only coat
# The capture's wall time by compute and drawn (no --out: its table is its output).
start=$SECONDS
timeout 45 .gpu/capture_cost >>"$log" 2>&1
echo "== capture_cost: exit $? after $((SECONDS - start)) s" | tee -a "$log"
