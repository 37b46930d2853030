#!/usr/bin/env bash
# hns train across processes (MPI): the same config gives byte-identical checkpoints and the same metrics
# (timings aside) with one process and with 2 or 3 ranks, at any thread count, in quadrant and in full with
# one env per rank (row counts that are not a multiple of 4); a run started with one rank resumes with two
# bit-identically; a non-finite loss stops every rank with status 3 and the last checkpoint kept; SIGUSR1 to
# mpirun stops every rank after the same iteration with a checkpoint; a killed rank (rank 1, then rank 0, the
# one that writes) ends the whole job within seconds with the last checkpoint intact, and the run resumes; a
# bad rank count, ranks started with different configs and ranks that compute in different precisions are
# refused with status 2.
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
grep -q "ranks 2" "$tmp/two.log" && grep -q "communication with and waiting for the other ranks" "$tmp/two.log" && ok ||
  fail "the progress line shows the ranks and the time split the communication"
[ "$(grep -c '^iter ' "$tmp/two.log")" -eq 3 ] && ok || fail "only rank 0 prints progress"

# Full, one env per rank (6 agent rows): rows that are not a multiple of 4 in every rank's inference chunk.
full=(train --scene full --model small --envs 3 --seed 5 --set horizon=30 --set epochs=1 --set minibatches=1
  --set grad_groups=3)
"$hns" "${full[@]}" --iterations 2 --threads 1 --out "$tmp/full1" >/dev/null 2>&1 || fail "full, 1 process"
launch 3 "${full[@]}" --iterations 2 --threads 1 --out "$tmp/full3" >/dev/null 2>&1 || fail "full, 3 ranks"
launch 2 "${full[@]}" --iterations 2 --threads 1 --out "$tmp/full2" >/dev/null 2>&1 || fail "full, 2 ranks"
same_run_n() { cmp -s "$1/checkpoint.bin" "$2/checkpoint.bin" && [ "$(results "$1")" = "$(results "$2")" ] && ok ||
  fail "$3: checkpoints or metrics differ"; }
same_run_n "$tmp/full1" "$tmp/full3" "full: 1 process vs 3 ranks (1 env each)"
same_run_n "$tmp/full1" "$tmp/full2" "full: 1 process vs 2 ranks (1 and 2 envs)"

# bf16 products (where this CPU has AVX512-BF16): the same byte-identity across rank counts.
if grep -qw avx512_bf16 /proc/cpuinfo; then
  "$hns" "${args[@]}" --precision bf16 --iterations 3 --threads 2 --out "$tmp/bf1" >/dev/null 2>&1 || fail "bf16, 1 process"
  launch 3 "${args[@]}" --precision bf16 --iterations 3 --threads 1 --out "$tmp/bf3" >/dev/null 2>&1 || fail "bf16, 3 ranks"
  same_run "$tmp/bf1" "$tmp/bf3" "bf16: 1 process vs 3 ranks"
  grep -q '"precision": "bf16"' "$tmp/bf3/config.json" && ok || fail "bf16 run's config.json names bf16"
    [ "$(results "$tmp/bf1" | sed 's/"precision": "[a-z0-9]*", //')" != "$(results "$tmp/one" | sed 's/"precision": "[a-z0-9]*", //')" ] && ok ||
    fail "bf16 and fp32 runs must train differently"
fi

# Ranks started with different arguments (mpirun's MPMD form): refused before any training.
out="$("$mpirun" --oversubscribe --bind-to none -np 1 "$hns" "${args[@]}" --iterations 1 --out "$tmp/mixed" : \
  -np 1 "$hns" "${args[@]}" --iterations 1 --set lr=0.001 --out "$tmp/mixed" 2>&1)"
rc=$?
[ "$rc" -eq 2 ] && grep -q "rank 1 starts from another config or checkpoint" <<<"$out" && ok ||
  fail "ranks with different configs -> exit $rc: $out"

# Ranks that compute differently (here one in bf16, one in fp32: as `auto` resolves on machines with and
# without AVX512-BF16): refused by name before any training, not as a generic config difference.
if grep -qw avx512_bf16 /proc/cpuinfo; then
  out="$("$mpirun" --oversubscribe --bind-to none -np 1 "$hns" "${args[@]}" --iterations 1 --precision bf16 \
    --out "$tmp/mixedp" : -np 1 "$hns" "${args[@]}" --iterations 1 --precision fp32 --out "$tmp/mixedp" 2>&1)"
  rc=$?
  [ "$rc" -eq 2 ] && grep -q "rank 1 computes in fp32 on the .* build and rank 0 in bf16 on the" <<<"$out" &&
    [ ! -e "$tmp/mixedp" ] && ok || fail "ranks in bf16 and fp32 -> exit $rc: $out"
fi

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

# intrinsic = count keeps state that one process owns whole: refused with 2 ranks, no run folder.
out="$(launch 2 "${args[@]}" --iterations 1 --set intrinsic=count --out "$tmp/count2" 2>&1)"
rc=$?
if [ "$rc" -eq 2 ] && grep -q "intrinsic = count runs in one process (2 ranks given)" <<<"$out" &&
   [ ! -e "$tmp/count2" ]; then ok; else
  fail "intrinsic = count with 2 ranks -> exit $rc: $out"
fi

