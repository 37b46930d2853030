"""Shared fixtures of the Python suite: the hns command line (HNS_CLI, set by ctest) for C++ references."""
import os
import subprocess

import pytest


@pytest.fixture(scope="session")
def hns_cli():
    path = os.environ.get("HNS_CLI")
    if not path or not os.path.exists(path):
        pytest.fail("HNS_CLI must name the hns executable (ctest sets it; by hand: HNS_CLI=build/hns)")
    return path


@pytest.fixture(scope="session")
def run_cli(hns_cli):
    def run(*args):
        result = subprocess.run([hns_cli, *map(str, args)], capture_output=True, text=True)
        assert result.returncode == 0, "hns %s failed:\n%s%s" % (" ".join(map(str, args)), result.stdout, result.stderr)
        return result

    return run


@pytest.fixture(scope="session")
def checkpoint(run_cli, tmp_path_factory):
    """A one-iteration quadrant checkpoint of the small model (a fraction of a second)."""
    out = tmp_path_factory.mktemp("run") / "quadrant"
    run_cli("train", "--scene", "quadrant", "--model", "small", "--iterations", 1, "--envs", 2, "--threads", 1,
            "--seed", 3, "--out", out)
    return out / "checkpoint.bin"
