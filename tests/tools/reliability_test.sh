#!/usr/bin/env bash
# Hostile and careless input to the hns command line (README "Reliability"): special files are refused rather
# than read or replaced, writes do not follow links planted in a run folder, a run folder has one writer, a
# damaged metrics row does not take the rows after it, and every form of a bad value exits 2 before any work.
# Usage: reliability_test.sh path/to/hns
set -u
hns="$1"
tmp="$(mktemp -d)"
pids=()
trap 'for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done; rm -rf "$tmp"' EXIT
passed=0
failed=0

ok() { passed=$((passed + 1)); }
fail() {
  failed=$((failed + 1))
  echo "FAIL: $*"
}

# expect_fail CODE PATTERN ARGS...: the command exits CODE within 20 s (a read that blocks on a FIFO would
# hang) and its output matches PATTERN.
expect_fail() {
  local code="$1" pattern="$2"
  shift 2
  local out rc
  out="$(timeout 20 "$hns" "$@" 2>&1 </dev/null)"
  rc=$?
  if [ "$rc" -eq "$code" ] && grep -q -E -- "$pattern" <<<"$out"; then
    ok
  else
    fail "hns $* -> exit $rc (want $code, output matching '$pattern'), output: $(head -c 600 <<<"$out")"
  fi
}

echo '{"scene": "lockbox", "envs": 4, "epochs": 1, "minibatches": 2}' >"$tmp/train.json"
train_small() { "$hns" train --config "$tmp/train.json" --threads 1 "$@"; }
resume() { "$hns" train --threads 1 --resume "$@"; }
if ! train_small --iterations 2 --out "$tmp/run" >"$tmp/log" 2>&1; then
  echo "FAIL: setting up a short run"; cat "$tmp/log"
  exit 1
fi
"$hns" play --scene quadrant --episodes 1 --out "$tmp/q.traj" >/dev/null 2>&1 || { echo "FAIL: play"; exit 1; }

# --- Special files are refused (item 5): a FIFO would block the reader forever, /dev/zero never ends.
mkfifo "$tmp/fifo"
expect_fail 2 "--config .*fifo.*not a regular file" train --config "$tmp/fifo" --out "$tmp/x1"
expect_fail 2 "--config /dev/zero.*not a regular file" train --config /dev/zero --out "$tmp/x1"
expect_fail 2 "fifo.*not a regular file" play --checkpoint "$tmp/fifo" --out "$tmp/x.traj"
expect_fail 2 "fifo.*not a regular file" replay "$tmp/fifo" --html "$tmp/x.html"
expect_fail 2 "/dev/zero.*not a regular file" replay /dev/zero --html "$tmp/x.html"
for f in checkpoint.bin config.json; do
  cp -r "$tmp/run" "$tmp/special-$f"
  rm "$tmp/special-$f/$f"
  mkfifo "$tmp/special-$f/$f"
  expect_fail 2 "$f.*not a regular file" train --resume "$tmp/special-$f"
done
cp -r "$tmp/run" "$tmp/special-metrics"
rm "$tmp/special-metrics/metrics.jsonl"
mkfifo "$tmp/special-metrics/metrics.jsonl"
expect_fail 2 "metrics.jsonl.*not a regular file" report "$tmp/special-metrics" --html "$tmp/x.html"
# A config file far beyond any config's size is refused by its size, not read whole.
head -c 20000000 /dev/zero | tr '\0' ' ' >"$tmp/huge.json"
expect_fail 2 "huge.json.*larger than" train --config "$tmp/huge.json" --out "$tmp/x1"
[ -e "$tmp/x1" ] && fail "a refused --config created its run folder"

# --- Writers do not replace special files (item 10), and refuse before any work.
expect_fail 2 "--out .*fifo.*not a regular file" play --scene quadrant --out "$tmp/fifo"
expect_fail 2 "--json .*fifo.*not a regular file" bench --envs 1 --steps 1 --json "$tmp/fifo"
expect_fail 2 "--html .*fifo.*not a regular file" replay "$tmp/q.traj" --html "$tmp/fifo"
expect_fail 2 "--profile .*fifo.*not a regular file" bench --envs 1 --steps 1 --profile "$tmp/fifo"
[ -p "$tmp/fifo" ] && ok || fail "the FIFO was replaced"

