#!/usr/bin/env bash
# Replay pages in a real browser (headless Chromium): the canvas draws the recorded agents, boxes and ramps,
# scrubbing (#frame=N) changes the drawn frame, a 240-step full-scene episode draws quickly, and screenshots
# are saved. Exits 77 (ctest: skipped) with a message where Chromium is not installed; tools/test installs it.
# Usage: replay_browser_test.sh path/to/hns SCREENSHOT_DIR
set -u
hns="$1"
shots="$2"
browser=""
for b in chromium chromium-browser google-chrome; do
  if command -v "$b" >/dev/null 2>&1; then browser="$(command -v "$b")"; break; fi
done
if [ -z "$browser" ]; then
  echo "SKIP: no headless Chromium found (install the Debian package 'chromium'; tools/test does it)"
  exit 77
fi
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$shots"
passed=0
failed=0
pass() { passed=$((passed + 1)); }
fail() { failed=$((failed + 1)); echo "FAIL: $*"; }

# These flags keep Chromium quiet on a machine without network: no background traffic, no GPU, no sandbox.
chrome() {
  timeout 90 "$browser" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
    --disable-background-networking --disable-component-update --disable-sync --hide-scrollbars \
    --user-data-dir="$(mktemp -d -p "$tmp")" "$@" 2>>"$tmp/chromium.log"
}
# status PAGE HASH: the page's <output id="hns-status"> element after load.
status() { chrome --dump-dom "file://$1#$2" | grep -o '<output id="hns-status"[^>]*>'; }
# attr NAME STATUS: one data-* attribute of a status element.
attr() { grep -o "data-$1=\"[^\"]*\"" <<<"$2" | head -n1 | sed 's/.*="\(.*\)"/\1/'; }

# expect_drawn LABEL PAGE HASH AGENTS BOXES RAMPS: the page is ready and drew exactly these counts.
expect_drawn() {
  local label="$1" page="$2" hash="$3" s
  s="$(status "$page" "$hash")"
  if [ "$(attr state "$s")" = "ready" ] && [ "$(attr drawn-agents "$s")" = "$4" ] &&
     [ "$(attr drawn-boxes "$s")" = "$5" ] && [ "$(attr drawn-ramps "$s")" = "$6" ]; then
    pass
  else
    fail "$label: expected $4 agents, $5 boxes, $6 ramps drawn; status: ${s:-<none>}"
  fi
}

# Recordings with fixed counts, so the expected drawing is known.
if ! "$hns" play --scene quadrant --episodes 2 --envs 2 --seed 7 --out "$tmp/q.traj" >"$tmp/log" 2>&1 ||
   ! "$hns" replay "$tmp/q.traj" --html "$tmp/q.html" >>"$tmp/log" 2>&1 ||
   ! "$hns" play --scene full --hiders 2 --seekers 3 --boxes 6 --ramps 2 --seed 3 --out "$tmp/f.traj" >>"$tmp/log" 2>&1 ||
   ! "$hns" replay "$tmp/f.traj" --html "$tmp/f.html" >>"$tmp/log" 2>&1; then
  cat "$tmp/log"
  echo "FAIL: could not record and render the test pages"
  exit 1
fi

expect_drawn "quadrant frame 0" "$tmp/q.html" "frame=0" 4 2 1
expect_drawn "quadrant episode 1" "$tmp/q.html" "episode=1&frame=50" 4 2 1
expect_drawn "full frame 200" "$tmp/f.html" "frame=200&lidar=1" 5 6 2

# Scrubbing: another frame draws other data and other pixels; the same frame twice draws the same.
a="$(status "$tmp/f.html" "frame=10&probe=1")"
b="$(status "$tmp/f.html" "frame=150&probe=1")"
c="$(status "$tmp/f.html" "frame=150&probe=1")"
if [ "$(attr frame "$b")" = "150" ] && [ -n "$(attr frame-hash "$a")" ] && [ -n "$(attr pixel-hash "$a")" ] &&
   [ "$(attr frame-hash "$a")" != "$(attr frame-hash "$b")" ] &&
   [ "$(attr pixel-hash "$a")" != "$(attr pixel-hash "$b")" ] &&
   [ "$(attr pixel-hash "$b")" = "$(attr pixel-hash "$c")" ]; then
  pass
