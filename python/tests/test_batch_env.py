"""hns.BatchEnv: shapes and dtypes, zero-copy views, agreement with the C++ simulator, determinism, errors."""
import gc
import re
import sys
import threading
import time

import numpy as np
import pytest

import hns

OBS_FIELDS = {
    "obs_self": (np.float32, ("A", 11)),
    "lidar": (np.float32, ("A", 30)),
    "obs_agents": (np.float32, ("A", "A-1", 11)),
    "obs_boxes": (np.float32, ("A", "B", 15)),
    "obs_ramps": (np.float32, ("A", "R", 12)),
    "mask_agents": (np.uint8, ("A", "A-1")),
    "mask_boxes": (np.uint8, ("A", "B")),
    "mask_ramps": (np.uint8, ("A", "R")),
    "value_mask_agents": (np.uint8, ("A", "A-1")),
    "value_mask_boxes": (np.uint8, ("A", "B")),
    "value_mask_ramps": (np.uint8, ("A", "R")),
    "step_count": (np.int32, ()),
    "episode": (np.int32, ()),
}


def random_actions(rng, env):
    a = rng.integers(0, 11, size=(env.num_envs, env.max_agents, 5), dtype=np.uint8)
    a[..., 3:] &= 1
    return a


SITE_OBS_FIELDS = {
    "obs_sites": (np.float32, ("A", "C", "S")),
    "mask_sites": (np.uint8, ("A", "C")),
    "value_mask_sites": (np.uint8, ("A", "C")),
}


@pytest.mark.parametrize(
    "scene",
    ["quadrant", "full", "lockbox", "lock-and-return", "sequential-lock", "shelter", "blueprint",
     "object-counting", "food", "dynamic-food"])
def test_shapes_and_dtypes(scene):
    env = hns.BatchEnv(scene=scene, num_envs=3, threads=1, seed=2)
    sites = {"blueprint": (4, 15), "food": (5, 4), "dynamic-food": (1, 4)}.get(scene, (0, 0))
    sizes = {"A": env.max_agents, "A-1": env.max_agents - 1, "B": env.max_boxes, "R": env.max_ramps,
             "C": env.max_sites, "S": sites[1]}
    obs, info = env.reset()
    # The fourth entity type (blueprint's construction sites, or the food) is observed only where it exists.
    fields = dict(OBS_FIELDS, **SITE_OBS_FIELDS) if sites[0] else OBS_FIELDS
    assert env.max_sites == sites[0]
    assert set(obs) == set(fields)
    for name, (dtype, dims) in fields.items():
        assert obs[name].dtype == dtype, name
        assert obs[name].shape == (3,) + tuple(sizes.get(d, d) for d in dims), name
        assert obs[name].flags.c_contiguous and not obs[name].flags.writeable, name
    actions = random_actions(np.random.default_rng(0), env)
    obs, reward, terminated, truncated, info = env.step(actions)
    assert reward.dtype == np.float32 and reward.shape == (3, env.max_agents)
    assert terminated.dtype == np.bool_ and terminated.shape == (3,)
    assert truncated.dtype == np.bool_ and truncated.shape == (3,)
    assert info["agent_exists"].shape == (3, env.max_agents)
    assert info["episode_return"].shape == (3, 2)
    state = env.state()
    assert state["agent_pos"].shape == (3, env.max_agents, 3)
    assert state["vis_boxes"].shape == (3, env.max_agents, env.max_boxes)
    assert state["num_walls"].shape == (3,)
    assert set(env.field_docs()) == set(state)
    scene_info = env.scene(0)
    assert scene_info["walls"].ndim == 2 and scene_info["walls"].shape[1] == 6
    assert scene_info["agents"].shape == (scene_info["num_hiders"] + scene_info["num_seekers"], 6)
    # The shelter task's cylinder (axis x, y, radius, height), in no other scene.
    assert scene_info["cylinders"].shape == ((1, 4) if scene == "shelter" else (0, 4))
    if scene == "shelter":
        assert state["shape_cyl_r"].shape == (3, 1) and 0.75 <= state["shape_cyl_r"][0, 0] <= 1.0
    # Blueprint's construction sites: centres and extents in the scene, the same centres in the state.
    assert scene_info["sites"].shape[1] == 6
    if scene == "blueprint":
        n = scene_info["sites"].shape[0]
        assert 1 <= n <= 4 and state["site_exists"][0].sum() == n
        np.testing.assert_allclose(state["site_pos"][0, :n], scene_info["sites"][:, :3], atol=1e-6)
        assert state["task_complete"].shape == (3,)
    else:
        assert scene_info["sites"].shape[0] == 0
    if scene in ("food", "dynamic-food"):
        assert state["food_health"].shape == (3, sites[0]) and state["food_exists"].all()
        np.testing.assert_array_equal(obs["obs_sites"][:, 0, :, 3], state["food_health"])


