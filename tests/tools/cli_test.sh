#!/usr/bin/env bash
# The hns command line: bad input exits 2 with a message naming the problem; a short bench run writes the
# documented JSON fields. Usage: cli_test.sh path/to/hns [mpi|no-mpi] (whether hns was built with MPI; default
# mpi)
set -u
hns="$1"
mpi="${2:-mpi}"
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
expect_fail 2 "threads" bench --threads -1
expect_fail 2 "boxes" bench --scene quadrant --boxes 40
expect_fail 2 "boxes.max = 20" bench --scene quadrant --boxes 20
expect_fail 2 "hiders" bench --hiders 0 --seekers 0
expect_fail 2 "" bench --no-such-flag
expect_fail 2 "" frobnicate
# `hns --version` names the version, the commit and the instruction set.
if "$hns" --version | grep -E -q "^hns [0-9]+\.[0-9]+\.[0-9]+ \(commit [0-9a-f]+(-dirty)?|unknown"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: hns --version: $("$hns" --version 2>&1)"
fi
# `hns help` is the overview, `hns help COMMAND` that command's help; both exit 0.
if "$hns" help 2>&1 | grep -q "Subcommands:" && "$hns" help train 2>&1 | grep -q -- "--resume"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: hns help / hns help train"
fi

# has_fields FILE NAME...: the JSON file has every named key.
has_fields() {
  local file="$1"
  shift
  for f in "$@"; do grep -q "\"$f\"" "$file" || return 1; done
}

# A short real run writes the JSON figures, and no temporary file is left behind.
if "$hns" bench --scene full --envs 2 --steps 20 --json "$tmp/out.json" >"$tmp/log" 2>&1 &&
   grep -q '"env_steps_per_s"' "$tmp/out.json" && grep -q '"agent_steps_per_s"' "$tmp/out.json" &&
   has_fields "$tmp/out.json" phases physics_s mirror_s vision_lidar_s observations_s rewards_resets_s \
     hns_version commit cpu_model isa &&
   grep -q '"scene": "full"' "$tmp/out.json" &&
   [ ! -e "$tmp/out.json.tmp" ] && grep -q "env-steps/s" "$tmp/log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: bench --json run"; cat "$tmp/log"; cat "$tmp/out.json" 2>/dev/null
fi
# The network benchmark writes its documented fields; at precision auto, bf16 (and its GEMM reference) where
# the CPU has AVX512-BF16.
if grep -q avx512_bf16 /proc/cpuinfo; then nn_precision=bf16; else nn_precision=fp32; fi
if "$hns" bench --nn small --masks quadrant --precision auto --json "$tmp/nn.json" >"$tmp/log" 2>&1 &&
   has_fields "$tmp/nn.json" model threads params isa masks infer_agent_steps_per_s train_agent_steps_per_s \
     infer_gflops train_gflops infer_useful_gflops train_useful_gflops gemm_gflops precision \
     precision_description hns_version commit cpu_model &&
   grep -q "\"precision\": \"$nn_precision\"" "$tmp/nn.json" &&
   { [ "$nn_precision" = fp32 ] || has_fields "$tmp/nn.json" gemm_bf16_gflops; } &&
   grep -q '"masks": "quadrant"' "$tmp/nn.json" && grep -q "instruction set" "$tmp/log" &&
   grep -q "precision  *$nn_precision" "$tmp/log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: bench --nn run"; cat "$tmp/log"
fi
expect_fail 2 "nn" bench --nn huge
expect_fail 2 "masks" bench --nn small --masks empty
expect_fail 2 "without --nn" bench --masks full
expect_fail 2 "without --nn" bench --masks synthetic
expect_fail 2 "precision" bench --nn small --precision fp16
expect_fail 2 "without --nn" bench --precision fp32
# A profiled run writes a Chrome trace with one event per env, step and phase (5 phases).
if "$hns" bench --scene quadrant --envs 2 --steps 5 --profile "$tmp/trace.json" >"$tmp/log" 2>&1 &&
   grep -q '"traceEvents"' "$tmp/trace.json" && [ "$(grep -o '"ph":"X"' "$tmp/trace.json" | wc -l)" -eq 50 ]; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: bench --profile run"; cat "$tmp/log"
fi
expect_fail 2 "profile" bench --envs 100000 --steps 1000 --profile "$tmp/huge.json"
# An unwritable JSON path fails with status 1 and says so.
# Outputs are checked before any work: a missing folder, an output that is an input, a folder as a file.
expect_fail 2 "missing-dir does not exist" bench --envs 1 --steps 1 --json "$tmp/missing-dir/out.json"
expect_fail 2 "is a folder" bench --envs 1 --steps 1 --json "$tmp"
# Seeds are whole numbers in [0, 2^64 - 1]; counts the generator can never place are refused up front;
# memory that cannot exist is refused with the figure; an unknown command is named; threads beyond the
# machine are reported as what is used.
expect_fail 2 "seed = -1" bench --seed -1 --steps 1
expect_fail 2 "seed = 1e23" bench --seed 1e23 --steps 1
expect_fail 2 "seed = 18446744073709551616" bench --seed 18446744073709551616 --steps 1
expect_fail 2 "cannot be placed.*12 boxes" bench --scene quadrant --boxes 12 --steps 1
expect_fail 2 "needs about .* GB of memory" train --scene full --model paper --envs 11000 --out "$tmp/huge-mem"
expect_fail 2 "unknown command 'frobnicate'" frobnicate
expect_fail 2 "unknown option '--bogus' before a command" --bogus
if "$hns" bench --envs 1 --steps 1 --threads 1024 --json "$tmp/t.json" 2>&1 | grep -q "1024 threads requested" &&
   ! grep -q '"threads": 1024' "$tmp/t.json"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: bench --threads 64 must report the threads it uses"
