#!/usr/bin/env python3
"""A compact PPO in PyTorch that learns an hns task through hns.BatchEnv (no hns trainer involved).

    PYTHONPATH=build/python python3 examples/torch_ppo.py                      # lockbox, 100 iterations
    PYTHONPATH=build/python python3 examples/torch_ppo.py --iterations 5 --envs 8

The lone agent of `lockbox` must reach a cube and lock it (docs/transfer.md); the uniformly random policy
scores about 3 per episode, a policy that locks the cube early and holds it about 50; this one passes 20
within about 60 iterations (230 k agent-steps, 40 s on 2 cores) and keeps rising. Observations go into
torch without a copy (torch.from_numpy views the batch's own buffers: the data pointers are printed and
checked), the network is a small MLP over agent 0's flattened observation with one categorical head per
action component, and the update is PPO's clipped objective with GAE, as in the paper (appendix B), minus
the recurrent and attention parts. Needs Debian's python3-torch.
"""
import argparse
import time
import warnings

import numpy as np
import torch
from torch import nn

import hns

# Agent 0's observation, flattened: these keys of BatchEnv's observation dict, slot 0 of the agent axis.
OBS_KEYS = ["obs_self", "lidar", "obs_boxes", "mask_boxes", "obs_ramps", "mask_ramps", "obs_agents", "mask_agents"]
HEADS = [11, 11, 11, 2, 2]  # movement x, y, turn bins; grab, lock