def doc_dims(doc, sizes):
    """The shape a field's doc states, "(envs x A x 3)", as (num_envs,) + sizes; None where it states none or
    names a size this test does not know (the ray-cast shape slots, the food and site counts)."""
    at = doc.rfind("(envs")
    if at < 0:
        return None
    dims = []
    for token in doc[at + 1:doc.index(")", at)].split(" x ")[1:]:
        token = re.split(r"[,=]", token)[0].strip()
        if token.isdigit():
            dims.append(int(token))
        elif token in sizes:
            dims.append(sizes[token])
        else:
            return None
    return (sizes["envs"],) + tuple(dims)


# Every state() array has the shape its entry of the C++ field list (HNS_BATCH_FIELDS) states: the module
# shapes its arrays from that list's counts, and the list's docs say the same shape.
@pytest.mark.parametrize("scene", ["quadrant", "lockbox", "blueprint", "food"])
def test_state_shapes_are_the_field_lists(scene):
    env = hns.BatchEnv(scene=scene, num_envs=3, threads=1, seed=2)
    sizes = {"envs": 3, "A": env.max_agents, "A-1": env.max_agents - 1, "B": env.max_boxes,
             "R": env.max_ramps, "C": env.max_sites}
    docs, state = env.field_docs(), env.state()
    checked = 0
    for name, array in state.items():
        want = doc_dims(docs[name], sizes)
        if want is not None:
            assert array.shape == want, (name, docs[name])
            checked += 1
    assert checked >= 50
    obs, _ = env.reset()
    for name, array in obs.items():
        assert array.shape == state[name].shape, name


def test_views_are_the_batch_buffers_without_copies():
    env = hns.BatchEnv(scene="quadrant", num_envs=4, threads=1, seed=1)
    obs, _ = env.reset()
    for name in OBS_FIELDS:
        assert obs[name].__array_interface__["data"][0] == env._field_address(name), name
    before = obs["obs_self"].copy()
    owned, _ = env.reset(copy=True, seed=1)  # the same episodes again
    obs2, reward, _, truncated, _ = env.step(np.full((4, env.max_agents, 5), [10, 10, 0, 0, 0], dtype=np.uint8))
    # The same memory, now holding the new step: a view is live, a copy is not.
    assert obs2["obs_self"].__array_interface__["data"][0] == obs["obs_self"].__array_interface__["data"][0]
    assert np.shares_memory(obs["obs_self"], obs2["obs_self"])
    assert not np.array_equal(obs["obs_self"], before)
    assert np.array_equal(owned["obs_self"], before)
    assert not np.shares_memory(owned["obs_self"], obs["obs_self"]) and owned["obs_self"].flags.writeable
    assert reward.__array_interface__["data"][0] == env._field_address("reward")
    assert truncated.__array_interface__["data"][0] == env._field_address("done")
    with pytest.raises(ValueError):
        obs["obs_self"][0, 0, 0] = 1.0  # read-only: the batch's state is not the user's to change


def test_views_outlive_the_env():
    env = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=1)
    obs, _ = env.reset()
    expected = {name: view.copy() for name, view in obs.items()}
    del env, _
    gc.collect()
    # Other batches of the same size now take the memory a freed batch would have returned.
    others = [hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=s) for s in range(2, 6)]
    for other in others:
        other.step(np.full((2, 4, 5), [0, 10, 3, 1, 1], dtype=np.uint8))
    for name, view in obs.items():
        assert np.array_equal(view, expected[name]), name