fi

# play / replay: bad flags and files exit 2 naming the problem; nothing is half-written.
expect_fail 2 "scene" play --scene nowhere --out "$tmp/x.traj"
expect_fail 2 "episodes" play --episodes 0 --out "$tmp/x.traj"
expect_fail 2 "envs" play --envs 0 --out "$tmp/x.traj"
expect_fail 2 "out" play --scene quadrant
expect_fail 2 "hiders" play --hiders 0 --seekers 0 --out "$tmp/x.traj"
expect_fail 2 "cannot open checkpoint" play --checkpoint "$tmp/model.ckpt" --out "$tmp/x.traj"
expect_fail 2 "excludes" play --random --checkpoint "$tmp/model.ckpt" --out "$tmp/x.traj"
expect_fail 2 "missing-dir does not exist" play --out "$tmp/missing-dir/x.traj"
expect_fail 2 "seed = -1" play --seed -1 --out "$tmp/x.traj"
expect_fail 2 "is also an input" replay "$tmp/x.traj" --html "$tmp/x.traj"
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
# The same recording as an animated GIF (one picture per frame of 2 episodes of 81 frames), from replay and
# straight from play; neither output asked for is refused.
if "$hns" replay "$tmp/q.traj" --gif "$tmp/q.gif" --size 96 >"$tmp/log" 2>&1 && [ ! -e "$tmp/q.gif.tmp" ] &&
   [ "$(head -c 6 "$tmp/q.gif")" = "GIF89a" ] && grep -q "162 pictures of 96 x 96 px" "$tmp/log" &&
   "$hns" play --scene quadrant --episodes 2 --envs 2 --seed 4 --out "$tmp/q2.traj" --gif "$tmp/q2.gif" >>"$tmp/log" 2>&1 &&
   [ "$(head -c 6 "$tmp/q2.gif")" = "GIF89a" ] && grep -q "q2.gif (162 pictures" "$tmp/log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: replay --gif"; cat "$tmp/log"
fi
expect_fail 2 "say what to write" replay "$tmp/q.traj"
expect_fail 2 "episode 7.*episodes 0 to 1" replay "$tmp/q.traj" --gif "$tmp/q7.gif" --episode 7
head -c 5000 "$tmp/q.traj" >"$tmp/cut.traj"
expect_fail 2 "episode 0.*truncated" replay "$tmp/cut.traj" --html "$tmp/cut.html"
[ -e "$tmp/cut.html" ] && { failed=$((failed + 1)); echo "FAIL: replay of a truncated file wrote a page"; }

# hns train: bad configs exit 2 naming the key; a short run writes its folder; resume continues it; a corrupt
# checkpoint is refused; an existing run is not overwritten by accident; Ctrl-C stops with a checkpoint.
expect_fail 2 "epochs" train --set epochs=0 --out "$tmp/bad"
expect_fail 2 "unknown key 'colour'" train --set colour=red --out "$tmp/bad"
expect_fail 2 "scene" train --scene moon --out "$tmp/bad"
expect_fail 2 "precision = 'nonsense' is invalid: must be one of fp32, bf16, auto" train --precision nonsense --out "$tmp/bad"
echo '{"epochs": 2,' >"$tmp/broken.json"
expect_fail 2 "broken.json" train --config "$tmp/broken.json" --out "$tmp/bad"
expect_fail 2 "no checkpoint.bin" train --resume "$tmp/nothing-here"
[ -e "$tmp/bad" ] && { failed=$((failed + 1)); echo "FAIL: a refused train config created its run folder"; }
echo '{"scene": "lockbox", "envs": 4, "epochs": 1, "minibatches": 2}' >"$tmp/train.json"
if "$hns" train --config "$tmp/train.json" --iterations 2 --threads 1 --out "$tmp/run" >"$tmp/log" 2>&1 &&
   [ "$(wc -l <"$tmp/run/metrics.jsonl")" -eq 2 ] && grep -q '"scene": "lockbox"' "$tmp/run/config.json" &&
   has_fields "$tmp/run/metrics.jsonl" iteration agent_steps env_steps steps_per_s hider_reward seeker_reward \
     policy_loss value_loss entropy approx_kl clip_frac max_box_move_prep num_box_lock_prep max_ramp_move \
     num_ramp_lock time_simulate time_observe time_infer time_learn &&
   [ -s "$tmp/run/checkpoint.bin" ] && [ ! -e "$tmp/run/checkpoint.bin.tmp" ] &&
   grep -q '"precision": "fp32"' "$tmp/run/config.json" && head -1 "$tmp/run/metrics.jsonl" | grep -q '"precision": "fp32"' &&
   grep -q "precision: fp32" "$tmp/log" && grep -q '"chunk_sequences": 4' "$tmp/run/config.json" &&
   "$hns" train --resume "$tmp/run" --iterations 3 >>"$tmp/log" 2>&1 &&
   [ "$(wc -l <"$tmp/run/metrics.jsonl")" -eq 3 ] && grep -q "resuming" "$tmp/log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: train + resume run"; cat "$tmp/log"
