#!/usr/bin/env bash
# Runs every verification script against build/mbdae (or $MBDAE, or the first argument).
# Exit status: the number of failed items (0: all passed).
set -u
cd "$(dirname "$0")/.."
if [ $# -ge 1 ]; then export MBDAE="$1"; fi
: "${MBDAE:=build/mbdae}"
export MBDAE
PY="${PYTHON:-/usr/bin/python3}"
[ -x "$PY" ] || PY=python3
failed=0
run() {
  echo "=== $*"
  if "$PY" "$@"; then echo "--- ok"; else echo "--- FAILED: $*"; failed=$((failed + 1)); fi
}
run verification/andrews/check_geometry.py
run verification/pendulum/run.py
run verification/free_body/run.py
run verification/bricard/run.py
run verification/andrews/run.py
run verification/oscillator/run.py
run verification/crank_motion/run.py
run verification/gear/run.py
lib="$(dirname "$MBDAE")/examples/user_force/libmbdae_spring_damper.so"
[ -f "$lib" ] && run verification/user_force/run.py --mbdae "$MBDAE" --library "$lib"
if [ -x verification/malformed/run.sh ]; then
  echo "=== verification/malformed/run.sh"
  if verification/malformed/run.sh; then echo "--- ok"; else echo "--- FAILED: malformed"; failed=$((failed + 1)); fi
elif [ -f verification/malformed/run.py ]; then
  run verification/malformed/run.py
fi
echo "verification: $failed failed"
exit "$failed"
