#!/usr/bin/env python3
"""The docs name only what the program has: every `hns SUBCOMMAND` and every `--flag` of one written in the
README or docs/*.md (in code spans and code blocks) exists in that subcommand's --help, every `--scene X` names a
scene of the program, and every scene of the program (`hns train --help`, and hns.scenes where the Python
package is built) is named in the README.

Usage: docs_test.py path/to/hns REPO_ROOT [PYTHON_PACKAGE_DIR]
"""
import pathlib
import re
import subprocess
import sys

hns, root = sys.argv[1], pathlib.Path(sys.argv[2])
package_dir = sys.argv[3] if len(sys.argv) > 3 else ""
failures = []


def help_text(*args):
    return subprocess.run([hns, *args, "--help"], capture_output=True, text=True, timeout=60).stdout


top = help_text()
subcommands = re.findall(r"^  ([a-z]+)\s{2,}", top.split("Subcommands:", 1)[1], re.M)
if not subcommands:
    sys.exit("could not read the subcommands from hns --help:\n" + top)
flags = {sub: set(re.findall(r"(--[a-z][a-z0-9-]*)", help_text(sub))) for sub in subcommands}
scene_line = next(line for line in help_text("train").splitlines() if line.strip().startswith("--scene"))
scenes = re.findall(r"[a-z][a-z-]+", scene_line.split("TEXT", 1)[1].split("(default", 1)[0])
if len(scenes) < 4:
    sys.exit("could not read the scenes from hns train --help: " + scene_line)

docs = [root / "README.md", *sorted((root / "docs").glob("*.md"))]


def code_of(text):
    """Code spans and code blocks (fenced, or indented by 4 spaces after a blank line) of a Markdown text."""
    out = []
    in_fence = False
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            in_fence = not in_fence
            continue
        if in_fence or line.startswith("    "):
            out.append(line)
        else:
            out.extend(re.findall(r"`([^`]+)`", line))
    return out


checked = 0
for doc in docs:
    name = doc.relative_to(root)
    for code in code_of(doc.read_text()):
        for m in re.finditer(r"(?:^|[\s/(])hns ([a-z][a-z-]*)((?: [^|;&#`]*)?)", code):
            sub, rest = m.group(1), m.group(2)
            if sub in ("help",):
                continue
            checked += 1
            if sub not in subcommands:
                failures.append(f"{name}: `hns {sub}` is not a subcommand of hns ({code.strip()})")
                continue
            for flag in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", rest):
                checked += 1
                if flag not in flags[sub]:
                    failures.append(f"{name}: `hns {sub} ... {flag}`: hns {sub} --help has no {flag} ({code.strip()})")
            for scene in re.findall(r"--scene[ =]([a-z][a-z-]*)", rest):
                checked += 1
                if scene not in scenes:
                    failures.append(f"{name}: --scene {scene} is not a scene of hns ({code.strip()})")

# The scene registry, as every command that takes --scene prints it: rows of name, family, summary.
def registry_of(sub):
    text = help_text(sub)
    if "\nScenes:\n" not in text:
        failures.append(f"hns {sub} --help has no Scenes: list")
        return []
    return [tuple(re.split(r"\s{2,}", line.strip(), maxsplit=2)) for line in
            text.split("\nScenes:\n", 1)[1].splitlines() if line.startswith("  ")]


registry = registry_of("train")
checked += 1
if [row[0] for row in registry] != scenes:
    failures.append(f"hns train --help: the Scenes list {[r[0] for r in registry]} differs from --scene's {scenes}")
for sub in ("play", "bench"):
    checked += 1
    if registry_of(sub) != registry:
        failures.append(f"hns {sub} --help lists other scenes than hns train --help")
# README's scene table: one row per scene, same family, the summary as the program prints it.
readme_rows = re.findall(r"^\| `([a-z-]+)` \| ([a-z-]+) \| (.*) \|$", (root / "README.md").read_text(), re.M)
checked += 1
if [r[0] for r in readme_rows] != [r[0] for r in registry]:
    failures.append(f"README.md's scene table {[r[0] for r in readme_rows]} differs from hns train --help's "
                    f"{[r[0] for r in registry]}")
