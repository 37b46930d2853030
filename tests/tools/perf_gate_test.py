#!/usr/bin/env python3
"""The perf gate's statistics on synthetic inputs (tools/perf-gate)."""
import importlib.machinery
import importlib.util
import os
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
GATE = os.path.join(HERE, "..", "..", "tools", "perf-gate")
loader = importlib.machinery.SourceFileLoader("perf_gate", GATE)
spec = importlib.util.spec_from_loader("perf_gate", loader)
gate = importlib.util.module_from_spec(spec)
loader.exec_module(gate)


def runs(times_per_pair):
    """[{name: t}, ...] from a list of per-pair times for one benchmark named 'bm'."""
    return [{"bm": t} for t in times_per_pair]


class GateStatistics(unittest.TestCase):
    def verdict(self, base, cur, threshold=0.05):
        rows = gate.compare(runs(base), runs(cur), threshold)
        self.assertEqual(len(rows), 1)
        return rows[0]

    def test_ten_percent_slowdown_with_low_noise_fails(self):
        base = [100.0, 101.0, 99.5, 100.5, 100.2]
        cur = [b * 1.10 * f for b, f in zip(base, [1.0, 1.005, 0.997, 1.002, 0.999])]
        row = self.verdict(base, cur)
        self.assertEqual(row["verdict"], "regression")
        self.assertAlmostEqual(row["ratio"], 1.10, delta=0.01)

    def test_two_percent_change_passes(self):
        base = [100.0, 101.0, 99.5, 100.5, 100.2]
        self.assertEqual(self.verdict(base, [b * 1.02 for b in base])["verdict"], "ok")
        self.assertEqual(self.verdict(base, [b * 0.98 for b in base])["verdict"], "ok")

    def test_noisy_pairs_covering_one_pass_with_warning(self):
        base = [100.0] * 5
        cur = [80.0, 130.0, 110.0, 95.0, 125.0]  # median ratio 1.10, pairs on both sides of 1.0
        row = self.verdict(base, cur)
        self.assertEqual(row["verdict"], "warning")
        self.assertIn("noise", row["note"])

    def test_slowdown_above_the_noise_with_pairs_not_slower_warns_saying_so(self):
        base = [100.0, 100.0, 100.0]
        cur = [106.0, 107.0, 99.0]  # median +6 %, noise 1.5 %, one pair of three faster
        row = self.verdict(base, cur)
        self.assertEqual(row["verdict"], "warning")
        self.assertIn("1 of 3 pairs were not slower", row["note"])

    def test_one_disturbed_pair_in_five_does_not_hide_a_large_slowdown(self):
        base = [36.5, 36.0, 37.0, 36.4, 36.8]
        cur = [45.7, 46.0, 45.1, 35.0, 46.3]  # +25 %, one pair where the baseline run was disturbed
        self.assertEqual(self.verdict(base, cur)["verdict"], "regression")

    def test_clear_speedup_is_reported_faster(self):
        base = [100.0, 100.5, 99.8]
        self.assertEqual(self.verdict(base, [b * 0.8 for b in base])["verdict"], "faster")

    def test_missing_and_renamed_benchmarks_are_reported_not_crashed_on(self):
        base = [{"old_name": 10.0, "kept": 5.0}] * 3
        cur = [{"new_name": 10.0, "kept": 5.0}] * 3
        rows = {r["benchmark"]: r for r in gate.compare(base, cur, 0.05)}
        self.assertEqual(rows["old_name"]["verdict"], "missing")
        self.assertEqual(rows["new_name"]["verdict"], "new")
        self.assertEqual(rows["kept"]["verdict"], "ok")
        text = gate.table_text(list(rows.values()))
        self.assertIn("missing in the current tree", text)

    def test_a_benchmark_absent_from_some_pairs_uses_the_pairs_it_has(self):
        base = [{"bm": 100.0}, {}, {"bm": 100.0}]
        cur = [{"bm": 120.0}, {"bm": 120.0}, {"bm": 121.0}]
        row = gate.compare(base, cur, 0.05)[0]
        self.assertEqual(row["pairs"], 2)
        self.assertEqual(row["verdict"], "regression")

    def test_instruction_counts(self):
        self.assertEqual(gate.judge_instructions(1000, 1100, 0.025)["verdict"], "regression")
        self.assertEqual(gate.judge_instructions(1000, 1001, 0.025)["verdict"], "ok")
        self.assertIsNone(gate.judge_instructions(None, 1000, 0.025))

    def confirm(self, first_cur, extra_cur):
        """Five flagged pairs, then the confirmation round's pairs from a fake benchmark runner; returns the
        verdict on all pairs together, as tools/perf-gate's main does."""
        base = runs([100.0] * len(first_cur))
        rows = gate.compare(base, runs(first_cur), 0.05)
        self.assertEqual(gate.needs_confirmation(rows), ["bm"])
        times = {"baseline": iter([100.0] * len(extra_cur)), "current": iter(extra_cur)}
        saved = gate.run_benchmark
        gate.run_benchmark = lambda build_dir, exe, name, min_time: next(times[build_dir])
        try:
            sides = {"baseline": "baseline", "current": "current"}
            names = {side: [("bench_x", "bm")] for side in sides}
            extra = gate.run_pairs(sides, names, [("bench_x", "bm")], len(first_cur), len(extra_cur), 0.1)
        finally:
            gate.run_benchmark = saved
        row = gate.compare(base + extra["baseline"], runs(first_cur) + extra["current"], 0.05)[0]
        self.assertEqual(row["pairs"], len(first_cur) + len(extra_cur))
        return row["verdict"]

    def test_a_burst_of_load_on_one_side_is_not_confirmed(self):
        # 4 of 5 pairs disturbed on the current side (+8 %), then 5 undisturbed pairs: not a regression.
        self.assertNotEqual(self.confirm([108.0, 107.5, 99.0, 108.5, 107.0],
                                         [100.5, 99.6, 100.2, 99.8, 100.1]), "regression")

    def test_a_real_slowdown_is_confirmed(self):
        self.assertEqual(self.confirm([110.0, 109.5, 110.5, 110.2, 109.8],
                                      [110.3, 109.9, 110.1, 110.6, 109.7]), "regression")

    def test_instruction_rows_are_not_re_run(self):
        row = gate.judge_instructions(1000, 1100, 0.025)
        self.assertEqual(gate.needs_confirmation([row]), [])

    def test_bad_usage_exits_2(self):
        self.assertEqual(gate.main(["--confirm-pairs", "-1"]), 2)
        self.assertEqual(gate.main(["--pairs", "0"]), 2)
        self.assertEqual(gate.main(["--threshold", "2"]), 2)
        self.assertEqual(gate.main(["--suite", "no-colon"]), 2)
        self.assertEqual(gate.main(["--baseline-src", "/nonexistent/folder"]), 2)


if __name__ == "__main__":
    result = unittest.main(exit=False, verbosity=1).result
    failed = len(result.failures) + len(result.errors)
    print(f"{result.testsRun - failed} passed, {failed} failed")
    sys.exit(1 if failed else 0)
