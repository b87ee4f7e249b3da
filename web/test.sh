#!/usr/bin/env bash
# The browser demo's end-to-end test: `bash web/test.sh [--prebuilt] OUT_DIR`.
# Builds the page (web/build.sh; --prebuilt: web/dist/ is already built, as
# .ci/run does before it starts the test jobs side by side), serves it on localhost, opens it in headless
# Chromium through playwright-core, runs 60 frames with a scripted deformer
# (the player's sphere driven along a line), and writes OUT_DIR/web.png (the
# app's own frame readback) and OUT_DIR/web.json. Exits non-zero if the page
# logs an error, has no WebGPU adapter, draws a blank frame, or its trail does
# not differ from untouched snow. Installs what is missing: the wasm32 target
# and wasm-bindgen-cli (build.sh), Debian's chromium (as root), playwright-core.
set -euo pipefail
prebuilt=false
if [ "${1:-}" = --prebuilt ]; then prebuilt=true; shift; fi
out="${1:?usage: web/test.sh [--prebuilt] OUT_DIR}"
cd "$(dirname "$0")/.."
mkdir -p "$out"
out="$(cd "$out" && pwd)"

if ! command -v chromium >/dev/null 2>&1 && [ -z "${CHROMIUM:-}" ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing chromium"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null)
  else
    echo "web test: chromium is missing (apt-get install chromium, or set CHROMIUM)" >&2
    exit 1
  fi
fi
# playwright-core, pinned in web/package-lock.json.
[ -d web/node_modules/playwright-core ] || (cd web && npm ci --no-audit --no-fund --loglevel=error)

if $prebuilt; then
  [ -f web/dist/index.html ] || { echo "web test: --prebuilt, but web/dist/ holds no build (run web/build.sh)" >&2; exit 1; }
else
  bash web/build.sh
fi

log="$out/serve.log"
node web/serve.mjs web/dist 0 >"$log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  grep -q '^serving' "$log" 2>/dev/null && break
  sleep 0.1
done
url=$(sed -n 's/^serving .* at \(http[^ ]*\)$/\1/p' "$log")
[ -n "$url" ] || { echo "web test: the server did not start: $(cat "$log")" >&2; exit 1; }
node web/test.mjs "${url}index.html" "$out" "${SNOWPACK_WEB_FRAMES:-60}"
