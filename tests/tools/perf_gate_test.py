#!/usr/bin/env python3
"""tools/perf-gate: the decision rule on synthetic ratios, and the gate end to end on fake builds (a tiny
CMake project whose benchmark executable is a script that answers like Google Benchmark), for its exit
statuses, its refusals and its reports."""
import importlib.machinery
import importlib.util
import io
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import textwrap
import unittest
from contextlib import redirect_stderr, redirect_stdout

HERE = os.path.dirname(os.path.abspath(__file__))
GATE = os.path.join(HERE, "..", "..", "tools", "perf-gate")
loader = importlib.machinery.SourceFileLoader("perf_gate", GATE)
spec = importlib.util.spec_from_loader("perf_gate", loader)
gate = importlib.util.module_from_spec(spec)
loader.exec_module(gate)
# Nothing here may write into a real CI job's summary.
os.environ.pop("GITHUB_STEP_SUMMARY", None)


def noisy(n, slowdown, sigma, seed):
    """n per-pair ratios: a true slowdown times log-normal noise of the given sigma."""
    rng = random.Random(seed)
    return [(1 + slowdown) * math.exp(rng.gauss(0, sigma)) for _ in range(n)]


def sequential(slowdown, sigma, seed, first=4, last=14):
    """The gate's sequential procedure on simulated pairs: a verdict after `first` pairs, then one more pair
    at a time while undecided, the last verdict final."""
    ratios = noisy(last, slowdown, sigma, seed)
    for n in range(first, last + 1):
        v = gate.judge(ratios[:n], 0.05, final=n == last)["verdict"]
        if v != "undecided":
            return v


