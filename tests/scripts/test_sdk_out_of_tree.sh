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
# OpenGL commands run without LeakSanitizer under the ASan suite (see hztest.py GL_COMMANDS).
gl() { ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:detect_leaks=0}" "$@"; }

cmake --install "$HORIZON_BUILD_DIR" --component sdk --prefix "$work/sdk" > /dev/null
test -f "$work/sdk/include/hz/hz.h"
test -f "$work/sdk/lib/cmake/HorizonSDK/HorizonSDKConfig.cmake"
# The authors' guide and the ABI's design record come with the SDK.
test -f "$work/sdk/share/horizon/sdk/docs/plugins.md"
test -f "$work/sdk/share/horizon/sdk/docs/ABI.md"

mkdir -p "$work/plugins"
for kind in loader loader_cpp shader clustering; do
  cp -r "$work/sdk/share/horizon/sdk/templates/$kind" "$work/src-$kind"
  cmake -S "$work/src-$kind" -B "$work/build-$kind" -DCMAKE_PREFIX_PATH="$work/sdk" -DCMAKE_BUILD_TYPE=Release > /dev/null
  cmake --build "$work/build-$kind" > /dev/null
  cp "$work"/build-$kind/*.so "$work/plugins/"
done

listing=$("$HORIZON_BIN" --plugin-dir "$work/plugins" plugins --json)
for id in org.example.loader.hzt org.example.loader.csv-streamlines org.example.shader.lambert org.example.clustering.length; do
  grep -q "\"id\": \"$id\"" <<< "$listing" || { echo "FAIL: $id not listed"; echo "$listing"; exit 1; }
done
python3 -c 'import json,sys; j=json.load(sys.stdin); assert not j["rejected"], j["rejected"]' <<< "$listing"

for so in "$work"/plugins/*.so; do
  "$HORIZON_BIN" validate "$so" > "$work/report.txt" || { cat "$work/report.txt"; echo "FAIL: validate $so"; exit 1; }
  tail -1 "$work/report.txt"
done

# The new loader works through the real CLI: phantom TCK -> .hzt -> TCK.
gl "$HORIZON_BIN" demo --out "$work/demo" --streamlines 50 --no-window > /dev/null
"$HORIZON_BIN" --plugin-dir "$work/plugins" convert "$work/demo/phantom.tck" "$work/p.hzt"
"$HORIZON_BIN" --plugin-dir "$work/plugins" convert "$work/p.hzt" "$work/back.tck"
info_out=$("$HORIZON_BIN" --plugin-dir "$work/plugins" info "$work/p.hzt")
grep -q "streamlines:   50" <<< "$info_out"
# And the C++ one (the SDK's loader adapter): TCK -> .csv -> TCK, the same streamlines.
"$HORIZON_BIN" --plugin-dir "$work/plugins" convert "$work/demo/phantom.tck" "$work/p.csv"
"$HORIZON_BIN" --plugin-dir "$work/plugins" convert "$work/p.csv" "$work/back_csv.tck"
/usr/bin/python3 - "$work/demo/phantom.tck" "$work/back_csv.tck" <<'PY'
import sys
import nibabel as nib
import numpy as np
a = nib.streamlines.load(sys.argv[1]).streamlines
b = nib.streamlines.load(sys.argv[2]).streamlines
assert len(a) == len(b) == 50, (len(a), len(b))
for x, y in zip(a, b):
    assert np.array_equal(x, y), "a streamline changed through CSV"
print("C++ template loader: 50 streamlines through CSV, bit for bit")
PY

# A new shading model without rebuilding the core: a toon shader from
# tests/fixtures, built against the installed SDK, passes validate and the
# GPU-equals-CPU check, and renders a scene headlessly.
cp -r "$HORIZON_SOURCE_DIR/tests/fixtures/toon_shader" "$work/src-toon"
cmake -S "$work/src-toon" -B "$work/build-toon" -DCMAKE_PREFIX_PATH="$work/sdk" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$work/build-toon" > /dev/null
mkdir -p "$work/toon"
cp "$work/build-toon/toon_shader.so" "$work/toon/"
"$HORIZON_BIN" validate "$work/toon/toon_shader.so" > "$work/report.txt" || { cat "$work/report.txt"; echo "FAIL: validate toon"; exit 1; }
# A hard-edged model (flat bands): GPU equals CPU over a sweep larger than validate's, pixels at the band
# edges allowed only the jump float32 rounding of their inputs can cause (docs/plugins.md).
DISPLAY= gl "$HORIZON_BIN" --plugin-dir "$work/toon" shader-check --shader toon --sets 16 --size 160
cat > "$work/toon.json" <<'JSON'
{"objects": [{"type": "surface", "builtin": "cortex", "color": [0.9, 0.5, 0.2],
              "material": {"shader": "toon", "params": {"bands": 3}}}],
 "environment": {"type": "none"}, "camera": {"view": "left"},
 "lights": [{"type": "directional", "direction": [-0.3, 0.6, 0.7], "intensity": 1.0}], "tonemap": "none"}
JSON
DISPLAY= gl "$HORIZON_BIN" --plugin-dir "$work/toon" render "$work/toon.json" -o "$work/toon.png" --size 240x160 --samples 1 --no-aa > /dev/null
/usr/bin/python3 - "$work/toon.png" <<'PY'
import sys
import numpy as np
from PIL import Image
im = np.asarray(Image.open(sys.argv[1]).convert("RGB")).astype(int)
surf = im[np.abs(im - im[0, 0]).sum(axis=2) > 30]
levels, counts = np.unique(surf[:, 0], return_counts=True)
top3 = np.sort(counts)[::-1][:3].sum() / counts.sum()
assert len(surf) > 5000, len(surf)
assert top3 > 0.97, f"toon shading should give 3 flat levels, got {dict(zip(levels, counts))}"
print(f"toon render: {len(surf)} surface pixels, {100 * top3:.1f}% in the 3 bands")
PY

test "$(sha256sum "$HORIZON_BIN" | cut -d' ' -f1)" = "$host_before"
echo "out-of-tree SDK test: OK"
