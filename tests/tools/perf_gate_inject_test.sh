#!/usr/bin/env bash
# End to end: the perf gate builds this source tree twice, once with deliberate extra work in every env step
# (HNS_INJECT_STEP_WORK, about +50 % on the quadrant step: large enough that a disturbed pair on a shared CI machine cannot hide it), and must report a regression (exit 1).
# Usage: perf_gate_inject_test.sh SOURCE_DIR WORK_DIR
set -u
src="$1"
work="$2"
rm -rf "$work"
"$src/tools/perf-gate" --baseline-src "$src" --current-src "$src" \
  --current-cmake-args=-DHNS_INJECT_STEP_WORK=12000 --suite 'bench_physics:BM_WorldStepQuadrant$' \
  --pairs 7 --min-time 0.2 --instructions off --work-dir "$work" --jobs "$(nproc)"
rc=$?
if [ "$rc" -eq 1 ]; then
  echo "1 passed, 0 failed"
  exit 0
fi
echo "perf gate exit status $rc, expected 1 (regression)"
echo "0 passed, 1 failed"
exit 1