else
  fail "scrubbing: frame 10 -> $a; frame 150 -> $b; again -> $c"
fi
# Frames past the end clamp to the last one (frame 240 of 241).
s="$(status "$tmp/f.html" "frame=9999")"
[ "$(attr frame "$s")" = "240" ] && [ "$(attr frames "$s")" = "241" ] && pass || fail "clamped frame: $s"
# Lidar on demand: 30 rays per agent when asked, none by default.
s="$(status "$tmp/f.html" "frame=100&lidar=1")"
[ "$(attr drawn-lidar-rays "$s")" = "150" ] && pass || fail "lidar rays: $s"
s="$(status "$tmp/f.html" "frame=100")"
[ "$(attr drawn-lidar-rays "$s")" = "0" ] && pass || fail "lidar off by default: $s"

# Playback (virtual time, so no waiting): 3 s at 2x moves about 80 frames on; at 8x it stops on the last frame.
played() { chrome --virtual-time-budget="$2" --dump-dom "file://$tmp/f.html#$1" | grep -o '<output id="hns-status"[^>]*>'; }
s="$(played "play=1&speed=2" 3000)"
f="$(attr frame "$s")"
[ -n "$f" ] && [ "$f" -gt 20 ] && [ "$f" -lt 240 ] && pass || fail "playing 3 s at 2x: $s"
s="$(played "play=1&speed=8" 6000)"
[ "$(attr frame "$s")" = "240" ] && pass || fail "playing to the end: $s"

# A page whose embedded data is broken says so instead of drawing (hns replay never writes one; hand edits might).
sed 's|<script id="trajectory" type="application/octet-stream">[^<]*</script>|<script id="trajectory" type="application/octet-stream">SGVsbG8gd29ybGQh</script>|' \
  "$tmp/q.html" >"$tmp/broken.html"
s="$(status "$tmp/broken.html" "frame=0")"
[ "$(attr state "$s")" = "error" ] && grep -q "not an hns trajectory" <<<"$(attr error "$s")" && pass ||
  fail "broken page: $s"

# Pages built from files someone sent run no code from them (README "Reliability"). A recording whose episode
# header names a "scene" that is markup (hns's reader refuses such a file; the page reads the bytes itself, so
# it must not trust them either): the page renders, and the markup stays text.
inject='<img src=x onerror="document.body.dataset.pwned=1">'
python3 - "$tmp/q.traj" "$tmp/evil.traj" "$inject" <<'PY'
import json, struct, sys
src, dst, evil = sys.argv[1], sys.argv[2], sys.argv[3]
data = open(src, "rb").read()
out, pos = bytearray(data[:8]), 8
while pos < len(data):
    (n,) = struct.unpack_from("<I", data, pos)
    header = json.loads(data[pos + 4 : pos + 4 + n])
    payload = data[pos + 4 + n : pos + 4 + n + header["payload_bytes"]]
    if header["kind"] == "episode":
        header["scene"] = evil
        header["layout"] = evil
        # Re-summed as docs/trajectory-format.md says (compact, keys sorted, without the key), so that the
        # reader's name check, not the checksum, is what refuses the file.
        rest = {k: v for k, v in header.items() if k != "header_fnv1a64"}
        h = 0xCBF29CE484222325
        for b in json.dumps(rest, separators=(",", ":"), sort_keys=True, ensure_ascii=False).encode():
            h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
        header["header_fnv1a64"] = "%016x" % h
    text = json.dumps(header).encode()
    start = len(out) + 4
    text += b" " * ((-(start + len(text))) % 8)
    out += struct.pack("<I", len(text)) + text + payload
    pos += 4 + n + len(payload)
