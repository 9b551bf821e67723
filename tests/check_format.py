#!/usr/bin/env python3
"""Fails when a C or C++ source of the repository is not in the house style
(.clang-format, clang-format 14: Debian's clang-format-14), naming each file
and the first line that differs.

    tests/check_format.py          check (exit 1 on a difference)
    tests/check_format.py --fix    reformat the files in place

Not checked: the public SDK headers (sdk/include/hz/*.h), whose column-aligned
field tables are contract documents laid out by hand, and tests/abi/v1_0 (the
SDK as first published, frozen) and tests/abi/v1_9 (1.9, frozen). Without clang-format-14
the check exits 77 (CTest: skipped), except in CI (CI set), where a missing
tool is a failure."""
import difflib
import os
import shutil
import subprocess
import sys

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
tool = shutil.which("clang-format-14") or shutil.which("clang-format")
if tool is None or (os.path.basename(tool) == "clang-format" and
                    "version 14." not in subprocess.run([tool, "--version"], capture_output=True, text=True).stdout):
    print("clang-format 14 is not installed (apt-get install clang-format-14)", file=sys.stderr)
    sys.exit(1 if os.environ.get("CI") else 77)
files = subprocess.run(["git", "-C", root, "ls-files", "*.c", "*.h", "*.cpp", "*.hpp"], capture_output=True, text=True,
                       check=True).stdout.split()
files = [f for f in files if not f.startswith(("sdk/include/hz/", "tests/abi/v1_0/", "tests/abi/v1_9/"))]
fix = "--fix" in sys.argv[1:]
bad = 0
for f in files:
    path = os.path.join(root, f)
    if fix:
        subprocess.run([tool, "-i", "--style=file", path], check=True)
        continue
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    formatted = subprocess.run([tool, "--style=file", f"--assume-filename={path}"], input=text, capture_output=True, text=True,
                               check=True).stdout
    if formatted != text:
        bad += 1
        a, b = text.splitlines(), formatted.splitlines()
        first = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
        print(f"{f}:{first + 1}: not in the house style (tests/check_format.py --fix)")
        for line in list(difflib.unified_diff(a, b, lineterm="", n=0))[2:8]:
            print("    " + line)
print(f"{len(files)} files checked, {bad} not formatted" if not fix else f"{len(files)} files formatted")
sys.exit(1 if bad else 0)