def test_returned_dicts_and_arrays_are_the_callers():
    env = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=1)
    obs, info = env.reset()
    obs["lidar"] = obs["lidar"] / 6.0  # a user's in-place edits of the dicts change nothing of the env's
    del obs["step_count"]
    state = env.state()
    state["reward"] = "not an array"
    neutral = np.full((2, 4, 5), [5, 5, 5, 0, 0], dtype=np.uint8)
    obs2, reward, terminated, truncated, _ = env.step(neutral)
    assert obs2 is not obs and "step_count" in obs2 and obs2["lidar"].base is not None
    assert reward.dtype == np.float32 and env.state()["reward"].dtype == np.float32
    for flag in (terminated, truncated):
        with pytest.raises(ValueError):
            flag.flags.writeable = True  # views of the batch (or of its constant zeros) stay read-only
    owned = env.step(neutral, copy=True)
    assert all(a.flags.writeable for a in owned[0].values())
    assert owned[1].flags.writeable and owned[2].flags.writeable and owned[3].flags.writeable
    assert not np.shares_memory(owned[1], env.state()["reward"])


@pytest.mark.parametrize("scene, envs", [("quadrant", 2), ("full", 3)])
def test_bit_identical_with_the_cpp_simulator(run_cli, tmp_path, scene, envs):
    """hns play (the C++ BatchSim, random actions) against BatchEnv fed the recorded actions."""
    path = tmp_path / "play.traj"
    run_cli("play", "--scene", scene, "--random", "--episodes", envs, "--envs", envs, "--seed", 11, "--out", path)
    episodes = sorted(hns.read_trajectory(str(path))["episodes"], key=lambda ep: ep["env"])
    assert [ep["env"] for ep in episodes] == list(range(envs))
    env = hns.BatchEnv(scene=scene, num_envs=envs, threads=1, seed=11)
    env.reset()
    horizon = episodes[0]["horizon"]
    state = env.state()
    actions = np.full((envs, env.max_agents, 5), [5, 5, 5, 0, 0], dtype=np.uint8)
    padding_seen = False
    for t in range(horizon + 1):
        if t > 0:
            for e, ep in enumerate(episodes):
                actions[e, : ep["action"].shape[1]] = ep["action"][t]
            _, reward, _, truncated, _ = env.step(actions)
            assert bool(truncated.all()) == (t == horizon)
        for e, ep in enumerate(episodes):
            n, b = ep["action"].shape[1], ep["num_boxes"]
            padding_seen |= n < env.max_agents
            np.testing.assert_array_equal(reward[e, :n] if t > 0 else np.zeros(n, np.float32), ep["reward"][t])
            if t == horizon:
                continue  # the env was reset into its next episode in the step that ended this one
            np.testing.assert_array_equal(state["agent_pos"][e, :n], ep["agent_pose"][t, :, :3], "t=%d" % t)
            np.testing.assert_array_equal(state["box_pos"][e, :b], ep["box_pose"][t, :, :3], "t=%d" % t)
            np.testing.assert_array_equal(state["vis_agents"][e, :n, :n], ep["vis_agents"][t], "t=%d" % t)
    if scene == "full":
        assert padding_seen, "no episode with padding agents: pick another seed"
    assert np.array_equal(env.state()["episode"], np.ones(envs, np.int32))


def run_random(threads, steps=260, envs=6, scene="full"):
    env = hns.BatchEnv(scene=scene, num_envs=envs, threads=threads, seed=5)
    env.reset()
    rng = np.random.default_rng(9)
    snapshots = []
    for t in range(steps):
        env.step(random_actions(rng, env))
        if t % 65 == 64:
            snapshots.append({k: v.tobytes() for k, v in env.state().items()})
    return snapshots


def test_deterministic_across_thread_counts():
    if hns.BatchEnv(num_envs=1, threads=2).threads < 2:
        pytest.skip("this machine has one hardware thread")
    one, two = run_random(1), run_random(2)
    assert len(one) == 4
    for a, b in zip(one, two):
        for name in a:
            assert a[name] == b[name], name