# The rank of a process of the job started by `launch` for run folder $1 (from its environment).
pid_of_rank() {
  local p
  for p in $(pgrep -f -- "--out $1\$"); do
    if tr '\0' '\n' <"/proc/$p/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$2"; then
      echo "$p"
      return
    fi
  done
}
# Starts a long 2-rank job into $1 and waits until it has written a checkpoint and run 2 iterations.
start_long_job() {
  launch 2 "${args[@]}" --iterations 100000 --threads 1 --set checkpoint_every=1 --out "$1" >"$1.log" 2>&1 &
  job=$!
  for _ in $(seq 1 300); do
    [ -f "$1/checkpoint.bin" ] && [ "$(grep -c '^iter ' "$1.log" 2>/dev/null)" -ge 2 ] && break
    sleep 0.1
  done
}
# Waits up to 30 s for the job; its exit status in $rc.
wait_job() {
  local waited=0
  while kill -0 "$job" 2>/dev/null && [ "$waited" -lt 300 ]; do
    sleep 0.1
    waited=$((waited + 1))
  done
  if kill -0 "$job" 2>/dev/null; then
    fail "$1: the job still runs after 30 s"
    pkill -9 -f -- "--out $2\$"
  fi
  wait "$job"
  rc=$?
}
resumes() {  # resumes DIR WHAT: the run continues one more iteration from its checkpoint
  local done_iters
  done_iters="$(wc -l <"$1/metrics.jsonl")"
  if "$hns" train --resume "$1" --iterations "$((done_iters + 1))" --threads 1 >"$1.after" 2>&1 &&
    grep -q "resuming" "$1.after"; then ok; else
    fail "$2: resume: $(tail -3 "$1.after")"
  fi
}

# A non-finite loss stops every rank alike: each exits 3 by itself after the same iteration (none is ended by
# mpirun for another's status), rank 0 says so, and the last checkpoint (iteration 1) is kept whole.
STATUS_DIR="$tmp" timeout 60 "$mpirun" --oversubscribe --bind-to none -x STATUS_DIR -np 2 \
  bash -c '"$0" "$@"; echo $? >"$STATUS_DIR/rank$OMPI_COMM_WORLD_RANK"' \
  "$hns" "${args[@]}" --iterations 4 --threads 1 --set checkpoint_every=1 --set inject_nan_at=2 --out "$tmp/nan" \
  >"$tmp/nan.log" 2>&1
rc=$?
# (The wrappers exit 0, so mpirun's status is 0 unless a rank was aborted or killed, or the job hung.)
if [ "$rc" -eq 0 ] && ! grep -q "MPI_ABORT" "$tmp/nan.log" &&
   [ "$(cat "$tmp/rank0" 2>/dev/null)" = 3 ] && [ "$(cat "$tmp/rank1" 2>/dev/null)" = 3 ] &&
   [ "$(grep -c "stopped: iteration 2, .*not finite" "$tmp/nan.log")" -eq 1 ] &&
   grep -q "last good checkpoint is kept: .*(iteration 1)" "$tmp/nan.log" &&
   [ "$(wc -l <"$tmp/nan/metrics.jsonl")" -eq 1 ]; then ok; else
  fail "NaN at iteration 2 with 2 ranks: mpirun $rc, ranks $(cat "$tmp/rank0" "$tmp/rank1" 2>&1 | tr '\n' ' '): $(tail -5 "$tmp/nan.log")"
fi
# (Resuming would meet the same NaN: inject_nan_at is part of the run's config. The kept checkpoint is whole.)
"$hns" play --checkpoint "$tmp/nan/checkpoint.bin" --episodes 1 --out "$tmp/nan.traj" >"$tmp/nan.play" 2>&1 && ok ||
  fail "NaN stop: the kept checkpoint does not play: $(tail -3 "$tmp/nan.play")"

# SIGUSR1 to mpirun (forwarded to every rank): all stop after the same iteration, status 130, a checkpoint.
start_long_job "$tmp/stopped"
if kill -0 "$job" 2>/dev/null; then
  kill -USR1 "$(pgrep -f -- "mpirun.*--out $tmp/stopped\$" | head -1)"
  wait_job "SIGUSR1" "$tmp/stopped"
  last="$(grep -c '^iter ' "$tmp/stopped.log")"
  if [ "$rc" -eq 130 ] && grep -q "interrupted after iteration $last; checkpoint written" "$tmp/stopped.log"; then ok; else
    fail "SIGUSR1: status $rc, $(tail -3 "$tmp/stopped.log")"
  fi
  resumes "$tmp/stopped" "SIGUSR1"
else
  fail "the job to stop ended early: $(tail -3 "$tmp/stopped.log")"
fi

# One rank killed (rank 1, then rank 0): every rank ends within seconds, non-zero; the last checkpoint is
# whole and the run resumes.
for victim_rank in 1 0; do
  dir="$tmp/killed$victim_rank"
  start_long_job "$dir"
  victim="$(pid_of_rank "$dir" "$victim_rank")"
  if [ -z "$victim" ] || ! kill -0 "$job" 2>/dev/null; then
    fail "kill rank $victim_rank: no such rank running ($(tail -2 "$dir.log"))"
    continue
  fi
  start=$(date +%s)
  kill -9 "$victim"
  wait_job "kill rank $victim_rank" "$dir"
  echo "killed rank $victim_rank: the job ended after $(($(date +%s) - start)) s with status $rc"
  [ "$rc" -ne 0 ] && ok || fail "a job with a killed rank $victim_rank exited 0"
  resumes "$dir" "kill rank $victim_rank"
done

echo "mpi_test: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