open(dst, "wb").write(bytes(out))
PY
if "$hns" replay "$tmp/evil.traj" --html "$tmp/evil.html" >"$tmp/log" 2>&1; then
  fail "hns replay accepted a trajectory whose scene is markup"
elif grep -q "scene.*is not a scene of hns" "$tmp/log"; then
  pass
else
  fail "hns replay refused the markup scene without naming it: $(cat "$tmp/log")"
fi
b64="$(base64 -w0 "$tmp/evil.traj")"
awk -v data="$b64" '{ if (sub(/<script id="trajectory" type="application\/octet-stream">[^<]*<\/script>/, "<script id=\"trajectory\" type=\"application/octet-stream\">" data "</script>")) {} print }' \
  "$tmp/q.html" >"$tmp/evil.html"
dom="$(chrome --virtual-time-budget=2000 --dump-dom "file://$tmp/evil.html#frame=0")"
s="$(grep -o '<output id="hns-status"[^>]*>' <<<"$dom")"
if [ "$(attr state "$s")" = "ready" ] && ! grep -q "data-pwned" <<<"$dom" && grep -q "&lt;img src=x" <<<"$dom"; then
  pass
else
  fail "a markup scene in a replay page ran or vanished: ${s:-<none>}; pwned: $(grep -c data-pwned <<<"$dom")"
fi
# The report page: a config.json holding "<!--<script>" and "</script>" with markup renders, and runs nothing.
mkdir -p "$tmp/evil-run"
printf '%s\n' '{"iteration": 1, "agent_steps": 100, "hider_reward": 0, "seeker_reward": 0}' >"$tmp/evil-run/metrics.jsonl"
printf '{"scene": "quadrant", "note": "<!--<script>", "other": "</script>%s"}\n' "${inject//\"/\\\"}" \
  >"$tmp/evil-run/config.json"
cp "$tmp/q.traj" "$tmp/evil-run/replay.traj"
if "$hns" report "$tmp/evil-run" --html "$tmp/evil-report.html" >"$tmp/log" 2>&1; then
  dom="$(chrome --virtual-time-budget=2000 --dump-dom "file://$tmp/evil-report.html")"
  s="$(grep -o '<output id="hns-status"[^>]*>' <<<"$dom")"
  if [ "$(attr state "$s")" = "ready" ] && [ "$(attr replay "$s")" = "1" ] && ! grep -q "data-pwned" <<<"$dom" &&
     grep -q 'sandbox="allow-scripts"' "$tmp/evil-report.html"; then
    pass
  else
    fail "report page with markup in config.json: ${s:-<none>}; pwned: $(grep -c data-pwned <<<"$dom")"
  fi
else
  cat "$tmp/log"
  fail "could not report the run with markup in its config"
fi

# Responsiveness: every frame of the 240-step full episode drawn once (reported, not judged: timing is noisy).
s="$(status "$tmp/f.html" "bench=1&frame=0")"
if [ -n "$(attr draw-ms-mean "$s")" ]; then
  pass
  echo "full scene, 241 frames: $(attr draw-ms-mean "$s") ms per frame on average, $(attr draw-ms-max "$s") ms at most"
else
  fail "bench mode: $s"
fi

# The training report: a short real run (checkpoint, hence a recording, every iteration) rendered as a page
# that draws its 16 charts from all 3 iterations, each with its quantity's unit on the y axis, and embeds the
# replay of the latest policy.
if "$hns" train --scene lockbox --envs 4 --iterations 3 --threads 1 --set checkpoint_every=1 --set minibatches=2 \
     --out "$tmp/run" >"$tmp/log" 2>&1 && "$hns" report "$tmp/run" --html "$tmp/report.html" >>"$tmp/log" 2>&1; then
  s="$(status "$tmp/report.html" "")"
  ytitles="$(attr ytitles "$s")"
  if [ "$(attr state "$s")" = "ready" ] && [ "$(attr charts "$s")" = "16" ] && [ "$(attr points "$s")" = "3" ] &&
     [ "$(attr replay "$s")" = "1" ] && [ "$(attr series "$s")" -ge 9 ] && ! grep -q 'https\?://' "$tmp/report.html" &&
     [ "$(tr '|' '\n' <<<"$ytitles" | grep -c .)" = "16" ] && grep -q "m/s" <<<"$ytitles" &&
     grep -q "fraction (0 to 1)" <<<"$ytitles" && grep -q "agent-steps/s" <<<"$ytitles"; then
    pass
  else
    fail "report page: ${s:-<none>}"
  fi
  chrome --window-size=1280,1600 --screenshot="$shots/report.png" "file://$tmp/report.html" >/dev/null
  [ -s "$shots/report.png" ] && pass || fail "screenshot report.png missing"