def test_episode_statistics_and_truncation():
    env = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=4)
    env.reset()
    rng = np.random.default_rng(1)
    for t in range(1, env.horizon + 1):
        obs, reward, terminated, truncated, info = env.step(random_actions(rng, env))
        assert not terminated.any()
        if t < env.horizon:
            assert not truncated.any() and len(info["finished"]["env"]) == 0
    assert truncated.all()
    finished = info["finished"]
    assert list(finished["env"]) == [0, 1] and list(finished["length"]) == [env.horizon] * 2
    assert list(obs["step_count"]) == [0, 0] and list(obs["episode"]) == [1, 1]
    assert np.all(finished["hider_return"] == -finished["seeker_return"])  # quadrant rewards are zero-sum


def test_gil_released_while_stepping():
    env = hns.BatchEnv(scene="full", num_envs=128, threads=1, seed=1)
    env.reset()
    actions = random_actions(np.random.default_rng(0), env)
    counter = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            counter[0] += 1

    interval = sys.getswitchinterval()
    # Python takes the GIL from a running thread only every 0.2 s, and never inside a C call that keeps it:
    # the spinner counts during step() only if step() lets go of the GIL (a call that keeps it scores 0).
    sys.setswitchinterval(0.2)
    thread = threading.Thread(target=spin)
    thread.start()
    try:
        time.sleep(0.05)
        before = counter[0]
        env.step(actions)
        during = counter[0] - before
    finally:
        stop.set()
        thread.join()
        sys.setswitchinterval(interval)
    assert during > 1000, "the other thread barely ran while step() worked: the GIL was held"


@pytest.mark.parametrize(
    "kwargs, error, words",
    [
        (dict(scene="castle"), ValueError, "scene"),
        (dict(num_envs=0), ValueError, "num_envs"),
        (dict(num_envs=2**22 + 1), ValueError, "num_envs"),
        (dict(threads=-1), ValueError, "threads"),
        (dict(seed=-1), ValueError, "seed"),
        (dict(seed=2**64), ValueError, "seed"),
        (dict(hiders=40), ValueError, "hiders"),
        (dict(horizon=0), ValueError, "horizon"),
        (dict(num_envs="many"), TypeError, ""),
        (dict(seed=1.5), TypeError, "seed"),
        (dict(seed=True), TypeError, "seed"),
    ],
)
def test_bad_constructor_arguments(kwargs, error, words):
    with pytest.raises(error, match=words):
        hns.BatchEnv(**kwargs)


def test_bad_actions():
    env = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=1)
    env.reset()
    good = np.full((2, env.max_agents, 5), 5, dtype=np.int64)
    good[..., 3:] = 0
    env.step(good)
    env.step(good.astype(np.uint8))
    env.step(good.tolist())
    with pytest.raises(ValueError, match=r"actions: shape \(2, 4, 4\), expected \(2, 4, 5\)"):
        env.step(good[..., :4])
    with pytest.raises(ValueError, match="shape"):
        env.step(good[:1])
    with pytest.raises(TypeError, match="actions: dtype float64"):
        env.step(good.astype(np.float64))
    with pytest.raises(TypeError, match="actions"):
        env.step("left")
    bad = good.copy()
    bad[1, 2, 0] = 11
    with pytest.raises(ValueError, match=r"actions\[1, 2, 0\] = 11 is out of range: movement bins are 0..10"):
        env.step(bad)
    bad = good.copy()
    bad[0, 3, 4] = 2
    with pytest.raises(ValueError, match=r"actions\[0, 3, 4\] = 2 .*grab and lock are 0 or 1"):
        env.step(bad)
    bad = good.copy()
    bad[0, 0, 1] = -1
    with pytest.raises(ValueError, match=r"actions\[0, 0, 1\] = -1 is out of range"):
        env.step(bad)
    big = good.astype(np.uint64)
    big[1, 1, 1] = 2**63 + 5
    with pytest.raises(ValueError, match=r"actions\[1, 1, 1\] = 9223372036854775813 is out of range"):
        env.step(big)
    with pytest.raises(ValueError, match="episodes: shape"):
        env.reset(episodes=np.zeros(3, np.int32))
    with pytest.raises(ValueError, match=r"episodes\[1\] = -2"):
        env.reset(episodes=np.array([0, -2]))
    with pytest.raises(ValueError, match=r"episodes\[0\] = 1073741824 is invalid: must be in \[0, 2\^30 - 1\]"):
        env.reset(episodes=np.array([2**30, 0]))
    with pytest.raises(IndexError, match="env = 2"):
        env.scene(2)
    # The env still works after every refusal.
    obs, info = env.reset(episodes=np.array([3, 4]))
    assert list(obs["episode"]) == [3, 4]


