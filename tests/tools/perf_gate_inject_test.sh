#!/usr/bin/env bash
# End to end: the perf gate builds this source tree twice, once with deliberate extra work in every env step
# (HNS_INJECT_STEP_WORK, +60 to +90 % on the quadrant step: large enough that a disturbed pair on a shared CI
# machine cannot hide it; 12000 iterations measured only +25 % on the 2-core VM on 2026-11-25, where 10 %
# noise per pair then left the gate undecided). Passes only on the gate's regression verdict: exit status 1 *and* the injected
# benchmark judged a regression in gate.json (a crash, exit 3, or a build failure, exit 2, fails the test).
# Usage: perf_gate_inject_test.sh SOURCE_DIR WORK_DIR
set -u
src="$1"
work="$2"
rm -rf "$work"
"$src/tools/perf-gate" --baseline-src "$src" --current-src "$src" \
  --current-cmake-args=-DHNS_INJECT_STEP_WORK=30000 --suite 'bench_physics:^BM_WorldStepQuadrant$' \
  --pairs 4 --max-pairs 10 --min-time 0.2 --instructions off --work-dir "$work" --jobs "$(nproc)"
rc=$?
if [ "$rc" -eq 1 ] && python3 - "$work/report/gate.json" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
rows = {r["benchmark"]: r for r in report["rows"]}
row = rows.get("BM_WorldStepQuadrant", {})
ok = report["exit_status"] == 1 and row.get("verdict") == "regression" and row.get("ratio", 0) > 1.2 \
    and not report["crashes"]
print(f"gate.json: BM_WorldStepQuadrant {row.get('verdict')} ratio {row.get('ratio')}; crashes {report['crashes']}")
sys.exit(0 if ok else 1)
PY
then
  echo "1 passed, 0 failed"
  exit 0
fi
echo "perf gate exit status $rc; expected 1 with BM_WorldStepQuadrant judged a regression"
echo "0 passed, 1 failed"
exit 1