else
  cat "$tmp/log"
  fail "could not train and report"
fi

# Screenshots for people to look at.
chrome --window-size=1280,1000 --screenshot="$shots/replay_full.png" "file://$tmp/f.html#frame=150&lidar=1" >/dev/null
chrome --window-size=1280,1000 --screenshot="$shots/replay_quadrant.png" "file://$tmp/q.html#episode=1&frame=60" >/dev/null
for png in replay_full.png replay_quadrant.png; do
  if [ -s "$shots/$png" ] && [ "$(head -c 8 "$shots/$png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]; then
    pass
  else
    fail "screenshot $png missing or not a PNG"
  fi
done
# The agent-step axis reads whole numbers right: ticks at 200k ... 800k are labelled so, not "2k ... 8k".
mkdir -p "$tmp/axis"
for i in 0 1 2 3 4; do
  echo "{\"iteration\": $((i + 1)), \"agent_steps\": $((i * 200000)), \"hider_reward\": 0.$i, \"seeker_reward\": -0.$i}"
done >"$tmp/axis/metrics.jsonl"
if "$hns" report "$tmp/axis" --html "$tmp/axis.html" >"$tmp/log" 2>&1; then
  labels="$(attr xlabels "$(status "$tmp/axis.html" "")")"
  [ "$labels" = "0 200k 400k 600k 800k" ] && pass || fail "agent-step axis labels: '$labels'"
else
  cat "$tmp/log"
  fail "could not report the axis run"
fi

# The stage band and markers: a quadrant run whose seekers chase from iteration 6 on and whose episodes seal
# both doors from iteration 21 on reaches running and chasing and fort building (windows of 1000 episodes:
# 10 iterations of 100); the page shades the return chart from each, marks each stage's first iteration
# with a named line, and lists them, and the command prints them.
mkdir -p "$tmp/stages"
echo '{"scene": "quadrant"}' >"$tmp/stages/config.json"
for i in $(seq 1 40); do
  sealed=0; [ "$i" -ge 21 ] && sealed=2
  approach=0.1; [ "$i" -ge 6 ] && approach=0.5
  echo "{\"iteration\": $i, \"agent_steps\": $((i * 20480)), \"episodes\": 100, \"hider_reward\": 0, \"seeker_reward\": 0, \"num_doors\": 2, \"num_door_sealed_prep\": $sealed, \"seeker_approach\": $approach}"
done >"$tmp/stages/metrics.jsonl"
if "$hns" report "$tmp/stages" --html "$tmp/stages.html" >"$tmp/log" 2>&1 &&
   grep -q "fort building: from iteration 25 " "$tmp/log"; then
  s="$(status "$tmp/stages.html" "")"
  if [ "$(attr stages "$s")" = "5" ] && [ "$(attr stages-reached "$s")" = "running-and-chasing fort-building" ] &&
     [ "$(attr band-spans "$s")" = "2" ] &&
     [ "$(attr stage-markers "$s")" = "running-and-chasing fort-building" ]; then
    pass
  else
    fail "stage band: ${s:-<none>}"
  fi
  chrome --window-size=1280,1000 --screenshot="$shots/report_stages.png" "file://$tmp/stages.html" >/dev/null
else
  cat "$tmp/log"
  fail "could not report the staged run"
fi

echo "screenshots: $shots/replay_full.png $shots/replay_quadrant.png $shots/report.png"

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
