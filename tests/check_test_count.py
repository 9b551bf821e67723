#!/usr/bin/env python3
"""Fails when the build registers fewer tests than expected (a test that
silently stops being registered, as the two TRK tests whose names held ';'
once did, is a defect).

    tests/check_test_count.py BUILD_DIR

Expected: tests/expected_test_count.txt, plus the two tests of the public BRDF
vectors when ../shared/brdf exists beside the checkout."""
import json
import os
import subprocess
import sys

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
build = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "build")
with open(os.path.join(root, "tests", "expected_test_count.txt")) as f:
    expected = int(f.read().split()[0])
if os.path.isdir(os.path.join(root, "..", "shared", "brdf")):
    expected += 2
out = subprocess.run(["ctest", "--test-dir", build, "--show-only=json-v1"], capture_output=True, text=True, check=True).stdout
names = [t["name"] for t in json.loads(out)["tests"]]
print(f"{len(names)} tests registered in {build}, {expected} expected")
if len(names) != expected:
    print("test count differs from tests/expected_test_count.txt (update it when adding or removing a test)", file=sys.stderr)
    sys.exit(1)