class DecisionRule(unittest.TestCase):
    def test_five_percent_with_little_noise_is_caught(self):
        row = gate.judge(noisy(6, 0.05, 0.005, 1), 0.05)
        self.assertEqual(row["verdict"], "regression", row)
        self.assertAlmostEqual(row["ratio"], 1.05, delta=0.01)

    def test_no_change_with_heavy_noise_is_not_flagged(self):
        # 15 % noise per pair, no change: this sample (median +5.6 %, 5 of 6 pairs slower) is not flagged,
        # and over many simulated gate runs (4 pairs, then one more at a time up to 14) hardly any is.
        ratios = [1.056, 1.30, 0.88, 1.12, 1.05, 1.09]
        for final in (False, True):
            self.assertNotEqual(gate.judge(ratios, 0.05, final=final)["verdict"], "regression")
        alarms = sum(sequential(0.0, 0.15, seed) == "regression" for seed in range(400))
        self.assertLessEqual(alarms, 12)  # 3 %; the noise is 3x the threshold

    def test_no_change_with_typical_noise_clears(self):
        self.assertEqual(gate.judge(noisy(4, 0.0, 0.01, 3), 0.05)["verdict"], "ok")

    def test_a_small_change_is_not_a_regression(self):
        # +1 %: below the bias allowance, whatever the precision.
        self.assertNotEqual(gate.judge(noisy(40, 0.01, 0.002, 4), 0.05)["verdict"], "regression")

    def test_one_disturbed_pair_does_not_hide_a_large_slowdown(self):
        # Six pairs: the sign test needs all six slower, so the gate adds pairs; with eight, one may differ.
        ratios = [1.25, 1.26, 1.24, 0.96, 1.25, 1.27]
        self.assertEqual(gate.judge(ratios, 0.05, final=False)["verdict"], "undecided")
        self.assertEqual(gate.judge(ratios + [1.26, 1.24], 0.05)["verdict"], "regression")

    def test_one_disturbed_pair_does_not_make_a_regression(self):
        ratios = [1.0, 1.01, 0.99, 1.35, 1.0, 0.995]
        self.assertNotEqual(gate.judge(ratios, 0.05)["verdict"], "regression")

    def test_undecided_until_final_then_warning(self):
        ratios = [1.0, 1.12, 0.95, 1.08]  # wide: neither rules out 5 % nor shows a slowdown
        self.assertEqual(gate.judge(ratios, 0.05, final=False)["verdict"], "undecided")
        row = gate.judge(ratios, 0.05, final=True)
        self.assertEqual(row["verdict"], "warning")
        self.assertIn("inconclusive", row["note"])

    def test_clear_speedup_is_reported_faster(self):
        self.assertEqual(gate.judge(noisy(5, -0.2, 0.01, 5), 0.05)["verdict"], "faster")

    def test_one_pair_is_refused(self):
        with self.assertRaises(gate.UsageError):
            gate.judge([1.3], 0.05)
        self.assertEqual(quiet(gate.main, ["--pairs", "1"]), 2)
        self.assertEqual(quiet(gate.main, ["--pairs", "2"]), 2)

    def test_false_alarm_and_power_of_the_sequential_rule(self):
        # The rule as the gate applies it, on simulated pairs with 2 % log-normal noise (the 2-core CI
        # machine's noise on most benchmarks; docs/perf-gate.md): a 5 % slowdown is caught in >= 90 % of
        # runs, 10 % always, and a benchmark that did not change is flagged in well under 1 % of runs.
        runs = 400
        caught5 = sum(sequential(0.05, 0.02, s) == "regression" for s in range(runs))
        caught10 = sum(sequential(0.10, 0.02, s) == "regression" for s in range(runs))
        alarms = sum(sequential(0.0, 0.02, s) == "regression" for s in range(runs))
        self.assertGreaterEqual(caught5, 0.9 * runs)
        self.assertEqual(caught10, runs)
        self.assertLessEqual(alarms, 2)
        # and a real 5 % slowdown is rarely declared "ok" (the rule's nominal rate is 1 %; the noise estimate
        # from a handful of pairs costs a little more; it may end undecided, as a warning)
        cleared5 = sum(sequential(0.05, 0.02, s) == "ok" for s in range(runs))
        self.assertLessEqual(cleared5, 0.02 * runs)

    def test_too_few_pairs_to_ever_fail_are_refused(self):
        # With 4 pairs the sign test cannot confirm anything at 95 %: such a gate could never fail.
        self.assertEqual(gate.judge([1.5] * 4, 0.05)["verdict"], "warning")
        self.assertEqual(gate.judge([1.5] * 5, 0.05)["verdict"], "regression")
        self.assertEqual(quiet(gate.main, ["--pairs", "3", "--max-pairs", "4"]), 2)

    def test_missing_and_new_benchmarks(self):
        base = [{"old_name": 10.0, "kept": 5.0}] * 4
        cur = [{"new_name": 10.0, "kept": 5.0}] * 4
        rows = {r["benchmark"]: r for r in gate.compare(base, cur, 0.05)}
        self.assertEqual(rows["old_name"]["verdict"], "missing")
        self.assertEqual(rows["new_name"]["verdict"], "new")
        self.assertEqual(rows["kept"]["verdict"], "ok")
        status, sentence = gate.exit_status(list(rows.values()), [])
        self.assertEqual(status, 2)
        self.assertIn("old_name", sentence)

    def test_exit_statuses(self):
        reg = {"benchmark": "a", "verdict": "regression", "ratio": 1.1}
        ok = {"benchmark": "b", "verdict": "ok", "ratio": 1.0}
        self.assertEqual(gate.exit_status([ok], [])[0], 0)
        self.assertEqual(gate.exit_status([ok, reg], [])[0], 1)
        self.assertEqual(gate.exit_status([ok, reg], ["bench_x crashed"])[0], 3)

    def test_acceptance(self):
        rows = [{"benchmark": "a", "verdict": "regression", "ratio": 1.07, "note": "7% slower"},
                {"benchmark": "b", "verdict": "regression", "ratio": 1.12, "note": "12% slower"},
                {"benchmark": "c", "verdict": "missing", "ratio": None, "note": ""}]
        gate.apply_acceptances(rows, {"a": 1.08, "b": 1.08, "c": "missing"})
        self.assertEqual([r["verdict"] for r in rows], ["accepted", "regression", "accepted"])
        self.assertEqual(gate.parse_acceptance("BM_X 1.08", "t"), ("BM_X", 1.08))
        for bad in ("BM_X", "BM_X 0.9", "BM_X fast", "BM_X 1.1 extra"):
            with self.assertRaises(gate.UsageError):
                gate.parse_acceptance(bad, "t")

    def test_instruction_counts(self):
        self.assertEqual(gate.judge_instructions("i", 1000, 1100, 0.025)["verdict"], "regression")
        self.assertEqual(gate.judge_instructions("i", 1000, 1001, 0.025)["verdict"], "ok")
        self.assertIsNone(gate.judge_instructions("i", None, 1000, 0.025))

    def test_callgrind_file_parsing(self):
        text = textwrap.dedent("""\
            # callgrind format
            events: Ir
            summary: 1000
            fn=(1) outer()
            0 100
            cfn=(2) inner(int)
            calls=3 0
            0 700
            fn=(2)
            0 650
            cfn=(3) leaf
            calls=1 0
            0 50
            fn=(3)
            0 50
            fn=(4) other
            +2 150
            """)
        with tempfile.NamedTemporaryFile("w", suffix=".out", delete=False) as f:
            f.write(text)
        try:
            c = gate.parse_callgrind(f.name)
        finally:
            os.unlink(f.name)
        self.assertEqual(c["total"], 1000)
        self.assertEqual(c["self"], {"outer()": 100, "inner(int)": 650, "leaf": 50, "other": 150})
        self.assertEqual(c["inclusive"]["outer()"], 800)
        self.assertEqual(c["inclusive"]["inner(int)"], 700)
        self.assertEqual(gate.suite_count(c, ["inner(", "outer("]), 1500)
        deltas = gate.top_function_deltas(c, {"self": {"outer()": 100, "inner(int)": 900, "leaf": 50}})
        self.assertEqual(deltas[0]["function"], "inner(int)")
        self.assertEqual(deltas[0]["delta"], 250)

    def test_bad_usage_exits_2(self):
        for argv in (["--max-pairs", "2"], ["--pairs", "4", "--max-pairs", "4"], ["--threshold", "2"], ["--suite", "no-colon"],
                     ["--suite", "bench_x:("], ["--baseline-src", "/nonexistent/folder"],
                     ["--accept", "BM_X=0.5"], ["--alpha", "0"], ["--time-limit", "0"]):
            self.assertEqual(quiet(gate.main, argv), 2, argv)


    def test_report_only_exits_0_even_on_bad_usage_and_writes_why(self):
        with tempfile.TemporaryDirectory() as d:
            summary = os.path.join(d, "ci", "summary.md")
            self.assertEqual(quiet(gate.main, ["--report-only", "--suite", "no-colon", "--summary", summary]), 0)
            with open(summary) as f:
                self.assertIn("exit status 2", f.read())

    def test_a_failure_of_the_gate_itself_is_3_not_a_regression(self):
        real = gate.gate
        gate.gate = lambda args: {}["no such key"]
        try:
            self.assertEqual(quiet(gate.main, ["--instructions", "off"]), 3)
            self.assertEqual(quiet(gate.main, ["--instructions", "off", "--report-only"]), 0)
        finally:
            gate.gate = real

    def test_acceptance_names_may_hold_spaces(self):
        self.assertEqual(gate.parse_acceptance("instructions: bench_physics 1.06", "t"),
                         ("instructions: bench_physics", 1.06))
        self.assertEqual(gate.parse_acceptance("BM_Old missing", "t"), ("BM_Old", "missing"))