fi
expect_fail 2 "already holds a run" train --config "$tmp/train.json" --iterations 2 --out "$tmp/run"
# A folder with files hns did not write is refused, --overwrite included, and nothing in it is touched.
mkdir -p "$tmp/mine" && echo "my notes" >"$tmp/mine/notes.txt" && echo '{"not": "hns"}' >"$tmp/mine/metrics.jsonl"
expect_fail 2 "holds '.*' and is not a run folder of hns train" train --config "$tmp/train.json" --out "$tmp/mine"
mkdir -p "$tmp/onlymetrics" && echo '{"iteration": 1, "agent_steps": 1}' >"$tmp/onlymetrics/metrics.jsonl"
expect_fail 2 "not a run folder" train --config "$tmp/train.json" --out "$tmp/mine" --overwrite
expect_fail 2 "not a run folder" train --config "$tmp/train.json" --out "$tmp/onlymetrics" --overwrite
mkdir -p "$tmp/cfgonly" && echo '{"colour": "red"}' >"$tmp/cfgonly/config.json"
expect_fail 2 "not a run folder" train --config "$tmp/train.json" --out "$tmp/cfgonly"
if [ "$(cat "$tmp/mine/notes.txt")" = "my notes" ] && grep -q '"not"' "$tmp/mine/metrics.jsonl" &&
   grep -q colour "$tmp/cfgonly/config.json"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: a refused --out folder was changed"
fi
expect_fail 2 "seed = -1" train --config "$tmp/train.json" --seed -1 --out "$tmp/neg"
expect_fail 2 "is also an input" train --resume "$tmp/run" --iterations 3 --profile "$tmp/run/metrics.jsonl"
# --profile over the run folder's lock or marker (a second run could then take the folder) is refused, neither
# overwritten by a trace; a refused --profile of a new run leaves no run folder behind.
expect_fail 2 "is also an input" train --resume "$tmp/run" --iterations 3 --profile "$tmp/run/.hns-lock"
expect_fail 2 "is also an input" train --resume "$tmp/run" --iterations 3 --profile "$tmp/run/.hns-run"
expect_fail 2 "is also an input" train --config "$tmp/train.json" --out "$tmp/newprof" --profile "$tmp/newprof/.hns-lock"
expect_fail 2 "cannot be written" train --config "$tmp/train.json" --out "$tmp/newprof" --profile /proc/hns-profile
if ! grep -q "traceEvents" "$tmp/run/.hns-lock" && grep -q "a run folder of hns train" "$tmp/run/.hns-run" &&
   [ ! -e "$tmp/newprof" ]; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: a refused --profile changed the run folder or left a new one: $(ls -a "$tmp/newprof" 2>&1)"
fi
# A profile in the new run folder whose name leaves no room for PATH.tmp's: refused before the folder is made.
long_name=$(printf 'p%.0s' $(seq 248)).json
expect_fail 2 "too long to write PATH.tmp" train --config "$tmp/train.json" --out "$tmp/longprof" \
  --profile "$tmp/longprof/$long_name"
[ ! -e "$tmp/longprof" ] || {
  failed=$((failed + 1))
  echo "FAIL: a --profile refused for its name left its new run folder: $(ls -A "$tmp/longprof")"
}
mkdir "$tmp/emptyprof"
expect_fail 2 "cannot be written" train --config "$tmp/train.json" --out "$tmp/emptyprof" --profile /proc/hns-profile
[ -z "$(ls -A "$tmp/emptyprof")" ] || {
  failed=$((failed + 1))
  echo "FAIL: a refused --profile left files in an empty --out folder: $(ls -A "$tmp/emptyprof")"
}
expect_fail 2 "seed: checkpoint has 1" train --resume "$tmp/run" --seed 5
expect_fail 2 "precision: checkpoint has fp32, this run has bf16|precision bf16 needs a CPU with AVX512-BF16" \
  train --resume "$tmp/run" --set precision=bf16