def test_a_refused_reset_leaves_the_env_as_it_was():
    # A reset refused for its episodes changes neither the seed nor the worlds nor the episode numbering: the
    # next reset gives what a twin env that was never refused gives.
    env = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=3)
    twin = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=3)
    with pytest.raises(ValueError, match=r"episodes\[1\] = -2"):
        env.reset(episodes=np.array([0, -2]))
    with pytest.raises(ValueError, match=r"episodes\[1\] = -2"):
        env.reset(seed=5, episodes=np.array([0, -2]))
    assert env.seed == 3
    a, _ = env.reset()
    b, _ = twin.reset()
    assert list(a["episode"]) == [0, 0]
    for name in b:
        assert a[name].tobytes() == b[name].tobytes(), name


def test_reset_with_episodes_replays_those_scenes():
    assert hns.BatchEnv(num_envs=1, seed=np.uint64(2**64 - 1)).seed == 2**64 - 1  # numpy integers are integers
    a = hns.BatchEnv(scene="full", num_envs=2, threads=1, seed=8)
    a.reset(episodes=np.array([5, 6]))
    b = hns.BatchEnv(scene="full", num_envs=2, threads=1, seed=8)
    b.reset()
    assert not np.array_equal(a.state()["agent_pos"], b.state()["agent_pos"])
    b.reset(episodes=np.array([5, 6]))
    for name, value in a.state().items():
        assert value.tobytes() == b.state()[name].tobytes(), name


def test_import_refuses_a_cpu_without_the_build_isa(monkeypatch):
    assert hns._BUILD_ISA == hns.isa
    hns._check_cpu()  # this machine built it, so it runs it
    monkeypatch.setattr(hns, "_BUILD_ISA", "avx512")
    monkeypatch.setitem(hns._ISA_FLAGS, "avx512", ("avx2", "no_such_cpu_flag"))
    with pytest.raises(ImportError, match="HNS_ISA=avx512.*lacks no_such_cpu_flag: rebuild with HNS_ISA=avx2"):
        hns._check_cpu()


def test_spaces_describe_what_reset_and_step_give_and_take():
    # Gymnasium's contract: every observation is in observation_space, every sample of action_space is an
    # action step() takes, and the single_* spaces are one env's share.
    env = hns.BatchEnv(scene="quadrant", num_envs=3, threads=1, seed=5)
    obs, _ = env.reset()
    space, single = env.observation_space, env.single_observation_space
    assert set(space.keys()) == set(obs.keys())
    for key, a in obs.items():
        assert space[key].shape == a.shape and space[key].dtype == a.dtype, key
        assert single[key].shape == a.shape[1:], key
    assert space.contains({k: v.copy() for k, v in obs.items()})
    assert env.action_space.shape == (3, env.max_agents, 5)
    assert env.single_action_space.shape == (env.max_agents, 5)
    env.action_space.seed(1)
    for _ in range(20):
        actions = env.action_space.sample()
        assert actions in env.action_space
        assert actions[..., :3].max() <= 10 and actions[..., 3:].max() <= 1
        obs, reward, terminated, truncated, info = env.step(actions)
        assert space.contains({k: v.copy() for k, v in obs.items()})
    bad = env.action_space.sample()
    bad[0, 0, 3] = 2  # grab is 0 or 1
    assert bad not in env.action_space
    assert env.action_space.sample().shape == (3, env.max_agents, 5)
    # Seeded samples repeat.
    env.action_space.seed(7)
    a = env.action_space.sample()
    env.action_space.seed(7)
    assert (env.action_space.sample() == a).all()


