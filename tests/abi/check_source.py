#!/usr/bin/env python3
"""Source compatibility within ABI major 1 (sdk/docs/ABI.md, "Migration"):
the SDK's C templates as released with 1.0 and 1.9 (frozen copies in
tests/abi/v1_0, v1_9) compile against today's headers as C11 and C++17
(-Wall -Wextra -pedantic); a name 1.10 replaced compiles with a deprecation
warning that names its replacement, and nothing else is an error.

Usage: check_source.py CC CXX SDK_INCLUDE ABI_DIR
"""
import os
import re
import subprocess
import sys

cc, cxx, include, here = sys.argv[1:5]
# What each frozen source uses that 1.10 replaced, and the replacement the
# warning must name.
cases = {
    "v1_0/templates/text_loader.c": [],
    "v1_0/templates/lambert_shader.c": [],
    "v1_9/templates/text_loader.c": [("check", "hz.ext.checked-read/1"), ("HZ_LOADER_WRITES_GAP", "hz.ext.delimited-streamlines/1")],
    # (not frozen: the 1.7-1.9 names a C++ loader used, in one file)
    "names_1_9.cpp": [("flags", "hz.ext.mapped-positions/1"), ("HZ_STREAMLINES_OFFSETS_ONLY", "hz.ext.mapped-positions/1"),
                      ("positions_check", "hz.ext.checked-read/1"),
                      ("HZ_LOADER_WRITES_GAP", "hz.ext.delimited-streamlines/1")],
}
failed = 0
for rel, deprecated in cases.items():
    src = os.path.join(here, rel)
    for compiler, lang in ((cc, ["-std=c11"]), (cxx, ["-std=c++20", "-x", "c++"])):
        if (compiler == cxx and rel.endswith("text_loader.c")) or (compiler == cc and rel.endswith(".cpp")):
            continue  # (the C templates' malloc casts are C, not C++)
        cmd = [compiler, *lang, "-Wall", "-Wextra", "-pedantic", "-fsyntax-only", "-I", include, src]
        p = subprocess.run(cmd, capture_output=True, text=True)
        errors = [l for l in p.stderr.splitlines() if " error: " in l]
        warnings = [l for l in p.stderr.splitlines() if "-Wdeprecated-declarations" in l]
        ok = p.returncode == 0 and not errors
        for name, replacement in deprecated:
            # (the name as the compiler spells it: qualified, with a signature)
            named = [w for w in warnings if re.search(r"'[^']*\b" + re.escape(name) + r"\b[^']*' is deprecated", w.replace("‘", "'").replace("’", "'"))]
            if not named or not all(replacement in w for w in named):
                print(f"{rel}: no deprecation warning for {name} naming {replacement}")
                ok = False
        if not deprecated and warnings:
            print(f"{rel}: unexpected deprecation warnings: {warnings[:2]}")
            ok = False
        print(f"{'ok' if ok else 'FAIL'}   {rel} ({os.path.basename(compiler)})")
        if not ok:
            print("\n".join(p.stderr.splitlines()[:20]))
            failed += 1
sys.exit(1 if failed else 0)
