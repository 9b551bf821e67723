#!/usr/bin/env python3
"""The mutation check: every declared mutant of real logic must be caught.

    tests/mutation/run.py [BUILD_DIR] [--only=ID,...] [--shard=K/N | --shard=auto]

For each mutant of tests/mutation/mutants.json: the snippet is replaced in the
source (it must occur exactly once: a stale list fails), the mutant's target
is rebuilt incrementally in BUILD_DIR (an already built tree: `build`), and its
tests run (ctest's command and environment for the named test, narrowed with
unittest's -k where given). The mutant is caught if any of them fails. First,
each of those tests runs unmutated: one that fails three times then would
"catch" every mutant, so it is reported (broken) instead; one that passes
on a second or third run is named flaky. The source is restored
after each mutant, whatever happens, and the touched targets are rebuilt at
the end. Exit status 1 if a mutant survived or could not be applied, or a
test failed unmutated. Meant for a scratch checkout (CI's clean clone).

--shard=K/N runs the mutants whose position in the list is K modulo N;
--shard=auto is K/10 with K HEAD's commit count modulo 10, so that ten
consecutive commits check the ten tenths (CI: each mutant costs a rebuild
of its source, 15-20 s alone and 35-45 s beside the sanitized suite: a third
of 277 mutants, 93, took over an hour of CI's time, its longest lane; a
sixth, 46, 25-28 minutes, longer than the sanitized suite beside it). A new
or changed mutant is run by its author with --only before it is committed.
Without --shard, every mutant.
"""
import json
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def ctest_tests(build):
    out = subprocess.run(["ctest", "--test-dir", build, "--show-only=json-v1"], capture_output=True, text=True, check=True).stdout
    tests = {}
    for t in json.loads(out)["tests"]:
        props = {p["name"]: p["value"] for p in t.get("properties", [])}
        tests[t["name"]] = (t["command"], props.get("WORKING_DIRECTORY"), props.get("ENVIRONMENT", []))
    return tests


def run_test(tests, name, k, timeout=900):
    command, cwd, env_list = tests[name]
    # The scale tests at 300k streamlines instead of 1M: the same paths
    # (chunks, threads, copies) at a third of the time, once per mutant.
    # (The Release suite runs them at 1M; at 100k the background work ends
    # before the frames the tests watch for.)
    env = {**os.environ, "HORIZON_SCALE_STREAMLINES": "300000"}
    for kv in env_list:
        key, _, value = kv.partition("=")
        env[key] = value
    cmd = list(command) + (["-k", k] if k else [])
    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    return p.returncode


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    only, shard = None, None
    for a in sys.argv[1:]:
        if a.startswith("--only="):
            only = set(a.split("=", 1)[1].split(","))
        elif a == "--shard=auto":
            count = subprocess.run(["git", "-C", ROOT, "rev-list", "--count", "HEAD"], capture_output=True, text=True, check=True)
            shard = (int(count.stdout) % 10, 10)
        elif a.startswith("--shard="):
            k, n = a.split("=", 1)[1].split("/")
            shard = (int(k), int(n))
            if not 0 <= shard[0] < shard[1]:
                sys.exit(f"--shard={k}/{n}: K must be in [0, N)")
        elif a.startswith("--"):
            sys.exit(f"unknown option {a}")
    build = os.path.abspath(args[0] if args else os.path.join(ROOT, "build"))
    with open(os.path.join(ROOT, "tests", "mutation", "mutants.json")) as f:
        mutants = json.load(f)["mutants"]
    tests = ctest_tests(build)
    if only:
        mutants = [m for m in mutants if m["id"] in only]
    if shard:
        every = len(mutants)
        mutants = [m for i, m in enumerate(mutants) if i % shard[1] == shard[0]]
        print(f"shard {shard[0]}/{shard[1]}: {len(mutants)} of the {every} mutants", flush=True)
    survived, broken, targets = [], [], set()
    t_all = time.time()
    # The baseline: each test of these mutants, unmutated, up to three times
    # (the scale tests' window watches frames go by while work runs in the
    # background: beside the sanitized suite, one run in a few can miss).
    failing = set()
    for name, k in sorted({(name, k or "") for m in mutants for name, k in m["tests"] if name in tests}):
        passed_on = next((run for run in (1, 2, 3) if run_test(tests, name, k) == 0), None)
        if passed_on is None:
            failing.add((name, k))
            print(f"BROKEN   {name}{' -k ' + k if k else ''} fails unmutated (three times)", flush=True)
        elif passed_on > 1:
            print(f"flaky    {name}{' -k ' + k if k else ''} passed unmutated on run {passed_on}", flush=True)
    print(f"baseline: {len(failing)} of the mutants' tests fail unmutated ({time.time() - t_all:.0f} s)", flush=True)
    for m in mutants:
        t0 = time.time()
        path = os.path.join(ROOT, m["file"])
        with open(path) as f:
            original = f.read()
        if original.count(m["find"]) != 1:
            broken.append(f"{m['id']}: the snippet occurs {original.count(m['find'])} times in {m['file']}")
            print(f"BROKEN   {m['id']}: snippet found {original.count(m['find'])} times", flush=True)
            continue
        missing = [t for t, _ in m["tests"] if t not in tests]
        failed_before = [f"{t}{' -k ' + k if k else ''}" for t, k in m["tests"] if (t, k or "") in failing]
        if failed_before:
            broken.append(f"{m['id']}: its tests fail unmutated: {failed_before}")
            continue
        if missing:
            broken.append(f"{m['id']}: no test named {missing}")
            print(f"BROKEN   {m['id']}: no test {missing}", flush=True)
            continue
        targets.add(m["target"])
        try:
            with open(path, "w") as f:
                f.write(original.replace(m["find"], m["replace"]))
            b = subprocess.run(["cmake", "--build", build, "--target", m["target"], "-j", str(os.cpu_count() or 2)], capture_output=True,
                               text=True)
            if b.returncode != 0:
                broken.append(f"{m['id']}: the mutant does not build:\n{b.stdout[-2000:]}{b.stderr[-2000:]}")
                print(f"BROKEN   {m['id']}: does not build", flush=True)
                continue
            t_built = time.time()
            caught_by = None
            for name, k in m["tests"]:
                if run_test(tests, name, k) != 0:
                    caught_by = f"{name}{' -k ' + k if k else ''}"
                    break
        finally:
            with open(path, "w") as f:
                f.write(original)
        status = f"caught by {caught_by}" if caught_by else "SURVIVED"
        print(f"{'ok      ' if caught_by else 'SURVIVED'} {m['id']}: {status} ({t_built - t0:.0f} s build, {time.time() - t_built:.0f} s tests)", flush=True)
        if not caught_by:
            survived.append(m["id"])
    for t in sorted(targets):  # the unmutated build again
        subprocess.run(["cmake", "--build", build, "--target", t, "-j", str(os.cpu_count() or 2)], capture_output=True, check=True)
    print(f"mutation check: {len(mutants) - len(survived) - len(broken)} caught, {len(survived)} survived, {len(broken)} broken "
          f"({time.time() - t_all:.0f} s)")
    for b in broken:
        print("  " + b)
    return 1 if survived or broken else 0


if __name__ == "__main__":
    sys.exit(main())
