#!/usr/bin/env bash
# Builds the browser demo into web/dist/: snowpack-web for wasm32-unknown-unknown
# (release), then wasm-bindgen (its version must equal the wasm-bindgen crate's in
# Cargo.lock), then the page and the credits beside it. Installs the wasm32 target
# and the matching wasm-bindgen-cli when they are missing (rustup's automatic
# install is off on our machines, so the target is added explicitly).
# Serve the result with `node web/serve.mjs` and open http://127.0.0.1:8080/.
set -euo pipefail
cd "$(dirname "$0")/.."

rustup target list --installed | grep -q '^wasm32-unknown-unknown$' || rustup target add wasm32-unknown-unknown
want=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
have=$(wasm-bindgen --version 2>/dev/null | awk '{ print $2 }' || true)
if [ "$have" != "$want" ]; then
  echo "installing wasm-bindgen-cli $want (found: ${have:-none})"
  # --locked first; a lock entry the registry no longer offers falls back to a fresh resolve.
  cargo install wasm-bindgen-cli --version "$want" --locked || cargo install wasm-bindgen-cli --version "$want"
fi

target_dir="${CARGO_TARGET_DIR:-$PWD/target}"
cargo build -p snowpack-web --lib --release --target wasm32-unknown-unknown
rm -rf web/dist.tmp && mkdir -p web/dist.tmp
wasm-bindgen --target web --no-typescript --out-dir web/dist.tmp "$target_dir/wasm32-unknown-unknown/release/snowpack_web.wasm"
cp web/index.html web/dist.tmp/
cp crates/snowpack-scene/assets/CREDITS.md web/dist.tmp/CREDITS.md
# Swap in whole: a failed build never leaves a half-written dist/.
rm -rf web/dist && mv web/dist.tmp web/dist
echo "built web/dist ($(du -sh web/dist | cut -f1)): node web/serve.mjs, then open http://127.0.0.1:8080/"