expect_fail 2 "chunk_sequences: checkpoint has 4, this run has 8" train --resume "$tmp/run" --set chunk_sequences=8
cp "$tmp/run/checkpoint.bin" "$tmp/good.bin"
printf 'x' | dd of="$tmp/run/checkpoint.bin" bs=1 seek=200 conv=notrunc status=none
expect_fail 2 "corrupt" train --resume "$tmp/run" --iterations 4
cmp -s "$tmp/run/checkpoint.bin" "$tmp/good.bin" && { failed=$((failed + 1)); echo "FAIL: corruption not applied"; }
# A lone hider in the quadrant game (the count keys of the count-based baselines): it trains, its report
# lists the standard stages of neither team, and its checkpoint starts lock-and-return. The keys are refused
# by a transfer task, and boxes = 0 in a scene with boxes. It runs at precision auto, which its config.json
# and first metrics row record as the precision that ran (bf16 where the CPU has AVX512-BF16).
if "$hns" train --scene quadrant --set hiders=1 --set seekers=0 --set spawn_quarter=1 --envs 2 --iterations 1 \
     --set horizon=20 --threads 1 --precision auto --out "$tmp/lone" >"$tmp/log" 2>&1 &&
   grep -q '"seekers": 0' "$tmp/lone/config.json" &&
   grep -q "\"precision\": \"$nn_precision\"" "$tmp/lone/config.json" &&
   grep -q "\"precision\": \"$nn_precision\"" "$tmp/lone/metrics.jsonl" &&
   "$hns" report "$tmp/lone" --html "$tmp/lone.html" >>"$tmp/log" 2>&1 && ! grep -q "^stages" "$tmp/log" &&
   "$hns" train --scene lock-and-return --init-from "$tmp/lone/checkpoint.bin" --envs 2 --iterations 1 \
     --threads 1 --out "$tmp/lone-lr" >>"$tmp/log" 2>&1; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: a lone-hider run, its report and its checkpoint in lock-and-return"; cat "$tmp/log"
fi
expect_fail 2 "spawn_quarter are for the hide-and-seek scenes" train --scene shelter --set seekers=0 --out "$tmp/no"
expect_fail 2 "boxes = '0' is invalid" train --scene quadrant --set boxes=0 --out "$tmp/no"
[ -e "$tmp/no" ] && { failed=$((failed + 1)); echo "FAIL: a refused count key wrote a run folder"; }
# play --checkpoint records with the trained policy (the run's scene); report renders a run folder.
cp "$tmp/good.bin" "$tmp/run/checkpoint.bin"
# A torn last line of metrics.jsonl (iteration 3, cut inside a number) is dropped on resume: only whole
# lines survive (iterations 1, 2, then the resumed 4), and the report renders the resumed run.
cp -r "$tmp/run" "$tmp/torn"
head -c -40 "$tmp/torn/metrics.jsonl" >"$tmp/torn/m" && mv "$tmp/torn/m" "$tmp/torn/metrics.jsonl"
if "$hns" train --resume "$tmp/torn" --iterations 4 >"$tmp/log" 2>&1 &&
   [ "$(python3 -c "import json,sys; print([json.loads(l)['iteration'] for l in open(sys.argv[1])])" \
        "$tmp/torn/metrics.jsonl")" = "[1, 2, 4]" ] &&
   "$hns" report "$tmp/torn" --html "$tmp/torn.html" >>"$tmp/log" 2>&1; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: resume after a torn metrics line"; cat "$tmp/log"; cat "$tmp/torn/metrics.jsonl"
fi
if "$hns" play --checkpoint "$tmp/run/checkpoint.bin" --episodes 1 --out "$tmp/p.traj" >"$tmp/log" 2>&1 &&
   grep -q "scene lockbox" "$tmp/log" && grep -q "checkpoint's policy" "$tmp/log" &&
   "$hns" report "$tmp/run" --html "$tmp/report.html" >>"$tmp/log" 2>&1 && grep -q 'id="hns-status"' "$tmp/report.html"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: play --checkpoint + report"; cat "$tmp/log"
fi
# report --windows: the detectors per window of agent-steps, alone (no file written) or beside the page;
# nothing asked, a window out of range or a title without a page: exit 2.
before="$(ls "$tmp" | sort)"
if "$hns" report "$tmp/run" --windows 0.001 >"$tmp/log" 2>&1 &&
   grep -q "^window (M agent-steps) *iterations" "$tmp/log" && grep -qE "^[0-9.]+-[0-9.]+ \(to " "$tmp/log" &&
   [ "$(ls "$tmp" | sort)" = "$before" ] &&
   "$hns" report "$tmp/run" --windows 1 --html "$tmp/both.html" >"$tmp/log2" 2>&1 &&
   grep -q 'id="hns-status"' "$tmp/both.html" && grep -qE "^0-1 \(to " "$tmp/log2"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: report --windows"; cat "$tmp/log" "$tmp/log2"
