#!/usr/bin/env bash
# Builds mbdae with AddressSanitizer and UndefinedBehaviorSanitizer into a build tree of its
# own (build-asan/ unless MBDAE_ASAN_BUILD names another) and runs the whole CTest suite in
# it. Any sanitizer report fails the test that caused it: UBSan stops at the first finding
# (-fno-sanitize-recover), ASan exits 1 and LeakSanitizer 23.
#
#   scripts/sanitize.sh                 configure, build everything, run every test
#   scripts/sanitize.sh -R python.      extra arguments go to ctest (here: a subset)
#   MBDAE_ASAN_TARGETS="mbdae mbdae_python" scripts/sanitize.sh -R '^app\.'
#                                       build only these targets, run only these tests
#
# Environment: MBDAE_ASAN_BUILD (build directory), MBDAE_ASAN_JOBS (parallel build and
# test jobs, default: the number of processors), MBDAE_ASAN_TARGETS (build targets;
# default: all), MBDAE_ASAN_TIMEOUT_FACTOR (the tests' time limits are multiplied by it,
# default 3). See docs/development.md.
set -euo pipefail
cd "$(dirname "$0")/.."
source_dir=$(pwd)
build_dir=${MBDAE_ASAN_BUILD:-$source_dir/build-asan}
jobs=${MBDAE_ASAN_JOBS:-$(nproc 2>/dev/null || echo 2)}

flags="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer -g"
# RelWithDebInfo: optimised (the verification studies would time out at -O0) with line
# numbers in the reports. Benchmarks are not tests and are left out. The Google Test
# programs are asked for their tests when ctest runs (PRE_TEST), not at the end of the
# build, where the slower instrumented programs exceeded the 5 s discovery limit.
cmake -S "$source_dir" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DMBDAE_PYTHON=/usr/bin/python3 -DMBDAE_BUILD_BENCHMARKS=OFF \
  -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_MODULE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_GTEST_DISCOVER_TESTS_DISCOVERY_MODE=PRE_TEST >/dev/null
# shellcheck disable=SC2086 # a list of target names
cmake --build "$build_dir" -j "$jobs" ${MBDAE_ASAN_TARGETS:+--target $MBDAE_ASAN_TARGETS}

# The instrumented programs are slower: every time limit of the tests (their TIMEOUT
# properties, in the CTest files of the build tree and in the Google Test discovery
# scripts, and the discovery limits) is multiplied by MBDAE_ASAN_TIMEOUT_FACTOR. CTest
# has no multiplier of its own (--timeout and CTEST_TEST_TIMEOUT only set the limit of
# tests without one); the files are generated again by every configure, so this is
# applied after the build, to the files this run uses.
factor=${MBDAE_ASAN_TIMEOUT_FACTOR:-3}
find "$build_dir" \( -name CTestTestfile.cmake -o -name '*_include.cmake' \) -print0 |
  MBDAE_FACTOR=$factor /usr/bin/python3 -c '
import os, re, sys
factor = float(os.environ["MBDAE_FACTOR"])
if not factor > 0:
    sys.exit("MBDAE_ASAN_TIMEOUT_FACTOR must be a number > 0")
scale = lambda m: m.group(1) + "%g" % (float(m.group(2)) * factor) + m.group(3)
for name in sys.stdin.read().split("\0"):
    if not name:
        continue
    text = open(name).read()
    new = re.sub(r"(\bTIMEOUT \x22)([0-9.]+)(\x22)", scale, text)  # CTestTestfile.cmake
    new = re.sub(r"(\bTIMEOUT;)([0-9.]+)(\b)", scale, new)  # gtest TEST_PROPERTIES
    new = re.sub(r"(TEST_DISCOVERY_TIMEOUT \[==\[)([0-9.]+)(\]==\])", scale, new)
    if new != text:
        open(name, "w").write(new)'

# detect_leaks is on for every program; the Python interpreter's own allocations still
# alive at exit are not leaks of ours (lsan-python.supp).
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=0"
export UBSAN_OPTIONS="print_stacktrace=1"

# Python loads libmbdae.so (built with ASan) through ctypes, so the ASan runtime has to be
# the first library of the interpreter process: those tests run with it preloaded.
# Everything else (the test programs, mbdae, cmake -P scripts) runs without preloading.
python_tests=$(ctest --test-dir "$build_dir" --show-only=json-v1 |
  /usr/bin/python3 -c '
import json, os, sys
tests = json.load(sys.stdin)["tests"]
names = [t["name"] for t in tests
         if t.get("command") and os.path.basename(t["command"][0]).startswith("python")]
print("|".join("^" + n.replace(".", "\\.") + "$" for n in names))')

asan_runtime=$(gcc -print-file-name=libasan.so)
cxx_runtime=$(gcc -print-file-name=libstdc++.so.6)
status=0
ctest --test-dir "$build_dir" -j "$jobs" --output-on-failure \
  ${python_tests:+-E "$python_tests"} "$@" || status=1
if [ -n "$python_tests" ]; then
  LD_PRELOAD="$asan_runtime $cxx_runtime" \
  LSAN_OPTIONS="suppressions=$source_dir/scripts/lsan-python.supp:print_suppressions=0" \
    ctest --test-dir "$build_dir" -j "$jobs" --output-on-failure \
      -R "$python_tests" "$@" || status=1
fi
exit $status
