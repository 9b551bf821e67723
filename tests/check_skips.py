#!/usr/bin/env python3
"""Counts the test methods the last ctest run of a build skipped, and says
why (issue 53: a silent skip, no tckedit, no Xvfb, not root, is a check
that did not run).

    tests/check_skips.py BUILD_DIR

Reads BUILD_DIR/Testing/Temporary/LastTest.log (unittest -v prints each
skip as "test_name (module.Class.test_name) ... skipped 'why'"; Catch2's
skipped cases are not counted: it has none). Prints every skip. Under CI
(the environment variable CI set), where everything a test needs is
installed and ../shared is beside the checkout, any skip fails."""
import os
import re
import sys

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
build = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "build")
log = os.path.join(build, "Testing", "Temporary", "LastTest.log")
if not os.path.exists(log):
    print(f"{log}: no ctest run to read", file=sys.stderr)
    sys.exit(1)
skips = []
with open(log, errors="replace") as f:
    for line in f:
        m = re.search(r"^(\S+) \((\S+)\) \.\.\. skipped '(.*)'$", line.rstrip("\n"))
        if m:
            skips.append((m.group(2), m.group(3)))
print(f"{len(skips)} test methods skipped in the last run of {build}")
for name, why in skips:
    print(f"  skipped {name}: {why}")
if skips and os.environ.get("CI"):
    print("CI runs every test: a skipped one is a failure (install what it needs in .ci/bootstrap)", file=sys.stderr)
    sys.exit(1)