fi
expect_fail 2 "nothing to do" report "$tmp/run"
expect_fail 2 "not in range" report "$tmp/run" --windows 0
expect_fail 2 "not in range" report "$tmp/run" --windows -5
expect_fail 2 "requires --html" report "$tmp/run" --windows 1 --title T
expect_fail 2 "trained on scene 'lockbox'" play --checkpoint "$tmp/run/checkpoint.bin" --scene full --out "$tmp/p2.traj"
# hns export: a run folder's policy without its optimiser; it plays the same episodes (same trajectory bytes
# but the file's policy name), writes the replay page in the same command, starts a run, and cannot resume one.
if "$hns" export "$tmp/run" --out "$tmp/run.hnspolicy" >"$tmp/log" 2>&1 && grep -q "wrote .*run.hnspolicy" "$tmp/log" &&
   [ "$(stat -c %s "$tmp/run.hnspolicy")" -lt "$(($(stat -c %s "$tmp/run/checkpoint.bin") / 2))" ] &&
   "$hns" play --checkpoint "$tmp/run.hnspolicy" --episodes 1 --out "$tmp/pe.traj" --html "$tmp/pe.html" >>"$tmp/log" 2>&1 &&
   grep -q 'id="hns-status"' "$tmp/pe.html" &&
   "$hns" replay "$tmp/p.traj" --gif "$tmp/p.gif" >>"$tmp/log" 2>&1 && "$hns" replay "$tmp/pe.traj" --gif "$tmp/pe.gif" >>"$tmp/log" 2>&1 &&
   cmp -s "$tmp/p.gif" "$tmp/pe.gif" &&
   "$hns" train --config "$tmp/train.json" --iterations 1 --threads 1 --init-from "$tmp/run.hnspolicy" \
     --out "$tmp/init-exported" >>"$tmp/log" 2>&1 && grep -q "starting from .*policy weights" "$tmp/log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: export, play and init-from the export"; cat "$tmp/log"
fi
cp "$tmp/run.hnspolicy" "$tmp/init-exported/checkpoint.bin"
expect_fail 2 "is an exported policy .* not resume one" train --resume "$tmp/init-exported"
expect_fail 2 "already an exported policy" export "$tmp/run.hnspolicy" --out "$tmp/again.hnspolicy"
expect_fail 2 "not an hns checkpoint" export "$tmp/train.json" --out "$tmp/again.hnspolicy"
expect_fail 2 "init_optimizer = 1 needs Adam's moments" train --config "$tmp/train.json" --envs 3 \
  --set init_optimizer=1 --init-from "$tmp/run.hnspolicy" --out "$tmp/bad-adam"
# train --init-from: a new run starts from the checkpoint's weights; a bad or foreign checkpoint is refused
# before anything of the --out folder is removed.
if "$hns" train --config "$tmp/train.json" --iterations 1 --threads 1 --seed 9 --envs 3 \
     --init-from "$tmp/run/checkpoint.bin" --out "$tmp/init" >"$tmp/log" 2>&1 &&
   grep -q "starting from .*policy weights, value weights" "$tmp/log" &&
   grep -q '"init_from": "/.*run/checkpoint.bin"' "$tmp/init/config.json" &&
   [ "$(wc -l <"$tmp/init/metrics.jsonl")" -eq 1 ] &&
   "$hns" train --resume "$tmp/init" --iterations 2 >>"$tmp/log" 2>&1 && [ "$(wc -l <"$tmp/init/metrics.jsonl")" -eq 2 ]; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: train --init-from, then --resume"; cat "$tmp/log"
fi
expect_fail 2 "init-from and --resume" train --resume "$tmp/init" --init-from "$tmp/run/checkpoint.bin"
expect_fail 2 "no such checkpoint file" train --config "$tmp/train.json" --init-from "$tmp/none.bin" --out "$tmp/bad"
expect_fail 2 "is a folder, not a checkpoint file" train --config "$tmp/train.json" --init-from "$tmp/run" --out "$tmp/bad"
echo '{"scene": "lockbox", "envs": 4, "init_from": "none.bin"}' >"$tmp/initcfg.json"
expect_fail 2 "config key init_from = none.bin: no such checkpoint file" train --config "$tmp/initcfg.json" --out "$tmp/bad"
expect_fail 2 "init_optimizer = '1'.*init_value is 0" train --config "$tmp/train.json" --set init_value=0 \
  --set init_optimizer=1 --init-from "$tmp/run/checkpoint.bin" --out "$tmp/bad"
expect_fail 2 "profile .*is also an input" train --config "$tmp/train.json" --init-from "$tmp/good.bin" \
  --profile "$tmp/good.bin" --out "$tmp/bad-profile"