class BaselineIsa(unittest.TestCase):
    """The baseline is built with the current build's code settings; a tree from before HNS_ISA gets the
    instruction set as compiler flags."""

    def tree(self, cmake_text):
        d = tempfile.mkdtemp()
        with open(os.path.join(d, "CMakeLists.txt"), "w") as f:
            f.write(cmake_text)
        return d

    def test_old_tree_gets_flags_new_tree_keeps_the_option(self):
        old, new = self.tree("option(HNS_NATIVE ...)\n"), self.tree('set(HNS_ISA "avx2" CACHE STRING "")\n')
        with redirect_stderr(io.StringIO()):
            self.assertEqual(gate.isa_args_for(old, ["-DHNS_ISA=avx512", "-DHNS_FMA=ON"]),
                             ["-DHNS_FMA=ON", "-DCMAKE_CXX_FLAGS=-march=x86-64-v4"])
            self.assertEqual(gate.isa_args_for(old, ["-DHNS_ISA=native"]), ["-DHNS_NATIVE=ON"])
            self.assertEqual(gate.isa_args_for(old, ["-DHNS_ISA=avx2"]), ["-DHNS_ISA=avx2"])
        self.assertEqual(gate.isa_args_for(new, ["-DHNS_ISA=avx512"]), ["-DHNS_ISA=avx512"])
        self.assertEqual(gate.isa_args_for(old, ["-DHNS_FMA=OFF"]), ["-DHNS_FMA=OFF"])

    def test_baseline_takes_the_current_builds_code_settings(self):
        # The settings that change the binaries (HNS_PCH: their layout) come from --current-build's cache,
        # unless given for the baseline explicitly.
        build = tempfile.mkdtemp()
        with open(os.path.join(build, "CMakeCache.txt"), "w") as f:
            f.write("CMAKE_BUILD_TYPE:STRING=Release\nHNS_ISA:STRING=avx2\nHNS_FMA:BOOL=OFF\nHNS_PCH:BOOL=OFF\n")
        src = os.path.dirname(os.path.dirname(GATE))
        args = gate.parse_args(["--current-build", build, "--current-src", src])
        self.assertEqual(args.baseline_cmake_args.split(), ["-DHNS_ISA=avx2", "-DHNS_FMA=OFF", "-DHNS_PCH=OFF"])
        args = gate.parse_args(["--current-build", build, "--current-src", src,
                                "--baseline-cmake-args=-DHNS_PCH=ON"])
        self.assertEqual(args.baseline_cmake_args.split(), ["-DHNS_PCH=ON", "-DHNS_ISA=avx2", "-DHNS_FMA=OFF"])


