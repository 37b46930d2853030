#!/usr/bin/env bash
# Every policy shipped in models/ loads and plays (hns play --checkpoint, one episode, with its replay page)
# and models/README.md describes it; every file the README names is shipped; no file records a directory of the
# machine that trained it (an absolute path in its config, such as init_from).
# Usage: models_test.sh path/to/hns path/to/models
set -u
hns="$1"
models="$2"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
passed=0
failed=0
shopt -s nullglob
files=("$models"/*.hnspolicy)
if [ "${#files[@]}" -eq 0 ]; then
  echo "FAIL: no policy in $models"
  exit 1
fi
for f in "${files[@]}"; do
  name="$(basename "$f")"
  ok=1
  if ! "$hns" play --checkpoint "$f" --episodes 1 --out "$tmp/p.traj" --html "$tmp/p.html" >"$tmp/log" 2>&1 ||
     ! grep -q "checkpoint's policy" "$tmp/log" || ! grep -q 'id="hns-status"' "$tmp/p.html" ||
     ! grep -q "^| \`$name\`" "$models/README.md"; then
    ok=0
    echo "FAIL: $name does not play, or models/README.md has no row for it"
    cat "$tmp/log"
  fi
  if grep -aq '": "/' "$f"; then
    ok=0
    echo "FAIL: $name records an absolute path of the machine that trained it: $(grep -ao '"[a-z_]*": "/[^"]*"' "$f")"
  fi
  if [ "$ok" -eq 1 ]; then passed=$((passed + 1)); else failed=$((failed + 1)); fi
done
for name in $(grep -o '^| `[^`]*\.hnspolicy`' "$models/README.md" | tr -d '|` '); do
  [ -f "$models/$name" ] || { failed=$((failed + 1)); echo "FAIL: models/README.md names $name, which is not there"; }
done
echo "models: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
