#!/usr/bin/env bash
# Out-of-tree plugin test: install the SDK to a temporary prefix, build each
# template as a separate CMake project against it, drop the result into a
# plugin dir, and check that the already-built `horizon` lists and validates
# it. Nothing of core or host is rebuilt.
set -euo pipefail
: "${HORIZON_BIN:?}" "${HORIZON_BUILD_DIR:?}" "${HORIZON_SOURCE_DIR:?}"
work=$(mktemp -d /tmp/hz_sdk_XXXXXX)
trap 'rm -rf "$work"' EXIT
host_before=$(sha256sum "$HORIZON_BIN" | cut -d' ' -f1)

cmake --install "$HORIZON_BUILD_DIR" --component sdk --prefix "$work/sdk" > /dev/null
test -f "$work/sdk/include/hz/hz.h"
test -f "$work/sdk/lib/cmake/HorizonSDK/HorizonSDKConfig.cmake"

mkdir -p "$work/plugins"
for kind in loader shader clustering; do
  cp -r "$work/sdk/share/horizon/sdk/templates/$kind" "$work/src-$kind"
  cmake -S "$work/src-$kind" -B "$work/build-$kind" -DCMAKE_PREFIX_PATH="$work/sdk" -DCMAKE_BUILD_TYPE=Release > /dev/null
  cmake --build "$work/build-$kind" > /dev/null
  cp "$work"/build-$kind/*.so "$work/plugins/"
done

listing=$("$HORIZON_BIN" --plugin-dir "$work/plugins" plugins --json)
for id in org.example.loader.hzt org.example.shader.lambert org.example.clustering.length; do
  grep -q "\"id\": \"$id\"" <<< "$listing" || { echo "FAIL: $id not listed"; echo "$listing"; exit 1; }
done
python3 -c 'import json,sys; j=json.load(sys.stdin); assert not j["rejected"], j["rejected"]' <<< "$listing"

for so in "$work"/plugins/*.so; do
  "$HORIZON_BIN" validate "$so" > "$work/report.txt" || { cat "$work/report.txt"; echo "FAIL: validate $so"; exit 1; }
  tail -1 "$work/report.txt"
done

# The new loader works through the real CLI: phantom TCK -> .hzt -> TCK.
"$HORIZON_BIN" demo --out "$work/demo" --streamlines 50 > /dev/null
"$HORIZON_BIN" --plugin-dir "$work/plugins" convert "$work/demo/phantom.tck" "$work/p.hzt"
"$HORIZON_BIN" --plugin-dir "$work/plugins" convert "$work/p.hzt" "$work/back.tck"
info_out=$("$HORIZON_BIN" --plugin-dir "$work/plugins" info "$work/p.hzt")
grep -q "streamlines:   50" <<< "$info_out"

test "$(sha256sum "$HORIZON_BIN" | cut -d' ' -f1)" = "$host_before"
echo "out-of-tree SDK test: OK"