# --- Atomic writes do not follow a link planted as PATH.tmp (item 2).
cp -r "$tmp/run" "$tmp/linked"
echo "precious" >"$tmp/precious"
ln -s "$tmp/precious" "$tmp/linked/config.json.tmp"
ln -s "$tmp/precious" "$tmp/linked/checkpoint.bin.tmp"
if resume "$tmp/linked" --iterations 3 >"$tmp/log" 2>&1 &&
   [ "$(cat "$tmp/precious")" = "precious" ] && [ ! -L "$tmp/linked/config.json" ] &&
   [ ! -L "$tmp/linked/checkpoint.bin" ] && grep -q '"scene": "lockbox"' "$tmp/linked/config.json"; then
  ok
else
  fail "a link planted as config.json.tmp / checkpoint.bin.tmp was followed: $(cat "$tmp/precious" | head -c 100)"
  cat "$tmp/log"
fi

# --- One writer per run folder (item 4): a second hns train into a folder that a running one uses is
# refused at start, naming the first one's process; the first run is not disturbed.
"$hns" train --config "$tmp/train.json" --threads 1 --iterations 100000 --out "$tmp/busy" >"$tmp/busy.log" 2>&1 &
busy=$!
pids+=("$busy")
for _ in $(seq 1200); do [ -s "$tmp/busy/checkpoint.bin" ] && break; sleep 0.1; done  # sanitizer builds are slow
expect_fail 2 "busy.*in use by process $busy" train --config "$tmp/train.json" --iterations 1 --out "$tmp/busy" --overwrite
expect_fail 2 "busy.*in use by process $busy" train --resume "$tmp/busy" --iterations 1
kill -INT "$busy"
wait "$busy"
rc=$?
if [ "$rc" -eq 130 ] && ! resume "$tmp/busy" --iterations 1 2>&1 | grep -q "in use"; then
  ok
else
  fail "the first run of a busy folder did not end as a normal interrupted run (exit $rc)"
  cat "$tmp/busy.log"
fi
# --resume while a fresh run is starting in the folder (no checkpoint yet: checkpoint_every is beyond the run)
# names that run's process too.
"$hns" train --config "$tmp/train.json" --threads 1 --iterations 100000 --set checkpoint_every=100000 \
  --out "$tmp/early" >"$tmp/early.log" 2>&1 &
early=$!
pids+=("$early")
for _ in $(seq 1200); do [ -s "$tmp/early/metrics.jsonl" ] && break; sleep 0.1; done
expect_fail 2 "early.*in use by process $early" train --resume "$tmp/early" --iterations 1
kill -9 "$early"
wait "$early" 2>/dev/null
# Two fresh starts a moment apart: one of them is refused.
"$hns" train --config "$tmp/train.json" --threads 1 --iterations 100000 --out "$tmp/twin" >"$tmp/twin1.log" 2>&1 &
t1=$!
pids+=("$t1")
"$hns" train --config "$tmp/train.json" --threads 1 --iterations 100000 --out "$tmp/twin" >"$tmp/twin2.log" 2>&1 &
t2=$!
pids+=("$t2")
# The refused one ends by itself (exit 2) once the other holds the folder; then the other is stopped.
for _ in $(seq 1200); do kill -0 "$t1" 2>/dev/null && kill -0 "$t2" 2>/dev/null || break; sleep 0.1; done
for _ in $(seq 1200); do [ -s "$tmp/twin/checkpoint.bin" ] && break; sleep 0.1; done
kill -INT "$t1" "$t2" 2>/dev/null
wait "$t1"
r1=$?
wait "$t2"
r2=$?
if { [ "$r1" -eq 2 ] && [ "$r2" -ne 2 ]; } || { [ "$r2" -eq 2 ] && [ "$r1" -ne 2 ]; }; then
  ok
else
  fail "two runs started into one folder: exits $r1 and $r2 (one must be refused with 2)"
  cat "$tmp/twin1.log" "$tmp/twin2.log"
fi