[ -e "$tmp/bad-profile" ] && { failed=$((failed + 1)); echo "FAIL: a refused --profile left its run folder"; }
expect_fail 2 "observation slots" train --scene quadrant --envs 2 --init-from "$tmp/run/checkpoint.bin" --out "$tmp/bad"
[ -e "$tmp/bad" ] && { failed=$((failed + 1)); echo "FAIL: a refused --init-from created its run folder"; }
expect_fail 2 "init_value = '2'" train --config "$tmp/train.json" --set init_value=2 --out "$tmp/bad"
# refused_start VAR=VALUE PATTERN [ARGS...]: hns train started with VAR=VALUE in its environment (and ARGS)
# exits 2 with output matching PATTERN and makes no run folder.
refused_start() {
  local setting="$1" pattern="$2" out rc
  shift 2
  rm -rf "$tmp/refused"
  out="$(env "$setting" "$hns" train --config "$tmp/train.json" --iterations 1 --out "$tmp/refused" "$@" 2>&1)"
  rc=$?
  if [ "$rc" -eq 2 ] && grep -q -- "$pattern" <<<"$out" && [ ! -e "$tmp/refused" ]; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL: $setting hns train $* -> exit $rc (want 2 and no run folder), output: $out"
  fi
}
# srun without an MPI plugin starts plain processes, each of which would train the whole run alone: refused.
refused_start SLURM_STEP_NUM_TASKS=4 "started by srun as 4 tasks without MPI"
# HNS_BF16_KERNEL picks the bf16 kernel: an unknown value, or amx on a CPU without AMX-BF16 tiles, is refused
# when a bf16 run starts. Only where the CPU has AVX512-BF16 (elsewhere bf16 itself is refused first).
if grep -qw avx512_bf16 /proc/cpuinfo; then
  refused_start HNS_BF16_KERNEL=bogus "HNS_BF16_KERNEL='bogus'" --precision bf16
  grep -qw amx_bf16 /proc/cpuinfo || refused_start HNS_BF16_KERNEL=amx "HNS_BF16_KERNEL=amx" --precision bf16
  # A bf16 run resumed where the other kernel runs (a machine with AMX after one without, or the reverse:
  # here the first metrics row is made to name the other kernel) continues with a warning that says so;
  # resumed on the kernel it started on, it says nothing.
  rm -rf "$tmp/bfk"
  if "$hns" train --config "$tmp/train.json" --precision bf16 --threads 1 --iterations 1 --out "$tmp/bfk" \
       >"$tmp/log" 2>&1 &&
     "$hns" train --resume "$tmp/bfk" --iterations 2 --threads 1 >>"$tmp/log" 2>&1 &&
     ! grep -q "bf16 run started on the" "$tmp/log" &&
     kern="$(head -1 "$tmp/bfk/metrics.jsonl" | grep -o '"bf16_kernel": "[a-z0-9-]*"' | cut -d'"' -f4)" &&
     if [ "$kern" = amx ]; then other=avx512-bf16; else other=amx; fi &&
     sed -i "1s/\"bf16_kernel\": \"$kern\"/\"bf16_kernel\": \"$other\"/" "$tmp/bfk/metrics.jsonl" &&
     "$hns" train --resume "$tmp/bfk" --iterations 3 --threads 1 >"$tmp/log" 2>&1 &&
     grep -q "warning: this bf16 run started on the $other kernel (metrics.jsonl's first row) and this leg runs on $kern" \
       "$tmp/log"; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL: a bf16 run resumed on another kernel warns (and on its own kernel does not)"; cat "$tmp/log"
  fi
fi
# A build without MPI started by an MPI launcher as one of several processes (its environment says so):
# refused (each process would train the whole run alone). Only where hns has no MPI: an MPI build would join
# the job, and there is none here.
if [ "$mpi" = no-mpi ]; then
  for launcher in OMPI_COMM_WORLD_SIZE PMI_SIZE PMIX_SIZE; do
    refused_start "$launcher=3" "built without MPI.*one of 3 processes"
  done
fi
cp "$tmp/init/checkpoint.bin" "$tmp/init-good.bin"
expect_fail 2 "init-from .*observation slots: the checkpoint's scene lockbox" train --scene quadrant --envs 2 --init-from "$tmp/run/checkpoint.bin" \
  --out "$tmp/init" --overwrite
expect_fail 2 "init-from .*not an hns checkpoint" train --config "$tmp/train.json" --init-from "$tmp/train.json" \
  --out "$tmp/init" --overwrite
expect_fail 2 "is the checkpoint of --out" train --config "$tmp/train.json" --init-from "$tmp/init/checkpoint.bin" \
  --out "$tmp/init" --overwrite
cmp -s "$tmp/init/checkpoint.bin" "$tmp/init-good.bin" ||
  { failed=$((failed + 1)); echo "FAIL: a refused --init-from removed the run's checkpoint"; }
expect_fail 2 "not an hns checkpoint" play --checkpoint "$tmp/train.json" --out "$tmp/p2.traj"
echo '{"iteration": 1, "agent_steps": 5}' >"$tmp/run/metrics.jsonl"
echo 'garbage' >>"$tmp/run/metrics.jsonl"
expect_fail 2 "metrics.jsonl:2 is not an iteration record" report "$tmp/run" --html "$tmp/bad.html"
expect_fail 2 "cannot be read" report "$tmp/nothing" --html "$tmp/bad.html"
[ -e "$tmp/bad.html" ] && { failed=$((failed + 1)); echo "FAIL: a refused report wrote a page"; }
# train --profile writes a Chrome trace with the trainer's phases and the batch's per-env phases.
if "$hns" train --config "$tmp/train.json" --iterations 1 --threads 1 --out "$tmp/prof" --profile "$tmp/prof.json" \
     >"$tmp/log" 2>&1 && grep -q '"forward+backward"' "$tmp/prof.json" && grep -q '"optimizer"' "$tmp/prof.json" &&
   grep -q '"physics"' "$tmp/prof.json" && grep -q '"infer"' "$tmp/prof.json" && grep -q "time split" "$tmp/log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: train --profile"; cat "$tmp/log"