def torch_views(obs):
    """Zero-copy torch tensors of the observation arrays (read-only views of the batch: only read them)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # torch warns that the arrays are not writable
        return {k: torch.from_numpy(obs[k]) for k in OBS_KEYS if k in obs}


def features(views):
    """(E, F) float32: agent 0's observation, flattened (one copy, into the network's input)."""
    parts = [views[k][:, 0].reshape(views[k].shape[0], -1).float() for k in OBS_KEYS if k in views]
    return torch.cat(parts, dim=1)


class ActorCritic(nn.Module):
    def __init__(self, n_in, hidden=128):
        super().__init__()
        self.body = nn.Sequential(nn.Linear(n_in, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh())
        self.pi = nn.Linear(hidden, sum(HEADS))
        self.v = nn.Linear(hidden, 1)
        self.register_buffer("mean", torch.zeros(n_in))
        self.register_buffer("var", torch.ones(n_in))
        self.register_buffer("count", torch.tensor(1e-4))

    def normalise(self, x, update):
        if update:  # running mean and variance of the inputs (Welford over batches)
            b_mean, b_var, b_n = x.mean(0), x.var(0, unbiased=False), x.shape[0]
            delta, total = b_mean - self.mean, self.count + b_n
            self.mean += delta * b_n / total
            self.var = (self.var * self.count + b_var * b_n + delta ** 2 * self.count * b_n / total) / total
            self.count = total
        return ((x - self.mean) / torch.sqrt(self.var + 1e-8)).clamp(-5, 5)

    def forward(self, x):
        h = self.body(x)
        return torch.split(self.pi(h), HEADS, dim=1), self.v(h).squeeze(1)


def act(model, x):
    logits, value = model(x)
    dists = [torch.distributions.Categorical(logits=l) for l in logits]
    actions = torch.stack([d.sample() for d in dists], dim=1)
    logp = sum(d.log_prob(actions[:, i]) for i, d in enumerate(dists))
    return actions, logp, value


def evaluate(model, x, actions):
    logits, value = model(x)
    dists = [torch.distributions.Categorical(logits=l) for l in logits]
    logp = sum(d.log_prob(actions[:, i]) for i, d in enumerate(dists))
    entropy = sum(d.entropy() for d in dists)
    return logp, entropy, value


def random_return(env, rng, episodes):
    """Mean return of the uniformly random policy over at least `episodes` episodes."""
    env.reset()
    returns = []
    while len(returns) < episodes:
        a = rng.integers(0, 11, size=(env.num_envs, env.max_agents, 5), dtype=np.uint8)
        a[..., 3:] &= 1
        _, _, _, _, info = env.step(a)
        returns += info["episode"]["hider_return"][info["_episode"]].tolist()
    return float(np.mean(returns))


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="lockbox", help="a single-agent task (lockbox, lock-and-return, ...)")
    p.add_argument("--envs", type=int, default=64)
    p.add_argument("--iterations", type=int, default=100)
    p.add_argument("--epochs", type=int, default=4)
    p.add_argument("--minibatches", type=int, default=4)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--threads", type=int, default=0, help="hns's threads (0 = every hardware thread)")
    args = p.parse_args()
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)

    env = hns.BatchEnv(scene=args.scene, num_envs=args.envs, threads=args.threads, seed=args.seed)
    T, E = env.horizon, env.num_envs  # one episode per env per iteration
    baseline = random_return(env, rng, 2 * E)
    obs, _ = env.reset()
    views = torch_views(obs)
    same = all(views[k].data_ptr() == obs[k].ctypes.data for k in views if views[k].numel() > 0)
    print("hns %s: %s, %d envs, horizon %d; observations zero-copy into torch: %s (data pointers equal)" % (
        hns.__version__, args.scene, E, T, "yes" if same else "NO"))
    print("random policy: mean return %.2f" % baseline)
    model = ActorCritic(features(views).shape[1])
    opt = torch.optim.Adam(model.parameters(), lr=args.lr, eps=1e-5)
    actions_np = np.zeros((E, env.max_agents, 5), np.uint8)
    actions_np[...] = 5
    actions_np[..., 3:] = 0
    start = time.perf_counter()
    history = []
    for it in range(1, args.iterations + 1):
        xs, acts, logps, values, rewards, dones = [], [], [], [], [], []
        finished = []
        with torch.no_grad():
            for t in range(T):
                x = model.normalise(features(torch_views(obs)), update=True)
                a, logp, v = act(model, x)
                actions_np[:, 0] = a.numpy()
                obs, reward, terminated, truncated, info = env.step(actions_np)
                xs.append(x), acts.append(a), logps.append(logp), values.append(v)
                rewards.append(torch.from_numpy(reward[:, 0].copy()))
                dones.append(torch.from_numpy((terminated | truncated).astype(np.float32)))
                finished += info["episode"]["hider_return"][info["_episode"]].tolist()
            last_v = model(model.normalise(features(torch_views(obs)), update=False))[1]
        # GAE (gamma 0.99, lambda 0.95); an episode's end cuts the bootstrap (a time limit, treated as an end:
        # the horizon is the whole task).
        adv = torch.zeros(T, E)
        gae = torch.zeros(E)
        for t in reversed(range(T)):
            nxt = last_v if t == T - 1 else values[t + 1]
            nonterminal = 1.0 - dones[t]
            delta = rewards[t] + 0.99 * nxt * nonterminal - values[t]
            gae = delta + 0.99 * 0.95 * nonterminal * gae
            adv[t] = gae
        returns = adv + torch.stack(values)
        b_x, b_a, b_logp = torch.cat(xs), torch.cat(acts), torch.cat(logps)
        b_adv, b_ret = adv.reshape(-1), returns.reshape(-1)
        n = b_x.shape[0]
        for _ in range(args.epochs):
            order = torch.randperm(n)
            for mb in order.chunk(args.minibatches):
                logp, entropy, v = evaluate(model, b_x[mb], b_a[mb])
                a_mb = (b_adv[mb] - b_adv[mb].mean()) / (b_adv[mb].std() + 1e-8)
                ratio = torch.exp(logp - b_logp[mb])
                pg = -torch.min(ratio * a_mb, ratio.clamp(0.8, 1.2) * a_mb).mean()
                loss = pg + 0.5 * (v - b_ret[mb]).pow(2).mean() - 0.01 * entropy.mean()
                opt.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(model.parameters(), 0.5)
                opt.step()
        history.append(float(np.mean(finished)) if finished else float("nan"))
        print("iteration %3d: %6d agent-steps, mean return %6.2f over %d episodes, %.0f s" % (
            it, it * T * E, float(np.mean(finished)) if finished else float("nan"), len(finished),
            time.perf_counter() - start), flush=True)
    env.close()
    print("final: mean return of the last 5 iterations %.2f, random policy %.2f" % (
        float(np.mean(history[-5:])), baseline))


if __name__ == "__main__":
    main()
