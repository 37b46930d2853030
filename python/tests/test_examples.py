"""The example scripts of examples/ run as the docs show them."""
import os
import subprocess
import sys

import pytest

EXAMPLES = os.path.join(os.path.dirname(__file__), "..", "..", "examples")


def run_example(name, *args, status=0):
    result = subprocess.run([sys.executable, os.path.join(EXAMPLES, name), *map(str, args)],
                            capture_output=True, text=True, env=dict(os.environ))
    assert result.returncode == status, result.stdout + result.stderr
    return result.stdout + result.stderr


def test_random_loop_prints_returns():
    out = run_example("random_loop.py", "--envs", 2, "--steps", 170, "--threads", 1)
    assert out.count("episode") >= 4 and "mean return hiders" in out and "env-steps/s" in out


def test_random_loop_with_a_checkpoint(checkpoint):
    out = run_example("random_loop.py", "--checkpoint", checkpoint, "--envs", 2, "--steps", 81, "--threads", 1)
    assert "policy " in out and "mean return hiders" in out


def test_plot_run(checkpoint, tmp_path):
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        # The table instead, and with --out a failure that says the picture was not written.
        out = run_example("plot_run.py", checkpoint.parent)
        assert "matplotlib is not installed" in out and "hider_reward" in out
        out = run_example("plot_run.py", checkpoint.parent, "--out", tmp_path / "curves.png", status=1)
        assert "curves.png not written" in out and not (tmp_path / "curves.png").exists()
    else:
        run_example("plot_run.py", checkpoint.parent, "--out", tmp_path / "curves.png")
        assert (tmp_path / "curves.png").stat().st_size > 1000


def test_torch_ppo_learns_lockbox():
    # A shrunk run of the PyTorch example: observations reach torch without a copy, and within 40 iterations
    # (154 k agent-steps) the return clearly beats the random policy's (measured: about 15 against 3.3).
    pytest.importorskip("torch", reason="Debian's python3-torch is not installed (tools/test installs it)")
    out = run_example("torch_ppo.py", "--iterations", 40, "--envs", 64)
    assert "zero-copy into torch: yes" in out, out
    final = [line for line in out.splitlines() if line.startswith("final:")][0]
    learned, random = (float(w.rstrip(",")) for w in final.split()[8:12:3])
    assert learned > 2.5 * random, final