fi
# A NaN before the first checkpoint stops with exit 3 and says so; the same command then starts over.
expect_fail 3 "no checkpoint was written yet" train --config "$tmp/train.json" --set inject_nan_at=1 \
  --iterations 2 --threads 1 --out "$tmp/nan"
if "$hns" train --config "$tmp/train.json" --iterations 1 --threads 1 --out "$tmp/nan" >"$tmp/log" 2>&1 &&
   grep -q "holds no checkpoint" "$tmp/log" && [ -s "$tmp/nan/checkpoint.bin" ]; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: train after a NaN stop before the first checkpoint"; cat "$tmp/log"
fi
expect_fail 2 "rollout buffer" train --set envs=60000 --set episodes_per_iteration=100 --out "$tmp/huge"
# Ctrl-C: the run finishes its iteration, writes a checkpoint and exits 130.
"$hns" train --config "$tmp/train.json" --iterations 100000 --threads 1 --out "$tmp/int" >"$tmp/int.log" 2>&1 &
pid=$!
for _ in $(seq 1 600); do
  [ -s "$tmp/int/metrics.jsonl" ] && break
  sleep 0.1
done
kill -INT "$pid"
wait "$pid"
rc=$?
if [ "$rc" -eq 130 ] && [ -s "$tmp/int/checkpoint.bin" ] && grep -q "resume" "$tmp/int.log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: Ctrl-C during train -> exit $rc"; cat "$tmp/int.log"
fi
# Stopped by Ctrl-C and resumed, a run is one run: its metrics.jsonl equals an uninterrupted run's (timings
# aside), and the report counts each iteration once.
cat >"$tmp/same_metrics.py" <<'PY'
import json, sys
def rows(path):
    skip = ("seconds", "steps_per_s")
    return [{k: v for k, v in json.loads(line).items() if not k.startswith("time_") and k not in skip}
            for line in open(path)]
a, b = rows(sys.argv[1]), rows(sys.argv[2])
sys.exit(0 if a == b and len(a) == int(sys.argv[3]) else 1)
PY
n=$(($(wc -l <"$tmp/int/metrics.jsonl") + 2))
if "$hns" train --resume "$tmp/int" --iterations "$n" >"$tmp/log" 2>&1 &&
   "$hns" train --config "$tmp/train.json" --iterations "$n" --threads 1 --out "$tmp/straight" >>"$tmp/log" 2>&1 &&
   python3 "$tmp/same_metrics.py" "$tmp/int/metrics.jsonl" "$tmp/straight/metrics.jsonl" "$n" &&
   "$hns" report "$tmp/int" --html "$tmp/int.html" 2>&1 | grep -q "($n iterations"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: an interrupted and resumed run is not one run of $n iterations"; cat "$tmp/log"
fi

# hns eval: a tiny suite (from scratch and from a lockbox checkpoint), its three outputs, --resume adding a
# seed and keeping the finished runs, a resume that does not name the recorded condition keeping it, and the
# refusals (before any file is written).
cp "$tmp/init-good.bin" "$tmp/lb.bin"
if "$hns" eval --out "$tmp/eval" --tasks lockbox --seeds 1 --iterations 2 --envs 2 --random-episodes 4 \
     --pretrained "lb=$tmp/lb.bin" --threads 1 >"$tmp/log" 2>&1 &&
   [ "$(grep -c '"task"' "$tmp/eval/eval.json")" -eq 2 ] &&
   grep -q "| lockbox |" "$tmp/eval/eval.md" && grep -q "<svg" "$tmp/eval/eval.html" &&
   [ "$(grep -o "class='xtick'" "$tmp/eval/eval.html" | wc -l)" -ge 2 ] &&
   grep -q "<table class='settings'><tr><th>envs</th>" "$tmp/eval/eval.html" &&
   grep -q ">normalised return (0 random, 1 best)</text>" "$tmp/eval/eval.html" &&
   "$hns" eval --out "$tmp/eval" --tasks lockbox --seeds 2 --iterations 2 --envs 2 --random-episodes 4 \
     --threads 1 --resume >"$tmp/log2" 2>&1 &&
   [ "$(grep -c "iteration 2/2" "$tmp/log2")" -eq 2 ] && [ "$(grep -c '"task"' "$tmp/eval/eval.json")" -eq 4 ] &&
   grep -q "lockbox / lb / seed 2" "$tmp/log2" && grep -q "lb normalised" "$tmp/eval/eval.md" &&
   grep -q '"seed": 2' "$tmp/eval/eval.json" && ! grep -q "random policy return" "$tmp/log2"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: hns eval"; cat "$tmp/log" "$tmp/log2" 2>/dev/null
fi
expect_fail 2 "holds an evaluation" eval --out "$tmp/eval" --tasks lockbox --iterations 2
expect_fail 2 "settings .* differ" eval --out "$tmp/eval" --tasks lockbox --iterations 3 --envs 2 --resume
expect_fail 2 "pretrained lb was .*lb.bin, now .*init-good.bin" eval --out "$tmp/eval" --tasks lockbox \
  --seeds 2 --iterations 2 --envs 2 --random-episodes 4 --pretrained "lb=$tmp/init-good.bin" --resume
