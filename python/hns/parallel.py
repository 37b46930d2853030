"""One hide-and-seek game in PettingZoo's parallel API (`pettingzoo.ParallelEnv`'s contract; the pettingzoo
package is not needed).

    env = hns.ParallelEnv(scene="quadrant", seed=1)
    observations, infos = env.reset(seed=42)
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)

Agents are the batch's agent slots, named "agent_0" ... (`possible_agents`); `agents` are those that play the
current episode (a game draws its team sizes per episode), and each one's info says whether it is a hider.
An agent's observation is its row of every key of hns.BatchEnv's observation dict (the per-env keys
`step_count` and `episode` as 0-d arrays). The game ends by truncation at its horizon (no game ends
otherwise): that step returns the final observations, `agents` becomes empty, and reset() starts the next
episode.
"""
import numpy as _np

from . import spaces as _spaces


class ParallelEnv:
    metadata = {"name": "hns_v0", "render_modes": ["rgb_array"], "render_fps": 1 / 0.075}
    render_mode = "rgb_array"

    def __init__(self, scene="quadrant", seed=1, threads=1, **counts):
        from . import BatchEnv  # the compiled module, imported by the package first

        self._env = BatchEnv(scene=scene, num_envs=1, threads=threads, seed=seed, **counts)
        self.possible_agents = ["agent_%d" % i for i in range(self._env.max_agents)]
        self.agents = []
        obs = self._env.observations()
        single = _spaces.observation_space(obs, None, self._env.horizon)  # one env: (agents, ...)
        # One agent's share: the batch's per-agent arrays without the agent axis; per-env scalars as they are.
        self._per_agent = {k: v.ndim >= 2 for k, v in obs.items()}
        self._observation_spaces = {
            a: _spaces.Dict({k: self._agent_space(k, s) for k, s in single.spaces.items()})
            for a in self.possible_agents}
        self._action_spaces = {a: _spaces.MultiDiscrete(_np.array(_spaces.ACTION_NVEC, dtype=_np.uint8),
                                                       dtype=_np.uint8) for a in self.possible_agents}
        self._pending = None  # the auto-reset episode's first observation, after a truncation
        self._hider = _np.zeros(self._env.max_agents, dtype=_np.uint8)

    def _agent_space(self, key, space):
        if not self._per_agent[key]:
            return space
        return _spaces.Box(space.low.flat[0], space.high.flat[0], space.shape[1:], space.dtype)

    @property
    def num_agents(self):
        return len(self.agents)

    @property
    def max_num_agents(self):
        return len(self.possible_agents)

    def observation_space(self, agent):
        return self._observation_spaces[agent]

    def action_space(self, agent):
        return self._action_spaces[agent]

    def _split(self, obs):
        return {a: {k: (v[0, i] if self._per_agent[k] else v[0]).copy() for k, v in obs.items()}
                for i, a in enumerate(self.possible_agents) if a in self.agents}

    def _infos(self):
        return {a: {"hider": bool(self._hider[i])} for i, a in enumerate(self.possible_agents) if a in self.agents}

    def reset(self, seed=None, options=None):
        if seed is None and options is None and self._pending is not None:
            obs, info = self._pending  # the batch already started the next episode at the truncation
        else:
            obs, info = self._env.reset(seed=seed, options=options)
        self._pending = None
        exists = info["agent_exists"][0]
        self._hider = info["agent_hider"][0].copy()  # the episode's roles
        self.agents = [a for i, a in enumerate(self.possible_agents) if exists[i]]
        return self._split(obs), self._infos()

    def step(self, actions):
        if not self.agents:
            raise RuntimeError("the episode has ended: call reset()")
        batch = _np.zeros((1, self._env.max_agents, 5), dtype=_np.uint8)
        batch[0, :, :3] = 5  # agents not named stand still
        if not isinstance(actions, dict):
            raise TypeError("actions must be a dict of agent name -> action (got %s)" % type(actions).__name__)
        for agent, action in actions.items():
            if agent not in self.agents:
                raise KeyError("%r is not an agent of this episode (agents: %s)" % (agent, self.agents))
            batch[0, self.possible_agents.index(agent)] = action
        obs, reward, terminated, truncated, info = self._env.step(batch, copy=True)
        ended = bool(truncated[0])
        shown = info["final_obs"] if ended else obs
        observations = self._split(shown)
        rewards = {a: float(reward[0, i]) for i, a in enumerate(self.possible_agents) if a in self.agents}
        terminations = {a: bool(terminated[0]) for a in self.agents}
        truncations = {a: ended for a in self.agents}
        infos = self._infos()
        if ended:
            self._pending = (obs, info)
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def render(self, size=320):
        """The game as it is now, drawn top-down: a uint8 array (size, size, 3) (BatchEnv.render)."""
        return self._env.render(0, size)

    def close(self):
        self._env.close()
