#!/usr/bin/env bash
# The whole test suite while busy processes hold the cores (a shared CI runner, a laptop with a
# build going on): no test may fail because the machine is busy.
# Usage: bash tools/test-under-load.sh [pytest arguments, as for tools/test.sh]
#   BUSY=N         busy processes (default 2: both cores of a 2-core machine)
#   BUSY_MAX_S=S   each busy process ends by itself after S seconds (default 3600)
#   TEST_SH=path   the suite's script (default tools/test.sh)
# Exits with the suite's status.  The busy processes are stopped when this script ends, however
# it ends (and end by themselves when it is killed outright, or after BUSY_MAX_S).
set -uo pipefail
cd "$(dirname "$0")/.."
BUSY="${BUSY:-2}"
BUSY_MAX_S="${BUSY_MAX_S:-3600}"
TEST_SH="${TEST_SH:-tools/test.sh}"

# a busy loop that checks, every few million iterations, that this script still runs and that
# its time is not up
BUSY_LOOP='
import os, sys, time
parent, end, i = os.getppid(), time.monotonic() + float(sys.argv[1]), 0
while True:
    i += 1
    if i % 5_000_000 == 0 and (os.getppid() != parent or time.monotonic() > end):
        break
'
pids=()
stop_busy() {
  local pid
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null; done
  pids=()
}
trap stop_busy EXIT
trap 'exit 130' INT
trap 'exit 143' TERM HUP

for _ in $(seq "$BUSY"); do
  python3 -c "$BUSY_LOOP" "$BUSY_MAX_S" &
  pids+=("$!")
done
echo "test-under-load: $BUSY busy processes (pids ${pids[*]}) on $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2
start=$(date +%s)
bash "$TEST_SH" "$@"
rc=$?
echo "test-under-load: the suite exited with status $rc after $(( $(date +%s) - start )) s" >&2
exit "$rc"