# --- A damaged metrics row does not drop the rows after it (item 6).
train_small --iterations 6 --out "$tmp/rows" >/dev/null 2>&1
sed -i '2s/.*/{"iteration": 2, "agent_ste/' "$tmp/rows/metrics.jsonl"
if resume "$tmp/rows" --iterations 7 >"$tmp/log" 2>&1 &&
   [ "$(grep -c '"iteration"' "$tmp/rows/metrics.jsonl")" -eq 6 ] && grep -q "line 2" "$tmp/log"; then
  ok
else
  fail "resume with a damaged metrics line 2 of 6: $(wc -l <"$tmp/rows/metrics.jsonl") lines kept"
  cat "$tmp/log"
fi

# --- Bad values are bad input (item 9): exit 2 naming the flag, before any work.
expect_fail 2 "--iterations" train --config "$tmp/train.json" --iterations "" --out "$tmp/x2"
expect_fail 2 "--threads" train --config "$tmp/train.json" --threads "" --out "$tmp/x2"
expect_fail 2 "--iterations" train --config "$tmp/train.json" --iterations " 2" --out "$tmp/x2"
expect_fail 2 "--iterations" train --config "$tmp/train.json" --iterations "+2" --out "$tmp/x2"
expect_fail 2 "--iterations" train --config "$tmp/train.json" --iterations "0x2" --out "$tmp/x2"
expect_fail 2 "--envs" bench --envs 0x2 --steps 1
expect_fail 2 "lr" train --config "$tmp/train.json" --set lr=0x1p-10 --out "$tmp/x2"
expect_fail 2 "envs" train --config "$tmp/train.json" --set envs=lots --envs 4 --out "$tmp/x2"
expect_fail 2 "--checkpoint" play --checkpoint "" --out "$tmp/x.traj"
expect_fail 2 "--out" train --config "$tmp/train.json" --iterations 1 --out ""
expect_fail 2 "--config" train --config "" --iterations 1 --out "$tmp/x2"
expect_fail 2 "--json" bench --envs 1 --steps 1 --json ""
expect_fail 2 "--out /proc/.*cannot be written" play --scene quadrant --out /proc/self/hns-test.traj
expect_fail 2 "--out .*too long" train --config "$tmp/train.json" --out "$tmp/$(printf 'a%.0s' $(seq 300))"
expect_fail 2 "--overwrite and --resume" train --resume "$tmp/run" --overwrite
[ -e "$tmp/x2" ] && fail "a refused command created its run folder"

# --- A folder is a run folder by its marker or a whole valid run, not by 8 bytes (item 11).
mkdir "$tmp/looks"
printf 'HNSCKPT\nthis is not a checkpoint' >"$tmp/looks/checkpoint.bin"
echo "mine" >"$tmp/looks/config.json"
expect_fail 2 "not a run folder" train --config "$tmp/train.json" --out "$tmp/looks" --overwrite
[ "$(cat "$tmp/looks/config.json")" = "mine" ] && ok || fail "--overwrite replaced a folder's config.json"

# A refused --resume of a folder that is not a run leaves at most the lock file, which marks nothing: the
# folder is still refused as a run folder afterwards, and the user's files are untouched.
mkdir "$tmp/notrun"
echo "my own" >"$tmp/notrun/checkpoint.bin"
echo "my own" >"$tmp/notrun/metrics.jsonl"
expect_fail 2 "" train --resume "$tmp/notrun"
expect_fail 2 "not a run folder" train --config "$tmp/train.json" --out "$tmp/notrun" --overwrite
[ "$(cat "$tmp/notrun/checkpoint.bin")" = "my own" ] && [ "$(cat "$tmp/notrun/metrics.jsonl")" = "my own" ] && ok ||
  fail "a folder that only a refused --resume had touched was taken for a run folder"

