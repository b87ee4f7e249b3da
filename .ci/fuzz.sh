#!/usr/bin/env bash
# One fuzz target for a bounded time, as CI runs it (a job of .ci/run's pool;
# docs/ci.md, "Fuzzing"):
#   bash .ci/fuzz.sh TARGET SEED FUZZ_TARGET_DIR
# The targets must be built (`cd fuzz && CARGO_TARGET_DIR=FUZZ_TARGET_DIR
# cargo +nightly fuzz build --dev -s none`). The corpus is kept between runs in
# FUZZ_TARGET_DIR/corpus/TARGET, which the checkout's seeds (fuzz/corpus/TARGET)
# are read beside; nothing is written into the checkout. A crash, a unit
# slower than 10 s or one over 2 GiB fails, printing the input's path, the
# command that replays it and, when small, the input itself (base64).
# SNOWPACK_FUZZ_SECONDS sets the time (default 20 s).
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 3 ] || { echo "usage: bash .ci/fuzz.sh TARGET SEED FUZZ_TARGET_DIR" >&2; exit 2; }
target=$1 seed=$2 dir=$3
seconds=${SNOWPACK_FUZZ_SECONDS:-20}
host=$(rustc +nightly -vV | sed -n 's/^host: //p')
fuzzer="$dir/$host/debug/$target"
[ -x "$fuzzer" ] || { echo "fuzz target $target is not built ($fuzzer)"; exit 1; }
[ -d "fuzz/corpus/$target" ] || { echo "fuzz target $target has no seed corpus (fuzz/corpus/$target)"; exit 1; }

# The largest input tried: a file of that kind as users hand it, small enough
# that thousands run in a job. Without it libFuzzer stays at the largest seed
# (170 bytes for the heightmaps). The other targets keep libFuzzer's choice.
# The scene targets start from the schema's words (fuzz/scene.dict).
max_len=()
dict=()
case $target in
  gltf_model) max_len=(-max_len=262144) ;;
  hdr_sky) max_len=(-max_len=65536) ;;
  heightmap) max_len=(-max_len=16384) ;;
  scene_world) max_len=(-max_len=16384) dict=(-dict=fuzz/scene.dict) ;;
  scene_parse) dict=(-dict=fuzz/scene.dict) ;;
  # The largest message a relay accepts (MAX_MESSAGE_BYTES), one byte past it
  # refused; the seeds hold the largest digest, want and presence.
  share_message) max_len=(-max_len=262145) ;;
esac

kept="$dir/corpus/$target"
artifacts="$dir/artifacts/$target"
mkdir -p "$kept" "$artifacts"
# New inputs accumulate in the kept corpus (each run adds tens to hundreds).
# libFuzzer runs every input once before its time limit starts counting
# (gltf_model does about 40 a second), so past 300 inputs and twice its size
# after the last merge, the kept corpus is merged down to the inputs that
# still add coverage.
inputs=$(find "$kept" -type f | wc -l)
merged=$(cat "$kept.size" 2>/dev/null || echo 0)
if [ "$inputs" -gt 300 ] && [ "$inputs" -gt $((2 * merged)) ]; then
  rm -rf "$kept.merged" && mkdir -p "$kept.merged"
  "$fuzzer" -merge=1 -timeout=10 -rss_limit_mb=2048 "${max_len[@]}" "$kept.merged" "$kept" >/dev/null 2>&1
  rm -rf "$kept" && mv "$kept.merged" "$kept"
  find "$kept" -type f | wc -l >"$kept.size"
  echo "fuzz $target: the kept corpus merged from $inputs to $(cat "$kept.size") inputs"
fi

echo "fuzz $target: seed $seed, ${seconds} s, kept corpus $kept ($(find "$kept" -type f | wc -l) inputs) and fuzz/corpus/$target"
log=$(mktemp)
trap 'rm -f "$log"' EXIT
before=$(date +%s)
if "$fuzzer" "$kept" "fuzz/corpus/$target" -seed="$seed" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 "${max_len[@]}" "${dict[@]}" \
     -artifact_prefix="$artifacts/" -print_final_stats=1 >"$log" 2>&1; then
  tail -n 6 "$log"
  exit 0
fi
tail -n 60 "$log"
# The panic's message, which a deep stack pushes out of the tail above.
grep -m 1 -A 1 "panicked at" "$log" || true
input=$(find "$artifacts" -type f -newermt "@$before" -printf '%T@ %p\n' | sort -n | tail -n 1 | cut -d' ' -f2-)
echo "fuzz target $target FAILED with seed $seed"
if [ -n "$input" ]; then
  echo "its input: $input"
  echo "replay it: (cd fuzz && cargo +nightly fuzz run --dev -s none $target '$input')"
  if [ "$(stat -c %s "$input")" -le 65536 ]; then
    echo "the input, base64 (base64 -d > input on another machine):"
    base64 -w 100 "$input"
  fi
fi
echo "the run again: bash .ci/fuzz.sh $target $seed '$dir' (a time-bounded run follows the seed only as far as timing allows)"
exit 1
