#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) and runs each for
# SECONDS (default 30) from generated seeds; prints the exec counts.
#   tests/fuzz/run.sh [--build-only | --no-build] [SECONDS] [BUILD_DIR]
# --build-only stops once the targets are built; --no-build runs what an
# earlier --build-only built (CI builds them before its mutation check starts
# editing the sources, and runs them beside it).
set -euo pipefail
cd "$(dirname "$0")/../.."
step=all
case "${1:-}" in --build-only) step=build; shift ;; --no-build) step=run; shift ;; esac
secs=${1:-30}
dir=${2:-build-fuzz}
if [ "$step" != run ]; then
  cmake -S . -B "$dir" -DHZ_FUZZ=ON -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_C_COMPILER=clang > "$dir.configure.log" 2>&1 || { cat "$dir.configure.log"; exit 1; }
  cmake --build "$dir" -j"$(nproc)" > /dev/null
  [ "$step" = build ] && exit 0
fi
seeds="$dir/seeds"
rm -rf "$seeds" && /usr/bin/python3 tests/fuzz/make_seeds.py "$seeds"
# OpenImageIO keeps its last error message for the life of the process (not a leak of ours).
export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0"
for t in tck trk trx nifti mgh gifti freesurfer gltf images plyobj; do
  mkdir -p "$dir/corpus/$t"
  log="$dir/fuzz_$t.log"
  # Full stacks for allocations, so the suppression can see OpenImageIO's frames.
  asan=""; [ "$t" = images ] && asan="fast_unwind_on_malloc=0"
  if ! ASAN_OPTIONS="$asan" "$dir/bin/fuzz_$t" -max_total_time="$secs" -rss_limit_mb=2048 -max_len=65536 \
        -artifact_prefix="$dir/crash_${t}_" "$dir/corpus/$t" "$seeds/$t" > "$log" 2>&1; then
    tail -40 "$log"; echo "fuzz_$t: FAILED (artifact in $dir)"; exit 1
  fi
  echo "fuzz_$t: $(grep -Eo 'Done [0-9]+ runs in [0-9]+ second' "$log" | tail -1)"
done
