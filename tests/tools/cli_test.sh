#!/usr/bin/env bash
# The hns command line: bad input exits 2 with a message naming the problem; a short bench run writes the
# documented JSON fields. Usage: cli_test.sh path/to/hns
set -u
hns="$1"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
passed=0
failed=0

# expect_fail CODE PATTERN ARGS...: the command exits CODE and its output matches PATTERN.
expect_fail() {
  local code="$1" pattern="$2"
  shift 2
  local out rc
  out="$("$hns" "$@" 2>&1)"
  rc=$?
  if [ "$rc" -eq "$code" ] && grep -q -E -- "$pattern" <<<"$out"; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL: hns $* -> exit $rc (want $code), output: $out"
  fi
}

expect_fail 2 "scene" bench --scene nowhere
expect_fail 2 "envs" bench --envs -3
expect_fail 2 "threads" bench --threads 0
expect_fail 2 "boxes" bench --scene quadrant --boxes 40
expect_fail 2 "boxes.max = 20" bench --scene quadrant --boxes 20
expect_fail 2 "hiders" bench --hiders 0 --seekers 0
expect_fail 2 "" bench --no-such-flag
expect_fail 2 "" frobnicate

# A short real run writes the JSON figures, and no temporary file is left behind.
if "$hns" bench --scene full --envs 2 --steps 20 --json "$tmp/out.json" >"$tmp/log" 2>&1 &&
   grep -q '"env_steps_per_s"' "$tmp/out.json" && grep -q '"agent_steps_per_s"' "$tmp/out.json" &&
   grep -q '"phases"' "$tmp/out.json" && grep -q '"scene": "full"' "$tmp/out.json" &&
   [ ! -e "$tmp/out.json.tmp" ] && grep -q "env-steps/s" "$tmp/log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: bench --json run"; cat "$tmp/log"; cat "$tmp/out.json" 2>/dev/null
fi
# The network benchmark writes its documented fields.
has_fields() {
  local file="$1"
  shift
  for f in "$@"; do grep -q "\"$f\"" "$file" || return 1; done
}
if "$hns" bench --nn small --json "$tmp/nn.json" >"$tmp/log" 2>&1 &&
   has_fields "$tmp/nn.json" model threads params infer_agent_steps_per_s train_agent_steps_per_s \
     infer_gflops train_gflops gemm_gflops; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: bench --nn run"; cat "$tmp/log"
fi
expect_fail 2 "nn" bench --nn huge
# A profiled run writes a Chrome trace with one event per env, step and phase.
if "$hns" bench --scene quadrant --envs 2 --steps 5 --profile "$tmp/trace.json" >"$tmp/log" 2>&1 &&
   grep -q '"traceEvents"' "$tmp/trace.json" && [ "$(grep -o '"ph":"X"' "$tmp/trace.json" | wc -l)" -eq 40 ]; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: bench --profile run"; cat "$tmp/log"
fi
expect_fail 2 "profile" bench --envs 100000 --steps 1000 --profile "$tmp/huge.json"
# An unwritable JSON path fails with status 1 and says so.
expect_fail 1 "cannot write" bench --envs 1 --steps 1 --json "$tmp/missing-dir/out.json"

# play / replay: bad flags and files exit 2 naming the problem; nothing is half-written.
expect_fail 2 "scene" play --scene nowhere --out "$tmp/x.traj"
expect_fail 2 "episodes" play --episodes 0 --out "$tmp/x.traj"
expect_fail 2 "envs" play --envs 0 --out "$tmp/x.traj"
expect_fail 2 "out" play --scene quadrant
expect_fail 2 "hiders" play --hiders 0 --seekers 0 --out "$tmp/x.traj"
expect_fail 2 "checkpoints need the trainer \(not built yet\)" play --checkpoint "$tmp/model.ckpt" --out "$tmp/x.traj"
expect_fail 2 "excludes" play --random --checkpoint "$tmp/model.ckpt" --out "$tmp/x.traj"
expect_fail 1 "cannot write" play --out "$tmp/missing-dir/x.traj"
expect_fail 2 "html" replay "$tmp/x.traj"
expect_fail 2 "cannot read" replay "$tmp/nothing.traj" --html "$tmp/x.html"
printf 'not a trajectory at all' >"$tmp/garbage.traj"
expect_fail 2 "bad trajectory file.*not an hns trajectory" replay "$tmp/garbage.traj" --html "$tmp/x.html"
if [ -e "$tmp/x.traj" ] || [ -e "$tmp/x.html" ] || [ -e "$tmp/x.html.tmp" ]; then
  failed=$((failed + 1))
  echo "FAIL: a failed play/replay left a file behind"; ls -la "$tmp"
else
  passed=$((passed + 1))
fi

# A real recording replays into one self-contained page; a truncated copy is refused with the reason.
if "$hns" play --scene quadrant --episodes 2 --envs 2 --seed 4 --out "$tmp/q.traj" >"$tmp/log" 2>&1 &&
   [ ! -e "$tmp/q.traj.tmp" ] && grep -q "env 1 episode 0" "$tmp/log" &&
   "$hns" replay "$tmp/q.traj" --html "$tmp/q.html" >>"$tmp/log" 2>&1 &&
   [ ! -e "$tmp/q.html.tmp" ] && grep -q '<canvas id="view"' "$tmp/q.html" && ! grep -q 'https\?://' "$tmp/q.html"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: play + replay run"; cat "$tmp/log"
fi
head -c 5000 "$tmp/q.traj" >"$tmp/cut.traj"
expect_fail 2 "episode 0.*truncated" replay "$tmp/cut.traj" --html "$tmp/cut.html"
[ -e "$tmp/cut.html" ] && { failed=$((failed + 1)); echo "FAIL: replay of a truncated file wrote a page"; }

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