for (name, family, what), row in zip(readme_rows, registry):
    checked += 1
    if len(row) != 3 or family != row[1] or not what.replace("`", "").startswith(row[2]):
        failures.append(f"README.md's scene table row `{name}` ({family}: {what}) differs from the program's {row}")
# hns eval takes the transfer family, and its --help names exactly those.
transfer = [row[0] for row in registry if len(row) == 3 and row[1] == "transfer"]
eval_help = " ".join(help_text("eval").split())
checked += 1
if "transfer tasks, of " + ", ".join(transfer) not in eval_help:
    failures.append(f"hns eval --help does not name the transfer scenes {transfer}")

# The game and the design are written down in the repository: every `docs/game.md §N` and
# `docs/design.md "Heading"` that a source file or doc cites has its heading, and nothing cites a document
# the repository does not have.
game_sections = set(re.findall(r"^#+ (\d+(?:\.\d+)?)[. ]", (root / "docs/game.md").read_text(), re.M))
design_sections = set(re.findall(r"^## (.+?)\s*$", (root / "docs/design.md").read_text(), re.M))
cited_trees = ["src", "tools", "python", "tests", "bench", "docs", "examples", "configs", "cmake"]
for path in sorted(p for tree in cited_trees for p in (root / tree).rglob("*") if p.is_file()):
    if path.suffix not in (".cpp", ".hpp", ".h", ".py", ".md", ".sh", ".txt", ".cmake", ".html", ".json") or \
            path.name == "docs_test.py":
        continue
    text = path.read_text(errors="replace")
    name = path.relative_to(root)
    for m in re.finditer(r"docs/game\.md §\s*(\d+(?:\.\d+)?)((?:\s*(?:,|and|-)\s*§?\s*\d+(?:\.\d+)?)*)", text):
        for number in [m.group(1)] + re.findall(r"\d+(?:\.\d+)?", m.group(2)):
            checked += 1
            if number not in game_sections:
                failures.append(f"{name}: cites docs/game.md §{number}, which has no such section")
    for m in re.finditer(r'docs/design\.md "([^"]+)"', text):
        checked += 1
        if m.group(1) not in design_sections:
            failures.append(f'{name}: cites docs/design.md "{m.group(1)}", which has no such section')
    # The two names written so that this file does not contain them (`git grep` of them finds nothing in tests).
    for m in re.finditer(r"\bSP[E]C\b|DESI[G]N\.md", text):
        failures.append(f"{name}: cites {m.group(0)}, a document the repository does not have")

readme_code = "\n".join(code_of((root / "README.md").read_text()))
for scene in scenes:
    checked += 1
    if not re.search(r"(?<![\w-])" + re.escape(scene) + r"(?![\w-])", readme_code):
        failures.append(f"README.md does not name the scene `{scene}` (hns train --help lists it)")

if package_dir:
    out = subprocess.run(
        [sys.executable, "-c", "import hns; print(' '.join(hns.scenes)); "
         "print(' '.join(hns.scene_info[s]['family'] for s in hns.scenes))"],
        capture_output=True, text=True, env={"PYTHONPATH": package_dir}, timeout=60,
    )
    if out.returncode != 0:
        failures.append("import hns failed: " + out.stderr.strip())
    else:
        checked += 1
        names, families = (out.stdout.splitlines() + ["", ""])[:2]
        if names.split() != scenes:
            failures.append(f"hns.scenes {names.split()} differs from hns train --help's {scenes}")
        checked += 1
        if families.split() != [row[1] for row in registry if len(row) == 3]:
            failures.append(f"hns.scene_info's families {families.split()} differ from hns train --help's")

for f in failures:
    print("FAIL:", f)
print(f"docs test: {checked} names checked, {len(failures)} failures")
sys.exit(1 if failures else 0)
