"""hns.Policy: the actions of a checkpoint's policy equal `hns play --checkpoint`'s; bad input is refused."""
import numpy as np
import pytest

import hns


@pytest.fixture(scope="session")
def blueprint_checkpoint(run_cli, tmp_path_factory):
    """A one-iteration blueprint checkpoint: its network has the construction sites' embedding."""
    out = tmp_path_factory.mktemp("run") / "blueprint"
    run_cli("train", "--scene", "blueprint", "--model", "small", "--iterations", 1, "--envs", 2, "--threads", 1,
            "--seed", 3, "--set", "horizon=30", "--out", out)
    return out / "checkpoint.bin"


@pytest.mark.parametrize("scene", ["quadrant", "blueprint"])
def test_policy_actions_equal_hns_play(run_cli, checkpoint, blueprint_checkpoint, tmp_path, scene):
    checkpoint = checkpoint if scene == "quadrant" else blueprint_checkpoint
    envs, episodes, seed = 2, 4, 5  # two episodes per env: the LSTM state is carried and reset at episode starts
    path = tmp_path / "play.traj"
    run_cli("play", "--checkpoint", checkpoint, "--episodes", episodes, "--envs", envs, "--seed", seed, "--out", path)
    trajectory = hns.read_trajectory(str(path))
    recorded = {(ep["env"], ep["episode"]): ep for ep in trajectory["episodes"]}
    assert sorted(recorded) == [(0, 0), (0, 1), (1, 0), (1, 1)]
    if scene == "blueprint":  # the sites are recorded for the replay page
        assert all(1 <= ep["sites"].shape[0] <= 4 for ep in trajectory["episodes"])

    policy = hns.Policy.load(str(checkpoint), seed=seed)
    assert policy.scene == scene and policy.model == "small" and policy.precision == "fp32"
    env = policy.make_env(num_envs=envs, threads=1, seed=seed)
    obs, _ = env.reset()
    state = policy.initial_state(envs)
    assert state.shape == (2, envs, env.max_agents, policy.state_width) and not state.any()
    horizon = env.horizon
    compared = 0
    for k in range(2):
        for t in range(1, horizon + 1):
            actions, state = policy.act(obs, state)
            assert actions.dtype == np.uint8 and actions.shape == (envs, env.max_agents, 5)
            for e in range(envs):
                ep = recorded[(e, k)]
                np.testing.assert_array_equal(actions[e, : ep["action"].shape[1]], ep["action"][t],
                                              "env %d episode %d step %d" % (e, k, t))
                compared += 1
            obs, *_ = env.step(actions)
    assert compared == 2 * envs * horizon


def test_state_is_returned_not_changed_in_place(checkpoint):
    policy = hns.Policy.load(str(checkpoint))
    env = policy.make_env(num_envs=2, threads=1)
    obs, _ = env.reset()
    state = policy.initial_state(2)
    actions, new_state = policy.act(obs, state)
    assert not state.any() and new_state.any()
    # The same inputs give the same outputs from a fresh policy with the same seed; copies work as views do.
    again, again_state = hns.Policy.load(str(checkpoint)).act(env.observations(copy=True), state)
    np.testing.assert_array_equal(again, actions)
    np.testing.assert_array_equal(again_state, new_state)


def test_exported_policy_acts_as_its_checkpoint(run_cli, checkpoint, tmp_path):
    """hns export's file (no optimiser state) gives the checkpoint's actions and states."""
    exported = tmp_path / "run.hnspolicy"
    run_cli("export", checkpoint, "--out", exported)
    assert exported.stat().st_size < checkpoint.stat().st_size / 2
    a, b = hns.Policy.load(checkpoint, seed=4), hns.Policy.load(exported, seed=4)
    assert (b.scene, b.model, b.precision) == (a.scene, a.model, a.precision)
    env = a.make_env(num_envs=2, threads=1, seed=4)
    obs, _ = env.reset()
    sa, sb = a.initial_state(2), b.initial_state(2)
    for _ in range(30):
        (acts, sa), (bcts, sb) = a.act(obs, sa), b.act(obs, sb)
        np.testing.assert_array_equal(acts, bcts)
        np.testing.assert_array_equal(sa, sb)
        obs, *_ = env.step(acts)


def test_one_policy_for_two_batch_sizes_keeps_its_streams(checkpoint):
    """Acting for batches of 4 and 2 envs in turn continues env e's stream; it never restarts it."""
    alone = hns.Policy.load(checkpoint, seed=2)  # a pathlib.Path works as well as a str
    shared = hns.Policy.load(str(checkpoint), seed=2)
    big, small = alone.make_env(num_envs=4, threads=1), alone.make_env(num_envs=2, threads=1)
    obs_big, _ = big.reset()
    obs_small, _ = small.reset()
    state_big, state_small = alone.initial_state(4), alone.initial_state(2)
    draws = []
    for _ in range(6):
        draws.append(shared.act(obs_big, state_big)[0])
        shared.act(obs_small, state_small)
    # The same observations each time: with the streams running on, the sampled actions vary.
    assert sum(np.array_equal(draws[0], d) for d in draws[1:]) < 5
    # Without the second batch the first batch's actions are the same sequence as with a Policy of its own.
    np.testing.assert_array_equal(alone.act(obs_big, state_big)[0], hns.Policy.load(str(checkpoint), seed=2).act(obs_big, state_big)[0])


def test_bad_policy_input(checkpoint, tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        hns.Policy.load(str(tmp_path / "missing.bin"))
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"not a checkpoint at all" * 10)
    with pytest.raises(ValueError):
        hns.Policy.load(str(junk))
    with pytest.raises(ValueError, match="seed"):
        hns.Policy.load(str(checkpoint), seed=-3)

    policy = hns.Policy.load(str(checkpoint))
    env = policy.make_env(num_envs=2, threads=1)
    obs, _ = env.reset(copy=True)
    state = policy.initial_state(2)
    with pytest.raises(ValueError, match="num_envs"):
        policy.initial_state(0)
    with pytest.raises(ValueError, match=r"state: shape"):
        policy.act(obs, state[:, :1])
    with pytest.raises(TypeError, match=r"state: dtype float64"):
        policy.act(obs, state.astype(np.float64))
    missing = dict(obs)
    del missing["mask_boxes"]
    with pytest.raises(KeyError, match="mask_boxes"):
        policy.act(missing, state)
    wrong = dict(obs, obs_self=obs["obs_self"].astype(np.float64))
    with pytest.raises(TypeError, match=r"obs\['obs_self'\]: dtype float64, expected float32"):
        policy.act(wrong, state)
    wrong = dict(obs, lidar=obs["lidar"][:, :, :10])
    with pytest.raises(ValueError, match=r"obs\['lidar'\]: shape"):
        policy.act(wrong, state)
    other = hns.BatchEnv(scene="full", num_envs=2, threads=1)
    with pytest.raises(ValueError, match="shape"):
        policy.act(other.reset()[0], state)
    # Boolean masks are accepted as they are (the same bytes).
    as_bool = dict(obs, mask_boxes=obs["mask_boxes"].astype(bool))
    np.testing.assert_array_equal(hns.Policy.load(str(checkpoint)).act(as_bool, state)[0],
                                  hns.Policy.load(str(checkpoint)).act(obs, state)[0])