def test_reset_follows_gymnasium_seeding():
    # reset(seed=s) starts episode 0 of every env drawn from s (as a new env of that seed); resets without a
    # seed after the first start new episodes, never replaying one; options={"episodes": ...} names them.
    env = hns.BatchEnv(scene="quadrant", num_envs=3, threads=1, seed=1)
    first, _ = env.reset(seed=42)
    first = {k: v.copy() for k, v in first.items()}
    assert env.seed == 42 and (first["episode"] == 0).all()
    fresh = hns.BatchEnv(scene="quadrant", num_envs=3, threads=1, seed=42)
    obs, _ = fresh.reset()
    for k in first:
        np.testing.assert_array_equal(first[k], obs[k], err_msg=k)
    seen = [first["episode"].copy()]
    for _ in range(3):
        obs, _ = env.reset()
        assert (obs["episode"] > seen[-1]).all(), "a reset without a seed replayed an episode"
        seen.append(obs["episode"].copy())
    again, _ = env.reset(seed=42)
    np.testing.assert_array_equal(again["obs_self"], first["obs_self"])
    obs, _ = env.reset(options={"episodes": np.array([3, 4, 5])})
    np.testing.assert_array_equal(obs["episode"], [3, 4, 5])
    with pytest.raises(ValueError, match="unknown key 'bogus'"):
        env.reset(options={"bogus": 1})
    with pytest.raises(TypeError, match="options"):
        env.reset(options=[1])
    with pytest.raises(ValueError, match="given twice"):
        env.reset(episodes=np.array([1, 2, 3]), options={"episodes": np.array([1, 2, 3])})


def test_close_releases_the_env_and_with_closes_it():
    with hns.BatchEnv(scene="quadrant", num_envs=2, threads=1) as env:
        obs, _ = env.reset()
        kept = obs["obs_self"]
        assert not env.closed
    assert env.closed
    env.close()  # idempotent
    assert env.num_envs == 2 and env.max_agents == 4 and env.seed == 1  # properties stay
    for call in (lambda: env.reset(), lambda: env.step(np.zeros((2, 4, 5), np.uint8)), env.observations,
                 env.state, lambda: env.scene(0)):
        with pytest.raises(RuntimeError, match="closed"):
            call()
    assert kept.shape == (2, 4, 11) and np.isfinite(kept).all()  # an array handed out stays valid


def test_final_observation_is_the_last_step_before_the_auto_reset():
    # Horizon 9 and 10 have the same 4-step preparation phase, so both envs play the same first 9 steps: the
    # final observation of the first (which auto-resets at step 9) is the second's observation after step 9.
    short = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=3, horizon=9)
    long = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1, seed=3, horizon=10)
    rng = np.random.default_rng(0)
    for t in range(9):
        actions = rng.integers(0, 11, size=(2, short.max_agents, 5), dtype=np.uint8)
        actions[..., 3:] &= 1
        obs, _, _, truncated, info = short.step(actions)
        reference, *_ = long.step(actions)
        assert info["_final_obs"].dtype == bool and info["_final_obs"].shape == (2,)
        assert bool(info["_final_obs"].all()) == (t == 8) and bool(truncated.all()) == (t == 8)
    assert set(info["final_obs"]) == set(obs)
    for key, final in info["final_obs"].items():
        np.testing.assert_array_equal(final, reference[key], err_msg=key)
    assert (obs["step_count"] == 0).all() and (obs["episode"] == 1).all(), "obs is the next episode's"
    assert (info["final_obs"]["episode"] == 0).all()
    # The next step's mask is clear again.
    _, _, _, _, info = short.step(np.zeros((2, short.max_agents, 5), np.uint8))
    assert not info["_final_obs"].any()