class ExportRevision(unittest.TestCase):
    """An export over an earlier one rewrites exactly the files that differ, with a new time, so that the
    cached build of the earlier export recompiles them (git archive would stamp them with the commit's time)."""

    def test_only_changed_files_are_rewritten_and_stale_ones_removed(self):
        git = lambda *a: subprocess.run(["git", "-C", gate.ROOT] + list(a), capture_output=True, text=True)
        old, new = git("rev-parse", "HEAD~1").stdout.strip(), git("rev-parse", "HEAD").stdout.strip()
        if not old or not new:
            self.skipTest("needs a repository with at least two commits")
        changed = set(git("diff", "--name-only", old, new).stdout.split())
        with tempfile.TemporaryDirectory() as d:
            dest = os.path.join(d, "src")
            quiet(gate.export_revision, old, dest)
            stale = os.path.join(dest, "not-in-any-commit.txt")
            with open(stale, "w") as f:
                f.write("x")
            past = 1_000_000_000  # 2001: older than any build
            for root, _, files in os.walk(dest):
                for name in files:
                    os.utime(os.path.join(root, name), (past, past))
            quiet(gate.export_revision, new, dest)
            self.assertFalse(os.path.exists(stale))
            for name in git("ls-tree", "-r", "--name-only", new).stdout.split():
                path = os.path.join(dest, name)
                with open(path, "rb") as f:
                    self.assertEqual(f.read(), subprocess.run(["git", "-C", gate.ROOT, "show", f"{new}:{name}"],
                                                              capture_output=True).stdout, name)
                self.assertEqual(os.stat(path).st_mtime > past, name in changed, name)


