#!/usr/bin/env python3
"""Plots a training run's curves from its metrics.jsonl (matplotlib, if installed).

    PYTHONPATH=build/python python3 examples/plot_run.py runs/quickstart --out curves.png

Without matplotlib it prints the same columns as a table instead; given --out, it then also says on stderr that
no picture was written and exits with status 1.
"""
import argparse
import os
import sys

import hns

CURVES = [
    ("hider_reward", "seeker_reward", "episode return"),
    ("num_box_lock_prep", "max_ramp_move_prep", "preparation phase"),
    ("entropy", "approx_kl", "policy"),
    ("steps_per_s", None, "agent-steps/s"),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="run folder of hns train (holds metrics.jsonl)")
    parser.add_argument("--out", default=None, help="PNG to write (default RUN/curves.png)")
    args = parser.parse_args()

    rows = hns.read_metrics(os.path.join(args.run, "metrics.jsonl"))
    steps = hns.metrics_column(rows, "agent_steps")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed (apt-get install python3-matplotlib); the columns instead:")
        names = [n for pair in CURVES for n in pair[:2] if n]
        print("agent_steps " + " ".join(names))
        for i in range(len(rows)):
            print("%11.0f " % steps[i] + " ".join("%g" % hns.metrics_column(rows[i:i + 1], n)[0] for n in names))
        if args.out is not None:
            print("plot_run.py: %s not written: matplotlib is not installed" % args.out, file=sys.stderr)
            sys.exit(1)
        return
    fig, axes = plt.subplots(len(CURVES), 1, figsize=(8, 2.6 * len(CURVES)), sharex=True)
    for ax, (first, second, title) in zip(axes, CURVES):
        for name in (first, second):
            if name:
                ax.plot(steps, hns.metrics_column(rows, name), label=name)
        ax.set_title(title)
        ax.legend(loc="best")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("agent-steps")
    fig.tight_layout()
    out = args.out or os.path.join(args.run, "curves.png")
    fig.savefig(out, dpi=100)
    print("wrote %s (%d iterations)" % (out, len(rows)))


if __name__ == "__main__":
    main()