def test_episode_statistics_per_env_with_gymnasiums_mask():
    # Envs with horizons that end at different steps: each step's info["episode"] holds (E,) arrays, filled
    # where info["_episode"] is true, and agrees with the ended episodes' table info["finished"].
    env = hns.BatchEnv(scene="quadrant", num_envs=3, threads=1, seed=4, horizon=6)
    env.reset()
    ended_steps = 0
    for t in range(13):
        _, _, _, truncated, info = env.step(np.zeros((3, env.max_agents, 5), np.uint8))
        mask = info["_episode"]
        assert mask.dtype == bool and mask.shape == (3,)
        np.testing.assert_array_equal(mask, truncated)
        for key, values in info["episode"].items():
            assert values.shape == (3,), key
            assert not values[~mask].any(), key + ": zero where no episode ended"
        finished = info["finished"]
        assert sorted(finished["env"].tolist()) == np.flatnonzero(mask).tolist()
        for i, e in enumerate(finished["env"]):
            for key in ("hider_return", "seeker_return", "max_box_move", "length", "episode"):
                per_env = info["episode"]["l" if key == "length" else key]
                assert per_env[e] == finished[key][i], key
        ended_steps += bool(mask.any())
    assert ended_steps == 2
    env.close()


def test_parallel_env_follows_pettingzoos_contract():
    env = hns.ParallelEnv(scene="quadrant", seed=2, horizon=12)
    assert env.possible_agents == ["agent_%d" % i for i in range(4)] and env.agents == []
    observations, infos = env.reset(seed=5)
    assert env.agents and set(observations) == set(env.agents) == set(infos)
    with pytest.raises(TypeError, match="dict of agent name"):
        env.step(None)
    assert {infos[a]["hider"] for a in env.agents} == {True, False}, "both teams play"
    for a in env.agents:
        assert env.observation_space(a).contains(observations[a]), a
    steps, ended = 0, False
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)
        steps += 1
        assert set(observations) == set(rewards) == set(terminations) == set(truncations) == set(infos)
        for a in observations:
            assert env.observation_space(a).contains(observations[a]), a
        hider_rewards = {rewards[a] for a in rewards if infos[a]["hider"]}
        seeker_rewards = {rewards[a] for a in rewards if not infos[a]["hider"]}
        assert len(hider_rewards) == 1 and hider_rewards == {-r for r in seeker_rewards}, "team rewards"
        ended = all(truncations.values())
    assert steps == 12 and ended and not any(terminations.values())
    assert all(int(o["step_count"]) == 12 for o in observations.values()), "the episode's last observation"
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})
    observations, infos = env.reset()
    assert all(int(o["step_count"]) == 0 for o in observations.values())
    assert all(int(o["episode"]) == 1 for o in observations.values()), "the next episode, none skipped"
    env.close()


def test_gymnasium_metadata_and_render_draw_the_env():
    env = hns.BatchEnv(scene="quadrant", num_envs=2, threads=1)
    assert env.metadata["autoreset_mode"] == "same-step" and env.render_mode == "rgb_array"
    assert "rgb_array" in env.metadata["render_modes"]
    env.reset()
    picture = env.render()
    assert picture.shape == (320, 320, 3) and picture.dtype == np.uint8
    assert env.render(1, size=100).shape == (100, 100, 3)
    # Each box of env 0 is drawn where its state says: the pixel of its centre has a box's colour
    # (brown, or blue-grey / red-brown where locked).
    pos = env.state()["box_pos"][0]
    boxes = len(env.scene(0)["boxes"])
    assert boxes >= 1
    # The view of a quadrant game is the arena, x and y in [-0.2, 6.2] m, +y up.
    for b in range(boxes):
        col = int((pos[b][0] + 0.2) * 320 / 6.4)
        row = int((6.2 - pos[b][1]) * 320 / 6.4)
        assert tuple(picture[row, col]) in {(176, 122, 66), (86, 120, 170), (170, 70, 60)}, (b, pos[b])
    with pytest.raises(IndexError, match="env = 5"):
        env.render(5)
    with pytest.raises(ValueError, match="size = 10"):
        env.render(0, 10)
    env.close()
    game = hns.ParallelEnv(scene="quadrant", seed=3)
    game.reset()
    assert game.render_mode == "rgb_array" and game.render(size=128).shape == (128, 128, 3)
    game.close()