def quiet(fn, *args):
    with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):
        return fn(*args)


# A fake benchmark executable: answers --benchmark_list_tests and writes Google Benchmark's JSON. Its
# behaviour (per benchmark: a time in ns and a noise sigma, or "crash", or "noresult") is baked in.
FAKE_BENCH = r'''#!__PYTHON__
import json, math, random, re, sys
BEHAVIOUR = __BEHAVIOUR__
args = dict(a.split("=", 1) for a in sys.argv[1:] if "=" in a)
pattern = re.compile(args.get("--benchmark_filter", "."))
names = [n for n in BEHAVIOUR if pattern.search(n)]
if args.get("--benchmark_list_tests") == "true":
    print("\n".join(names))
    sys.exit(0)
out = []
for n in names:
    b = BEHAVIOUR[n]
    if b == "crash":
        sys.stderr.write("fake benchmark: segmentation fault\n")
        sys.exit(139)
    if b == "noresult":
        continue
    t, sigma = b
    out.append({"name": n, "run_type": "iteration", "real_time": t * math.exp(random.gauss(0, sigma)),
                "time_unit": "ns", "phase_a_share": 0.75, "phase_b_share": 0.25})
json.dump({"benchmarks": out}, open(args["--benchmark_out"], "w"))
'''

# The fake hns is compiled only where a case passes its work amounts (the instruction counts): the timing
# cases need no compiler, so their trees configure without CMake's compiler checks (a second each).
FAKE_CMAKE = """cmake_minimum_required(VERSION 3.16)
project(fake NONE)
if(DEFINED PHYSICS_WORK)
  enable_language(CXX)
  add_executable(hns fake_hns.cpp)
  target_compile_definitions(hns PRIVATE PHYSICS_WORK=${PHYSICS_WORK} NN_WORK=${NN_WORK})
  target_compile_features(hns PRIVATE cxx_std_20)
endif()
add_custom_target(benches ALL
  COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/bench
  COMMAND ${CMAKE_COMMAND} -E copy ${CMAKE_SOURCE_DIR}/fake_exe ${CMAKE_BINARY_DIR}/bench/bench_fake
  COMMAND ${CMAKE_COMMAND} -E copy ${CMAKE_SOURCE_DIR}/fake_exe ${CMAKE_BINARY_DIR}/bench/bench_physics
  COMMAND ${CMAKE_COMMAND} -E copy ${CMAKE_SOURCE_DIR}/fake_exe ${CMAKE_BINARY_DIR}/bench/bench_nn)
foreach(name bench_fake bench_physics bench_nn)
  add_custom_target(${name} DEPENDS benches)
endforeach()
"""

# A fake hns for the instruction counts: the functions the gate's workloads count, each doing a fixed
# amount of work set at configure time (PHYSICS_WORK, NN_WORK), called as the real workloads call them.
FAKE_HNS = r"""
#include <cstdint>
#include <cstring>
#include <span>
namespace hns::physics { struct World { void step(std::span<const int> actions); }; }
namespace hns::batch { struct BatchSim { void step(std::span<const int> actions); }; }
namespace hns::nn {
struct ActorCritic { void act(int rows); void forward_backward(int rows); };
struct Adam { void step(float* values, float* grads); };
}
namespace hns::ppo { struct Trainer { void iterate(); }; }
volatile uint64_t sink;
__attribute__((always_inline)) inline void busy(long n) {
  uint64_t x = sink | 1;
  for (long i = 0; i < n; ++i) { x ^= x << 13; x ^= x >> 7; x ^= x << 17; }
  sink = x;
}
__attribute__((noinline)) void hns::physics::World::step(std::span<const int>) { busy(PHYSICS_WORK); }
__attribute__((noinline)) void hns::batch::BatchSim::step(std::span<const int> a) {
  hns::physics::World w;
  w.step(a);
  busy(1000);
}
__attribute__((noinline)) void hns::nn::ActorCritic::act(int rows) { busy(long(rows) * NN_WORK); }
__attribute__((noinline)) void hns::nn::ActorCritic::forward_backward(int rows) { busy(3L * rows * NN_WORK); }
__attribute__((noinline)) void hns::nn::Adam::step(float*, float*) { busy(5000); }
__attribute__((noinline)) void hns::ppo::Trainer::iterate() {
  hns::nn::ActorCritic ac;
  hns::nn::Adam adam;
  ac.act(64);
  ac.forward_backward(64);
  adam.step(nullptr, nullptr);
}
int main(int argc, char** argv) {
  busy(100000);  // start-up: not counted
  if (argc > 1 && std::strcmp(argv[1], "bench") == 0) {
    hns::batch::BatchSim sim;
    const int actions[4] = {};
    for (int i = 0; i < 20; ++i) sim.step(actions);
  } else {
    hns::ppo::Trainer t;
    t.iterate();
  }
  return 0;
}
"""


