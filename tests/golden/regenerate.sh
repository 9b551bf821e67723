#!/usr/bin/env bash
# Regenerates the golden pictures of tests/scripts/test_render.py from the
# current build. Run only after checking the new pictures by eye:
#   tests/golden/regenerate.sh [build-dir]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
export HORIZON_BIN="$PWD/$build/bin/horizon" HORIZON_SOURCE_DIR="$PWD"
/usr/bin/python3 - <<'PY'
import json, os, subprocess, sys, tempfile
sys.path.insert(0, "tests/scripts")
from test_render import golden_scenes
for name, scene in golden_scenes().items():
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(scene, f)
    out = os.path.join("tests", "golden", name + ".png")
    subprocess.run([os.environ["HORIZON_BIN"], "render", f.name, "-o", out, "--size", "200x150", "--force"], check=True, env={**os.environ, "DISPLAY": ""})
    os.unlink(f.name)
    print("wrote", out)
PY
