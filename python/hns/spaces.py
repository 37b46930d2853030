"""Observation and action spaces of hns.BatchEnv in Gymnasium's terms.

Where the `gymnasium` package is importable these are its own `gymnasium.spaces.Box`, `MultiDiscrete` and `Dict`;
elsewhere the small classes below, which follow the same contract for what hns needs: `shape`, `dtype`,
`sample()` (from the space's own generator, seeded with `seed()`), `contains(x)` (also `x in space`), and for
`Dict` the mapping of keys to spaces (`space["obs_self"]`, `space.spaces`).
"""
import numpy as _np

try:  # pragma: no cover - depends on the interpreter
    from gymnasium.spaces import Box, Dict, MultiDiscrete  # noqa: F401

    GYMNASIUM = True
except ImportError:
    GYMNASIUM = False

    class _Space:
        def __init__(self, shape, dtype, seed=None):
            self.shape = tuple(shape)
            self.dtype = _np.dtype(dtype)
            self.np_random = _np.random.default_rng(seed)

        def seed(self, seed=None):
            self.np_random = _np.random.default_rng(seed)
            return [seed]

        def __contains__(self, x):
            return self.contains(x)

    class Box(_Space):
        """Values in [low, high] of one shape and dtype (low/high broadcast to the shape)."""

        def __init__(self, low, high, shape, dtype=_np.float32, seed=None):
            super().__init__(shape, dtype, seed)
            self.low = _np.full(self.shape, low, dtype=self.dtype)
            self.high = _np.full(self.shape, high, dtype=self.dtype)

        def sample(self):
            if self.dtype.kind == "f":
                # Unbounded floats: a standard normal where a bound is infinite, uniform between finite ones.
                bounded = _np.isfinite(self.low) & _np.isfinite(self.high)
                out = self.np_random.standard_normal(self.shape)
                lo, hi = _np.where(bounded, self.low, 0), _np.where(bounded, self.high, 1)
                out = _np.where(bounded, lo + (hi - lo) * self.np_random.random(self.shape), out)
                return out.astype(self.dtype)
            return self.np_random.integers(self.low, self.high, size=self.shape, endpoint=True).astype(self.dtype)

        def contains(self, x):
            x = _np.asarray(x)
            if x.shape != self.shape or not _np.can_cast(x.dtype, self.dtype):
                return False
            return bool(_np.all(x >= self.low) and _np.all(x <= self.high))

        def __repr__(self):
            return "Box(%s, %s)" % (self.shape, self.dtype)

    class MultiDiscrete(_Space):
        """Integers x with 0 <= x < nvec elementwise; nvec's shape is the space's shape."""

        def __init__(self, nvec, dtype=_np.int64, seed=None):
            self.nvec = _np.asarray(nvec, dtype=dtype)
            super().__init__(self.nvec.shape, dtype, seed)

        def sample(self):
            return (self.np_random.random(self.shape) * self.nvec).astype(self.dtype)

        def contains(self, x):
            x = _np.asarray(x)
            if x.shape != self.shape or x.dtype.kind not in "iu":
                return False
            return bool(_np.all(x >= 0) and _np.all(x < self.nvec))

        def __repr__(self):
            return "MultiDiscrete(%s)" % (self.nvec.tolist() if self.nvec.size <= 10 else str(self.shape))

    class Dict(_Space):
        """A dict of spaces: samples and contains() key by key."""

        def __init__(self, spaces, seed=None):
            self.spaces = dict(spaces)
            self.shape, self.dtype = None, None
            self.np_random = _np.random.default_rng(seed)
            self.seed(seed)

        def seed(self, seed=None):
            seeds = _np.random.SeedSequence(seed).spawn(len(self.spaces))
            for space, s in zip(self.spaces.values(), seeds):
                space.seed(int(s.generate_state(1)[0]))
            return [seed]

        def sample(self):
            return {k: s.sample() for k, s in self.spaces.items()}

        def contains(self, x):
            return isinstance(x, dict) and x.keys() == self.spaces.keys() and all(
                self.spaces[k].contains(v) for k, v in x.items())

        def __getitem__(self, key):
            return self.spaces[key]

        def keys(self):
            return self.spaces.keys()

        def __repr__(self):
            return "Dict(%s)" % ", ".join("%r: %r" % kv for kv in self.spaces.items())


# Action of one agent slot: movement along x and y and the turn as bins 0..10, then grab and lock as 0 or 1.
ACTION_NVEC = (11, 11, 11, 2, 2)


def action_space(num_agents, num_envs=None):
    """MultiDiscrete of shape (num_agents, 5), or (num_envs, num_agents, 5) for a batch, dtype uint8."""
    lead = (num_agents,) if num_envs is None else (num_envs, num_agents)
    return MultiDiscrete(_np.broadcast_to(_np.array(ACTION_NVEC, dtype=_np.uint8), lead + (5,)).copy(), dtype=_np.uint8)


def observation_space(obs, num_envs=None, horizon=2 ** 31 - 1):
    """A Dict of Box spaces matching the arrays of a BatchEnv observation dict `obs` (whose arrays have the
    batch's leading num_envs axis): per env when num_envs is None, else with that leading axis. Floats are
    unbounded, masks 0/1, `step_count` in [0, horizon], `episode` in [0, 2^31 - 1]."""
    spaces = {}
    for key, a in obs.items():
        shape = a.shape[1:] if num_envs is None else (num_envs,) + a.shape[1:]
        if a.dtype == _np.float32:
            spaces[key] = Box(-_np.inf, _np.inf, shape, _np.float32)
        elif key == "step_count":
            spaces[key] = Box(0, horizon, shape, _np.int32)
        elif key == "episode":
            spaces[key] = Box(0, 2 ** 31 - 1, shape, _np.int32)
        else:
            spaces[key] = Box(0, 1, shape, a.dtype)
    return Dict(spaces)