class FakeTrees(unittest.TestCase):
    """Two fake source trees in a temporary folder: a fake benchmark executable and a tiny fake hns."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def tree(self, name, behaviour):
        src = os.path.join(self.dir, name)
        os.makedirs(src, exist_ok=True)
        with open(os.path.join(src, "CMakeLists.txt"), "w") as f:
            f.write(FAKE_CMAKE)
        with open(os.path.join(src, "fake_hns.cpp"), "w") as f:
            f.write(FAKE_HNS)
        exe = os.path.join(src, "fake_exe")
        with open(exe, "w") as f:
            # The interpreter running this test, not whatever `python3` is first on the PATH (a version
            # manager's shim there costs half a second per start, and the gate starts the fake 20-40 times).
            f.write(FAKE_BENCH.replace("__PYTHON__", sys.executable).replace("__BEHAVIOUR__", repr(behaviour)))
        os.chmod(exe, 0o755)
        return src



class GateEndToEnd(FakeTrees):
    """The gate's exit statuses and reports on fake trees: a few seconds per case."""

    def run_gate(self, base, cur, *extra):
        argv = ["--baseline-src", self.tree("base", base), "--current-src", self.tree("cur", cur),
                "--suite", "bench_fake:.", "--instructions", "off", "--min-time", "0.01",
                "--work-dir", os.path.join(self.dir, "work"), "--jobs", "1", "--force-timing",
                "--summary", os.path.join(self.dir, "summary.md")] + list(extra)
        out, err = io.StringIO(), io.StringIO()
        env = dict(os.environ)
        os.environ.pop("GITHUB_STEP_SUMMARY", None)
        try:
            with redirect_stdout(out), redirect_stderr(err):
                status = gate.main(argv)
        finally:
            os.environ.clear()
            os.environ.update(env)
        return status, out.getvalue(), err.getvalue()

    def test_a_clear_regression_exits_1_and_writes_the_reports(self):
        status, out, _ = self.run_gate({"BM_a": (100.0, 0.003), "BM_b": (50.0, 0.003)},
                                       {"BM_a": (110.0, 0.003), "BM_b": (50.0, 0.003)})
        self.assertEqual(status, 1, out)
        with open(os.path.join(self.dir, "work", "report", "gate.json")) as f:
            report = json.load(f)
        verdicts = {r["benchmark"]: r["verdict"] for r in report["rows"]}
        self.assertEqual(verdicts, {"BM_a": "regression", "BM_b": "ok"})
        with open(os.path.join(self.dir, "summary.md")) as f:
            summary = f.read()
        self.assertIn("| BM_a |", summary)
        self.assertIn("REGRESSION", summary)
        self.assertIn("phase_a 75%", out)  # where the time went, for the flagged benchmark

    def test_no_change_exits_0(self):
        status, out, _ = self.run_gate({"BM_a": (100.0, 0.003)}, {"BM_a": (100.0, 0.003)})
        self.assertEqual(status, 0, out)

    def test_report_only_exits_0_and_says_what_it_would_have_done(self):
        status, out, _ = self.run_gate({"BM_a": (100.0, 0.003)}, {"BM_a": (120.0, 0.003)}, "--report-only")
        self.assertEqual(status, 0)
        self.assertIn("REPORT ONLY: the gate would have exited 1", out)

    def test_a_crashing_benchmark_exits_3(self):
        status, _, err = self.run_gate({"BM_a": (100.0, 0.003)}, {"BM_a": "crash"})
        self.assertEqual(status, 3)
        self.assertIn("segmentation fault", err)
        status, _, _ = self.run_gate({"BM_a": (100.0, 0.003)}, {"BM_a": "noresult"})
        self.assertEqual(status, 3)
        status, out, _ = self.run_gate({"BM_a": (100.0, 0.003)}, {"BM_a": "crash"}, "--report-only")
        self.assertEqual(status, 0)

    def test_an_empty_suite_exits_2(self):
        status, _, err = self.run_gate({"BM_a": (100.0, 0.003)}, {"BM_a": (100.0, 0.003)},
                                       "--suite", "bench_fake:^nothing$")
        self.assertEqual(status, 2)
        self.assertIn("matches no benchmark", err)

    def test_a_missing_benchmark_exits_2_unless_accepted(self):
        base = {"BM_a": (100.0, 0.003), "BM_old": (10.0, 0.003)}
        cur = {"BM_a": (100.0, 0.003)}
        self.assertEqual(self.run_gate(base, cur)[0], 2)
        self.assertEqual(self.run_gate(base, cur, "--accept", "BM_old=missing")[0], 0)

    def test_an_accepted_slowdown_passes(self):
        base, cur = {"BM_a": (100.0, 0.003)}, {"BM_a": (110.0, 0.003)}
        self.assertEqual(self.run_gate(base, cur, "--accept", "BM_a=1.15")[0], 0)
        self.assertEqual(self.run_gate(base, cur, "--accept", "BM_a=1.05")[0], 1)


