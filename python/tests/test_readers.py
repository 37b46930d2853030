"""hns.read_trajectory and hns.read_metrics: the files `hns play` and `hns train` write, and bad files."""
import numpy as np
import pytest

import hns


def test_read_trajectory(run_cli, tmp_path):
    path = tmp_path / "full.traj"
    run_cli("play", "--scene", "full", "--random", "--episodes", 2, "--envs", 2, "--seed", 3, "--out", path)
    data = hns.read_trajectory(path)  # str or os.PathLike
    assert data["version"] == 3 and data["created_by"] == "hns play" and data["policy"] == "random"
    assert len(data["episodes"]) == 2
    for ep in data["episodes"]:
        F, A, B, R = ep["frames"], ep["num_hiders"] + ep["num_seekers"], ep["num_boxes"], ep["num_ramps"]
        assert F == ep["horizon"] + 1 == 241 and ep["scene"] == "full"
        assert ep["agent_pose"].shape == (F, A, 4) and ep["agent_pose"].dtype == np.float32
        assert ep["box_pose"].shape == (F, B, 4) and ep["ramp_pose"].shape == (F, R, 4)
        assert ep["object_lock"].shape == (F, B + R) and ep["agent_holding"].dtype == np.int8
        assert ep["vis_boxes"].shape == (F, A, B) and ep["lidar"].shape == (F, A, 30)
        assert ep["lidar"].dtype == np.float32 and 0 <= ep["lidar"].min() and ep["lidar"].max() <= 6.0
        assert ep["action"].shape == (F, A, 5) and ep["reward"].shape == (F, A)
        assert ep["prep"].shape == (F,) and ep["prep"][1] == 1 and ep["prep"][-1] == 0
        assert ep["walls"].shape[1] == 6 and ep["box_sizes"].shape == (B, 3)
        # Hiders' and seekers' summed mean rewards are the header's returns.
        hiders = ep["reward"][:, : ep["num_hiders"]].mean(axis=1).sum(dtype=np.float64)
        assert hiders == pytest.approx(ep["hider_return"], abs=1e-3)


def test_read_trajectory_errors(checkpoint, tmp_path):
    with pytest.raises(FileNotFoundError):
        hns.read_trajectory(str(tmp_path / "none.traj"))
    with pytest.raises(ValueError, match="NUL"):
        hns.read_trajectory("play.traj\0junk")
    with pytest.raises(TypeError):
        hns.read_trajectory(42)
    bad = tmp_path / "bad.traj"
    bad.write_bytes(b"HNSTRAJ\n\x05\x00\x00\x00{oops")
    with pytest.raises(hns.TrajectoryError) as info:
        hns.read_trajectory(str(bad))
    assert isinstance(info.value, ValueError) and "bad.traj" in str(info.value)
    # A message that quotes a damaged header's bytes (here not UTF-8) keeps its text (it was empty before).
    good = (checkpoint.parent / "replay.traj").read_bytes()
    at = good.index(b"hns train") + 2
    flipped = tmp_path / "flipped.traj"
    flipped.write_bytes(good[:at] + b"\xff" + good[at + 1:])
    with pytest.raises(hns.TrajectoryError) as info:
        hns.read_trajectory(str(flipped))
    assert "flipped.traj" in str(info.value) and "\ufffd" in str(info.value)
    deep = tmp_path / "deep.jsonl"
    deep.write_text('{"iteration": 1, "agent_steps": 1, "z": ' + "[" * 70000 + "]" * 70000 + "}\n")
    with pytest.raises(ValueError, match="deep.jsonl:1"):
        hns.read_metrics(deep)


def test_read_metrics(checkpoint, tmp_path):
    rows = hns.read_metrics(checkpoint.parent / "metrics.jsonl")
    assert len(rows) == 1 and rows[0]["iteration"] == 1 and rows[0]["agent_steps"] > 0
    assert list(hns.metrics_column(rows, "iteration")) == [1.0]
    assert np.isnan(hns.metrics_column(rows, "no_such_metric")).all()
    broken = tmp_path / "metrics.jsonl"
    broken.write_text('{"iteration": 1, "agent_steps": 10}\n\n{"iteration": 2}\n')
    with pytest.raises(ValueError, match=r"metrics.jsonl:3: is not an iteration record"):
        hns.read_metrics(broken)
    with pytest.raises(FileNotFoundError):
        hns.read_metrics(tmp_path / "nothing.jsonl")


