#!/usr/bin/env python3
"""Overhead of the Python module: a Python loop of BatchEnv.step with numpy random actions against
`hns bench` with the same settings (scene, envs, steps, threads), interleaved, medians of --rounds pairs.

    PYTHONPATH=build/python python3 bench/python_step.py --hns build/hns --envs 1024 --steps 200 --rounds 5

Both time only the steps (the batch is built and reset before the clock starts) and both draw uniformly
random actions per step (C++'s stream there, numpy's here: the same distribution, so the same work on
average). Prints each pair and the medians; --json FILE writes them.
"""
import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

import numpy as np

import hns


def python_run(args):
    env = hns.BatchEnv(scene=args.scene, num_envs=args.envs, threads=args.threads, seed=args.seed)
    env.reset()
    rng = np.random.default_rng(args.seed)
    shape = (env.num_envs, env.max_agents, 5)
    start = time.perf_counter()
    for _ in range(args.steps):
        actions = rng.integers(0, 11, size=shape, dtype=np.uint8)
        actions[..., 3:] &= 1
        env.step(actions)
    return args.envs * args.steps / (time.perf_counter() - start)


def cli_run(args, tmp):
    out = os.path.join(tmp, "bench.json")
    subprocess.run([args.hns, "bench", "--scene", args.scene, "--envs", str(args.envs), "--steps",
                    str(args.steps), "--threads", str(args.threads), "--seed", str(args.seed), "--json", out],
                   check=True, capture_output=True)
    with open(out) as f:
        return json.load(f)["env_steps_per_s"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hns", default="build/hns", help="the hns executable of the same build")
    parser.add_argument("--scene", default="quadrant", choices=hns.scenes)
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--threads", type=int, default=0, help="0 = every hardware thread")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--rounds", type=int, default=5, help="interleaved (C++, Python) pairs")
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    if not os.path.exists(args.hns):
        parser.error("--hns %s: no such file (build with tools/test or tools/run first)" % args.hns)

    print("hns %s (%s): %s, %d envs x %d steps, threads %d, %d interleaved rounds" % (
        hns.__version__, hns.isa, args.scene, args.envs, args.steps, args.threads, args.rounds))
    cpp, py = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            first_cpp = r % 2 == 0  # alternate the order within a pair: ABBA
            for which in ("cpp", "py") if first_cpp else ("py", "cpp"):
                (cpp if which == "cpp" else py).append(cli_run(args, tmp) if which == "cpp" else python_run(args))
            print("  round %d: hns bench %9.0f env-steps/s, Python loop %9.0f env-steps/s (%.3f)" % (
                r + 1, cpp[-1], py[-1], py[-1] / cpp[-1]))
    c, p = statistics.median(cpp), statistics.median(py)
    ratios = [b / a for a, b in zip(cpp, py)]
    print("median: hns bench %.0f, Python loop %.0f env-steps/s; Python/C++ %.3f (median of pair ratios %.3f): "
          "overhead %+.1f %%" % (c, p, p / c, statistics.median(ratios), 100 * (1 - statistics.median(ratios))))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"scene": args.scene, "envs": args.envs, "steps": args.steps, "threads": args.threads,
                       "isa": hns.isa, "cpp_env_steps_per_s": cpp, "python_env_steps_per_s": py,
                       "median_ratio": statistics.median(ratios)}, f, indent=2)


if __name__ == "__main__":
    main()