class InstructionCounts(FakeTrees):
    """The callgrind path on a fake hns whose counted functions do known amounts of work."""

    def test_counts_split_per_suite_and_flag_the_changed_one(self):
        bench = {"BM_a": (100.0, 0.003)}
        argv = ["--baseline-src", self.tree("base", bench), "--current-src", self.tree("cur", bench),
                "--baseline-cmake-args=-DPHYSICS_WORK=2000 -DNN_WORK=100",
                "--current-cmake-args=-DPHYSICS_WORK=2400 -DNN_WORK=100",  # +20 % in World::step
                "--suite", "bench_physics:.", "--suite", "bench_nn:.", "--instructions", "on",
                "--min-time", "0.01", "--work-dir", os.path.join(self.dir, "work"), "--jobs", "2"]
        out = io.StringIO()
        with redirect_stdout(out), redirect_stderr(io.StringIO()):
            status = gate.main(argv)
        self.assertEqual(status, 1, out.getvalue())
        with open(os.path.join(self.dir, "work", "report", "gate.json")) as f:
            report = json.load(f)
        rows = {r["benchmark"]: r for r in report["rows"]}
        physics, nn = rows["instructions: bench_physics"], rows["instructions: bench_nn"]
        self.assertEqual(physics["verdict"], "regression")
        # Only World::step's loop is counted: 20 steps x 2000 iterations, not the start-up's 100000.
        self.assertGreater(physics["ratio"], 1.15)
        self.assertLess(physics["ratio"], 1.21)
        self.assertEqual(nn["verdict"], "ok")
        self.assertEqual(nn["ratio"], 1.0)
        top = report["functions"]["simulator"][0]
        self.assertTrue(top["function"].startswith("hns::physics::World::step("), top)
        self.assertGreater(top["delta"], 0)


if __name__ == "__main__":
    result = unittest.main(exit=False, verbosity=1).result
    failed = len(result.failures) + len(result.errors)
    print(f"{result.testsRun - failed} passed, {failed} failed")
    sys.exit(1 if failed else 0)