def test_detect_stages():
    # 100 episodes per iteration: windows of 10 iterations. Every episode seals both doors from iteration 21
    # on: half of a window at iteration 25.
    rows = [{"iteration": i, "agent_steps": 1000 * i, "episodes": 100, "num_doors": 2,
             "num_door_sealed_prep": 2 if i > 20 else 0} for i in range(1, 41)]
    report = hns.detect_stages(rows, "quadrant")
    assert report["window_episodes"] == 1000
    stages = {s["name"]: s for s in report["stages"]}
    assert list(stages)[:2] == ["running and chasing", "fort building"]
    fort = stages["fort building"]
    assert (fort["first_row"], fort["first_iteration"], fort["first_episodes"]) == (24, 25, 2500)
    assert np.isnan(fort["value"][8]) and fort["value"][9] == 0 and fort["value"][-1] == 1
    assert not fort["on"][23] and fort["on"][24] and fort["on"].dtype == bool
    assert stages["running and chasing"]["first_row"] == -1 and np.isnan(stages["running and chasing"]["value"]).all()
    assert hns.detect_stages(rows, "lockbox")["stages"] == []
    # Bad input is refused, not answered with an empty report or an AttributeError.
    with pytest.raises(ValueError, match="'nope' is not a scene"):
        hns.detect_stages(rows, "nope")
    with pytest.raises(ValueError, match=r"rows\[0\] is not a metrics row"):
        hns.detect_stages([{}], "quadrant")
    with pytest.raises(ValueError, match="NaN or an infinity"):
        hns.detect_stages([{"iteration": 1, "agent_steps": 1, "x": float("nan")}], "quadrant")
    with pytest.raises(TypeError, match=r"rows\[0\] is a int"):
        hns.metrics_column([1, 2], "a")


def episodes_of(path):
    return sorted(hns.read_trajectory(path)["episodes"], key=lambda ep: (ep["env"], ep["episode"]))


def assert_same_episodes(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.keys() == y.keys()
        for key in x:
            if isinstance(x[key], np.ndarray):
                np.testing.assert_array_equal(x[key], y[key], key)
            else:
                assert x[key] == y[key], key


@pytest.mark.parametrize("scene", ["quadrant", "full"])
def test_record_equals_hns_play(run_cli, tmp_path, scene):
    run_cli("play", "--scene", scene, "--random", "--episodes", 3, "--envs", 2, "--seed", 4, "--out", tmp_path / "cli.traj")
    done = hns.record(tmp_path / "py.traj", scene=scene, episodes=3, envs=2, seed=4)
    assert done["recorded"] == 3 and done["scene"] == scene and done["bytes"] > 0
    data = hns.read_trajectory(tmp_path / "py.traj")
    assert data["created_by"] == "hns.record" and data["policy"] == "random"
    assert_same_episodes(episodes_of(tmp_path / "py.traj"), episodes_of(tmp_path / "cli.traj"))


def test_record_with_a_checkpoint_equals_hns_play(run_cli, checkpoint, tmp_path):
    run_cli("play", "--checkpoint", checkpoint, "--episodes", 2, "--envs", 2, "--seed", 6, "--out", tmp_path / "cli.traj")
    done = hns.record(tmp_path / "py.traj", checkpoint=checkpoint, episodes=2, envs=2, seed=6)
    assert done["scene"] == "quadrant"
    assert hns.read_trajectory(tmp_path / "py.traj")["policy"] == str(checkpoint)
    assert_same_episodes(episodes_of(tmp_path / "py.traj"), episodes_of(tmp_path / "cli.traj"))


def test_record_refusals(checkpoint, tmp_path):
    with pytest.raises(ValueError, match="scene"):
        hns.record(tmp_path / "x.traj", scene="castle")
    with pytest.raises(ValueError, match="trained on scene 'quadrant'"):
        hns.record(tmp_path / "x.traj", scene="full", checkpoint=checkpoint)
    with pytest.raises(FileNotFoundError):
        hns.record(tmp_path / "x.traj", checkpoint=tmp_path / "none.bin")
    before = checkpoint.read_bytes()
    with pytest.raises(ValueError, match="is the checkpoint this recording plays"):
        hns.record(checkpoint, checkpoint=checkpoint)
    assert checkpoint.read_bytes() == before
    with pytest.raises(FileNotFoundError, match="folder does not exist"):
        hns.record(tmp_path / "no" / "x.traj")
    with pytest.raises(IsADirectoryError):
        hns.record(tmp_path)
    import os

    os.mkfifo(tmp_path / "fifo")  # a FIFO (or a device) is never replaced by a recording
    with pytest.raises((OSError, ValueError, RuntimeError), match="not a regular file"):
        hns.record(tmp_path / "fifo")
    assert (tmp_path / "fifo").is_fifo()
    with pytest.raises(ValueError, match="episodes = 0"):
        hns.record(tmp_path / "x.traj", episodes=0)
    with pytest.raises(ValueError, match="hiders"):
        hns.record(tmp_path / "x.traj", hiders=99)
    assert not (tmp_path / "x.traj").exists()  # nothing half-written


def test_special_files_are_refused_not_read(tmp_path):
    """A FIFO would block the reader forever and /dev/zero never ends: both are refused at once."""
    import os

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for read in (hns.read_trajectory, hns.read_metrics, hns.Policy.load):
        with pytest.raises((OSError, ValueError, RuntimeError), match="not a regular file"):
            read(str(fifo))
        with pytest.raises((OSError, ValueError, RuntimeError), match="not a regular file"):
            read("/dev/zero")