# hns counting and hns eval replace earlier results only when asked.
mkdir "$tmp/probe" "$tmp/evals"
echo "mine" >"$tmp/probe/counting.md"
echo "mine" >"$tmp/evals/eval.md"
expect_fail 2 "holds counting.md.*--overwrite" counting --out "$tmp/probe" --seeds 1
expect_fail 2 "holds eval.md but no eval.json" eval --out "$tmp/evals" --tasks lockbox --seeds 1
expect_fail 2 "--resume and --overwrite" eval --out "$tmp/evals" --tasks lockbox --resume --overwrite
mkdir "$tmp/evalfifo"
mkfifo "$tmp/evalfifo/eval.json"
expect_fail 2 "eval.json is not a regular file" eval --out "$tmp/evalfifo" --tasks lockbox --seeds 1 --overwrite
[ "$(cat "$tmp/probe/counting.md")" = "mine" ] && [ "$(cat "$tmp/evals/eval.md")" = "mine" ] && ok ||
  fail "counting or eval replaced a file it was not asked to"

# --- Third probe's findings.
# A key given by its flag and by --set: refused, not one value silently dropped unchecked.
expect_fail 2 "--set scene=bogus and --scene both give scene" train --scene quadrant --set scene=bogus --out "$tmp/x2"
expect_fail 2 "--set envs=-5 and --envs both give envs" train --envs 2 --set envs=-5 --out "$tmp/x2"
# Numbers with a leading zero, or a bare point, are not numbers in JSON's form.
expect_fail 2 "--seed = 010 is invalid" train --seed 010 --out "$tmp/x2"
expect_fail 2 "--seed = 010 is invalid" play --scene quadrant --seed 010 --out "$tmp/x2.traj"
expect_fail 2 "epochs = '010' is invalid" train --set epochs=010 --out "$tmp/x2"
expect_fail 2 "lr = '01' is invalid" train --set lr=01 --out "$tmp/x2"
expect_fail 2 "lr = '1.' is invalid" train --set lr=1. --out "$tmp/x2"
[ -e "$tmp/x2" ] && fail "a refused start created its run folder"
# --init-from a special file says what it is.
expect_fail 2 "--init-from /dev/zero is a character device, not a checkpoint file" train --init-from /dev/zero \
  --out "$tmp/x2"
# --resume keeps only rows hns report reads: a row it would refuse is dropped, with a warning.
cp -r "$tmp/run" "$tmp/badrow"
echo '{"iteration": -1}' >>"$tmp/badrow/metrics.jsonl"
if resume "$tmp/badrow" --iterations 3 >"$tmp/log" 2>&1 && grep -q "line 3 is not a whole metrics row" "$tmp/log" &&
   "$hns" report "$tmp/badrow" --html "$tmp/badrow.html" >/dev/null 2>&1; then
  ok
else
  fail "--resume kept a metrics row that hns report refuses: $(cat "$tmp/log")"
fi
# --overwrite over a run whose file is a FIFO or a folder: exit 2 before anything is removed.
cp -r "$tmp/run" "$tmp/ow-fifo"
rm "$tmp/ow-fifo/config.json"
mkfifo "$tmp/ow-fifo/config.json"
expect_fail 2 "config.json is a FIFO" train --config "$tmp/train.json" --iterations 1 --out "$tmp/ow-fifo" --overwrite
cp -r "$tmp/run" "$tmp/ow-dir"
rm "$tmp/ow-dir/metrics.jsonl"
mkdir "$tmp/ow-dir/metrics.jsonl"
echo "mine" >"$tmp/ow-dir/metrics.jsonl/user.txt"
expect_fail 2 "metrics.jsonl is a folder" train --config "$tmp/train.json" --iterations 1 --out "$tmp/ow-dir" --overwrite
[ -f "$tmp/ow-fifo/checkpoint.bin" ] && [ -f "$tmp/ow-dir/checkpoint.bin" ] && [ -f "$tmp/ow-dir/replay.traj" ] &&
  [ -f "$tmp/ow-dir/metrics.jsonl/user.txt" ] && ok || fail "a refused --overwrite removed run files"

# Fourth probe: JSON nested tens of thousands deep (a stack overflow in the parser before), a wall far outside
# any arena in a re-checksummed header, true for a number, a NaN flag.
python3 - "$tmp/q.traj" "$tmp/deep.traj" "$tmp/far.traj" <<'PY'
import hashlib, json, struct, sys
src = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", src, 8)[0]
header = json.loads(src[12:12 + n])
def framed(text):
    text = text.encode()
    text += b" " * ((-(12 + len(text))) % 8)
    return src[:8] + struct.pack("<I", len(text)) + text + src[12 + n:]
