#!/usr/bin/env python3
"""The loop a user of hns writes: a batch of hide-and-seek games driven from Python.

    PYTHONPATH=build/python python3 examples/random_loop.py                       # random actions
    PYTHONPATH=build/python python3 examples/random_loop.py --checkpoint runs/quickstart/checkpoint.bin

Steps `--steps` batch steps of `--envs` games and prints every finished episode's returns, then the
throughput. Nothing is trained.
"""
import argparse
import time

import numpy as np

import hns


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="quadrant", choices=hns.scenes)
    parser.add_argument("--checkpoint", help="act with this training checkpoint's policy (its scene)")
    parser.add_argument("--envs", type=int, default=16)
    parser.add_argument("--steps", type=int, default=2000, help="batch steps (each steps every env once)")
    parser.add_argument("--threads", type=int, default=0, help="0 = every hardware thread")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()

    policy = hns.Policy.load(args.checkpoint, seed=args.seed) if args.checkpoint else None
    if policy is not None:
        env = policy.make_env(num_envs=args.envs, threads=args.threads, seed=args.seed)
        state = policy.initial_state(args.envs)
    else:
        env = hns.BatchEnv(scene=args.scene, num_envs=args.envs, threads=args.threads, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    print("hns %s (%s): %s, %d envs of up to %d agents, horizon %d, %s" % (
        hns.__version__, hns.isa, env.scene_name, env.num_envs, env.max_agents, env.horizon,
        "policy " + args.checkpoint if policy else "random actions"))

    obs, info = env.reset()
    hider_returns, seeker_returns = [], []
    start = time.perf_counter()
    for step in range(args.steps):
        if policy is not None:
            actions, state = policy.act(obs, state)
        else:
            actions = rng.integers(0, 11, size=(env.num_envs, env.max_agents, 5), dtype=np.uint8)
            actions[..., 3:] &= 1  # grab and lock are bits
        obs, reward, terminated, truncated, info = env.step(actions)
        ended = info["finished"]
        for i in range(len(ended["env"])):
            hider_returns.append(ended["hider_return"][i])
            seeker_returns.append(ended["seeker_return"][i])
            print("step %5d  env %3d episode %4d: hiders %+7.1f  seekers %+7.1f  boxes locked in prep %.0f" % (
                step + 1, ended["env"][i], ended["episode"][i], ended["hider_return"][i],
                ended["seeker_return"][i], ended["num_box_lock_prep"][i]))
    seconds = time.perf_counter() - start
    if hider_returns:
        print("%d episodes: mean return hiders %+.2f, seekers %+.2f" % (
            len(hider_returns), np.mean(hider_returns), np.mean(seeker_returns)))
    print("%.0f env-steps/s (%d steps of %d envs in %.2f s)" % (
        args.steps * env.num_envs / seconds, args.steps, env.num_envs, seconds))


if __name__ == "__main__":
    main()