# A damaged eval.json (a run whose curve lost its agent-step counts) is refused on --resume, the pages untouched.
cp -r "$tmp/eval" "$tmp/eval-damaged"
python3 -c "import json,sys; d=json.load(open(sys.argv[1])); d['runs'][0]['agent_steps']=[]; json.dump(d, open(sys.argv[1],'w'))" \
  "$tmp/eval-damaged/eval.json"
cp "$tmp/eval-damaged/eval.html" "$tmp/eval-damaged.html"
expect_fail 2 "eval.json's run of lockbox, .*seed 1 has 2 returns and 0 agent-step counts" eval \
  --out "$tmp/eval-damaged" --tasks lockbox --seeds 2 --iterations 2 --envs 2 --random-episodes 4 --threads 1 --resume
cmp -s "$tmp/eval-damaged/eval.html" "$tmp/eval-damaged.html" || {
  failed=$((failed + 1))
  echo "FAIL: a refused eval --resume rewrote eval.html"
}
# eval.json names the chunk its runs trained with (the small model's 4); an evaluation from before that key
# (its runs trained in chunks of 16) resumes with 16 and then names it.
cp -r "$tmp/eval" "$tmp/eval-old"
python3 -c "import json,sys; d=json.load(open(sys.argv[1])); del d['settings']['train_config']['chunk_sequences']; json.dump(d, open(sys.argv[1],'w'))" \
  "$tmp/eval-old/eval.json"
if python3 -c "import json,sys; assert json.load(open(sys.argv[1]))['settings']['train_config']['chunk_sequences'] == 4" \
     "$tmp/eval/eval.json" &&
   "$hns" eval --out "$tmp/eval-old" --tasks lockbox --seeds 2 --iterations 2 --envs 2 --random-episodes 4 \
     --threads 1 --resume >"$tmp/log" 2>&1 &&
   python3 -c "import json,sys; assert json.load(open(sys.argv[1]))['settings']['train_config']['chunk_sequences'] == 16" \
     "$tmp/eval-old/eval.json"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: hns eval's chunk (4 recorded; an evaluation from before the key resumed with 16)"; cat "$tmp/log"
fi
cp "$tmp/run/checkpoint.bin" "$tmp/lb.bin"
expect_fail 2 "condition lb .*changed since its first runs" eval --out "$tmp/eval" --tasks lockbox \
  --seeds 2 --iterations 2 --envs 2 --random-episodes 4 --resume
expect_fail 2 "not a transfer task" eval --out "$tmp/eval-bad" --tasks quadrant
expect_fail 2 "--tasks: 'moon' is not a scene of hns" eval --out "$tmp/eval-bad" --tasks moon
expect_fail 2 "cannot start shelter: .*entity types" eval --out "$tmp/eval-bad" --tasks shelter \
  --pretrained "lb=$tmp/init-good.bin"
expect_fail 2 "seed is set by hns eval" eval --out "$tmp/eval-bad" --set seed=2
[ -e "$tmp/eval-bad" ] && { failed=$((failed + 1)); echo "FAIL: a refused hns eval created its folder"; }
# hns counting: the object-counting probe on a frozen policy from the seed, its two outputs, and its refusals
# (before any file is written); hns eval leaves the probe to it.
if "$hns" counting --out "$tmp/count" --seeds 1 --train-episodes 16 --test-episodes 8 --epochs 3 --envs 8 \
     --threads 1 >"$tmp/log" 2>&1 &&
   grep -q '"test_accuracy"' "$tmp/count/counting.json" && grep -q "| random |" "$tmp/count/counting.md" &&
   grep -q "random / seed 1: test accuracy" "$tmp/log"; then
  passed=$((passed + 1))
else
  failed=$((failed + 1))
  echo "FAIL: hns counting"; cat "$tmp/log"
fi
expect_fail 2 "cannot act in object-counting: .*entity types" counting --out "$tmp/count-bad" \
  --pretrained "lb=$tmp/init-good.bin"
expect_fail 2 "expected LABEL=CHECKPOINT" counting --out "$tmp/count-bad" --pretrained nolabel
expect_fail 2 "seeds 0: must be in" counting --out "$tmp/count-bad" --seeds 0
expect_fail 2 "probe of a frozen policy" eval --out "$tmp/eval-bad" --tasks object-counting
[ -e "$tmp/count-bad" ] && { failed=$((failed + 1)); echo "FAIL: a refused hns counting created its folder"; }
# The shipped recipes (configs/) are valid configs that train: each runs one iteration shrunk to 4 envs.
configs="$(cd "$(dirname "$0")/../../configs" && pwd)"
for cfg in "$configs"/*.json; do
  name="$(basename "$cfg" .json)"
  if "$hns" train --config "$cfg" --envs 4 --iterations 1 --threads 1 --out "$tmp/cfg-$name" >"$tmp/log" 2>&1 &&
     [ "$(wc -l <"$tmp/cfg-$name/metrics.jsonl")" -eq 1 ]; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL: recipe $cfg"; cat "$tmp/log"
  fi
done

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
