#!/usr/bin/env bash
# hns train across processes (MPI): the same config gives byte-identical checkpoints and the same metrics
# (timings aside) with one process and with 2 or 3 ranks, at any thread count; a run started with one rank
# resumes with two bit-identically; a killed rank ends the whole job within seconds with the last checkpoint
# intact, and the run resumes; a bad rank count is refused with exit status 2.
# Usage: mpi_test.sh path/to/hns path/to/mpirun
set -u
hns="$1"
mpirun="$2"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
passed=0
failed=0
# CI runs as root in a container: Open MPI needs both to allow it, shared-memory copies without ptrace
# (containers forbid it), and no core binding (two ranks and their threads on two cores).
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
launch() {
  local np="$1"
  shift
  "$mpirun" --oversubscribe --bind-to none -np "$np" "$hns" "$@"
}
ok() { passed=$((passed + 1)); }
fail() {
  failed=$((failed + 1))
  echo "FAIL: $*"
}

# Everything of metrics.jsonl but the timings, one line per iteration.
results() {
  sed -E 's/"(seconds|steps_per_s|time_[a-z]+)": [-0-9.e+]+, ?//g' "$1/metrics.jsonl"
}
same_run() {  # same_run DIR_A DIR_B WHAT
  if cmp -s "$1/checkpoint.bin" "$2/checkpoint.bin" && [ "$(results "$1")" = "$(results "$2")" ] &&
    [ "$(wc -l <"$1/metrics.jsonl")" -ge 3 ]; then
    ok
  else
    fail "$3: checkpoints or metrics differ"
  fi
}

# Quadrant, small model, 6 envs in 3 update blocks, short episodes.
args=(train --scene quadrant --model small --envs 6 --seed 11 --set horizon=40 --set epochs=2
  --set minibatches=2 --set grad_groups=3)
"$hns" "${args[@]}" --iterations 3 --threads 2 --out "$tmp/one" >"$tmp/one.log" 2>&1 || fail "1 process: $(tail -3 "$tmp/one.log")"
launch 2 "${args[@]}" --iterations 3 --threads 1 --out "$tmp/two" >"$tmp/two.log" 2>&1 || fail "2 ranks: $(tail -3 "$tmp/two.log")"
launch 2 "${args[@]}" --iterations 3 --threads 2 --out "$tmp/two2" >"$tmp/two2.log" 2>&1 || fail "2 ranks x 2 threads"
launch 3 "${args[@]}" --iterations 3 --threads 1 --out "$tmp/three" >"$tmp/three.log" 2>&1 || fail "3 ranks"
same_run "$tmp/one" "$tmp/two" "1 process x 2 threads vs 2 ranks x 1 thread"
same_run "$tmp/one" "$tmp/two2" "1 process vs 2 ranks x 2 threads"
same_run "$tmp/one" "$tmp/three" "1 process vs 3 ranks"
grep -q "ranks 2" "$tmp/two.log" && grep -q "communication with the other ranks" "$tmp/two.log" && ok ||
  fail "the progress line shows the ranks and the time split the communication"
[ "$(grep -c '^iter ' "$tmp/two.log")" -eq 3 ] && ok || fail "only rank 0 prints progress"

# Started with one process, resumed with two ranks: the same as the uninterrupted run.
"$hns" "${args[@]}" --iterations 2 --threads 1 --out "$tmp/resumed" >/dev/null 2>&1 || fail "first leg"
launch 2 train --resume "$tmp/resumed" --iterations 3 --threads 1 >"$tmp/resume.log" 2>&1 ||
  fail "resume with 2 ranks: $(tail -3 "$tmp/resume.log")"
same_run "$tmp/one" "$tmp/resumed" "1 process then 2 ranks (resume)"

# More ranks than update blocks: exit 2 naming the problem, no run folder.
out="$(launch 4 "${args[@]}" --iterations 1 --out "$tmp/bad" 2>&1)"
rc=$?
if [ "$rc" -eq 2 ] && grep -q "4 ranks for 3 update blocks" <<<"$out" && [ ! -e "$tmp/bad" ]; then ok; else
  fail "4 ranks for 3 blocks -> exit $rc: $out"
fi

# One rank killed: every rank ends within seconds, non-zero; the last checkpoint is whole and resumes.
launch 2 "${args[@]}" --iterations 1000 --threads 1 --set checkpoint_every=1 --out "$tmp/killed" \
  >"$tmp/killed.log" 2>&1 &
job=$!
for _ in $(seq 1 300); do
  [ -f "$tmp/killed/checkpoint.bin" ] && [ "$(grep -c '^iter ' "$tmp/killed.log")" -ge 2 ] && break
  sleep 0.1
done
victim="$(pgrep -f -- "--out $tmp/killed" | grep -v "^$job\$" | tail -1)"
start=$(date +%s)
kill -9 "$victim" 2>/dev/null
waited=0
while kill -0 "$job" 2>/dev/null && [ "$waited" -lt 300 ]; do
  sleep 0.1
  waited=$((waited + 1))
done
if kill -0 "$job" 2>/dev/null; then
  fail "the job still runs 30 s after one rank was killed"
  pkill -9 -f -- "--out $tmp/killed"
fi
wait "$job"
rc=$?
echo "killed rank: the job ended after $(($(date +%s) - start)) s with status $rc"
[ "$rc" -ne 0 ] && ok || fail "a job with a killed rank exited 0"
done_iters="$(grep -c '^iter ' "$tmp/killed.log")"
if "$hns" train --resume "$tmp/killed" --iterations "$((done_iters + 1))" --threads 1 >"$tmp/after.log" 2>&1 &&
  grep -q "resuming" "$tmp/after.log"; then ok; else
  fail "resume after the kill: $(tail -3 "$tmp/after.log")"
fi

echo "mpi_test: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