deep = json.dumps(header, separators=(",", ":"))[:-1] + ',"zz":' + "[" * 70000 + "]" * 70000 + "}"
open(sys.argv[2], "wb").write(framed(deep))
PY
expect_fail 2 "header nests arrays or objects more than 64 levels deep" replay "$tmp/deep.traj" --html "$tmp/x.html"
cp -r "$tmp/run" "$tmp/deep-metrics"
python3 -c "import sys; open(sys.argv[1], 'a').write('{\"iteration\": 9, \"agent_steps\": 1, \"z\": ' + '[' * 70000 + ']' * 70000 + '}\n')" \
  "$tmp/deep-metrics/metrics.jsonl"
expect_fail 2 "metrics.jsonl:3 is not an iteration record" report "$tmp/deep-metrics" --html "$tmp/x.html"
if resume "$tmp/deep-metrics" --iterations 3 >"$tmp/log" 2>&1 && grep -q "line 3 is not a whole metrics row" "$tmp/log"; then
  ok
else
  fail "--resume kept a metrics row nested 70000 deep: $(head -c 600 "$tmp/log")"
fi
cp -r "$tmp/run" "$tmp/loop"
rm "$tmp/loop/checkpoint.bin"
ln -s "$tmp/loop/checkpoint.bin" "$tmp/loop/checkpoint.bin"
expect_fail 2 "checkpoint.bin: too many levels of symbolic links" train --resume "$tmp/loop"
printf '{"scene": "lockbox", "init_from": "/x\033[31mRED"}' >"$tmp/esc.json"
expect_fail 2 "raw control character \(byte 0x1b\) in a string" train --config "$tmp/esc.json" --out "$tmp/x3"
printf '{"scene": "lock\377box"}' >"$tmp/latin.json"
expect_fail 2 "latin.json: not UTF-8 text \(byte 15\)" train --config "$tmp/latin.json" --out "$tmp/x3"
expect_fail 2 "horizon = '1000001' is invalid: must be in \[0, 100000\]" train --set horizon=1000001 --out "$tmp/x3"
# A run with minibatch_chunks (more than one env holds) exports and plays: acting rebuilds its config for one
# env. A path that is not UTF-8 is refused at start (config.json could not hold it, and the run would not
# resume).
if train_small --iterations 1 --set minibatch_chunks=16 --out "$tmp/mbc" >"$tmp/log" 2>&1 &&
   "$hns" export "$tmp/mbc" --out "$tmp/mbc.hnspolicy" >>"$tmp/log" 2>&1 &&
   "$hns" play --checkpoint "$tmp/mbc.hnspolicy" --out "$tmp/mbc.traj" >>"$tmp/log" 2>&1 &&
   "$hns" play --checkpoint "$tmp/mbc/checkpoint.bin" --out "$tmp/mbc.traj" >>"$tmp/log" 2>&1; then
  ok
else
  fail "a minibatch_chunks run does not export or play: $(head -c 600 "$tmp/log")"
fi
cp "$tmp/run/checkpoint.bin" "$tmp/caf"$'\xe9'".bin"
expect_fail 2 "init_from: byte [0-9]+ is not UTF-8" train --config "$tmp/train.json" --init-from "$tmp/caf"$'\xe9'".bin" \
  --out "$tmp/x4"
[ -e "$tmp/x4" ] && fail "a refused non-UTF-8 --init-from created its run folder"
expect_fail 2 "lr = 'true' is invalid" train --set lr=true --out "$tmp/x3"
expect_fail 2 "epochs = 'false' is invalid" train --set epochs=false --out "$tmp/x3"
expect_fail 2 "--speed: 'nan' is not a decimal number" replay "$tmp/q.traj" --gif "$tmp/x.gif" --speed nan
expect_fail 2 "--speed: '0x1p0' is not a decimal number" replay "$tmp/q.traj" --gif "$tmp/x.gif" --speed 0x1p0
[ -e "$tmp/x3" ] || [ -e "$tmp/x.gif" ] && fail "a refused command wrote its output"

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
