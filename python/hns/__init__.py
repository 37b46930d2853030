"""hns: the batch hide-and-seek simulator of hns as numpy arrays, trained policies, and recordings.

    import hns
    env = hns.BatchEnv(scene="quadrant", num_envs=1024, seed=1)
    obs, info = env.reset()
    obs, reward, terminated, truncated, info = env.step(actions)   # actions: (num_envs, max_agents, 5)

Also: Policy.load(checkpoint) to act with a trained policy, record() to write episodes as `hns play` does,
read_trajectory() and read_metrics() for recordings and training runs.

The manual is docs/python.md of the hns repository.
"""
import json as _json

try:
    import numpy as _numpy  # noqa: F401  (the compiled module hands out numpy arrays)
except ImportError as _error:  # pragma: no cover - depends on the interpreter
    import sys as _sys

    raise ImportError(
        "hns needs numpy for this interpreter (%s); on Debian: apt-get install python3-numpy and run "
        "Debian's python3" % _sys.executable
    ) from _error

# The instruction set this package was compiled for (CMake's HNS_ISA). Checked before the compiled module
# loads: an AVX-512 build on a CPU without AVX-512 is an ImportError here, not a stopped interpreter.
_BUILD_ISA = "@HNS_ISA@"
_ISA_FLAGS = {"avx2": ("avx2", "fma"), "avx512": ("avx2", "fma", "avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl")}


def _check_cpu():
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), None)
    except OSError:
        return
    if flags is None:
        return
    missing = [flag for flag in _ISA_FLAGS.get(_BUILD_ISA, ()) if flag not in flags]
    if missing:
        raise ImportError(
            "this hns package was built with HNS_ISA=%s, which needs %s; this CPU lacks %s: rebuild with "
            "HNS_ISA=avx2 tools/test (or cmake -DHNS_ISA=avx2)" % (_BUILD_ISA, ", ".join(_ISA_FLAGS[_BUILD_ISA]), ", ".join(missing))
        )


_check_cpu()

from ._hns import (  # noqa: F401
    BatchEnv,
    Policy,
    TrajectoryError,
    __version__,
    isa,
    read_trajectory,
    record,
    scene_info,
    scenes,
)
from ._hns import _detect_stages_json, _read_metrics_json
from . import spaces  # noqa: E402


# Gymnasium's names for what a BatchEnv takes and gives (hns.spaces: gymnasium.spaces where importable). Each
# is built on first use and kept by the env, so seeding a space (env.action_space.seed(1)) lasts.
def _cached(name, make):
    def get(self):
        space = self.__dict__.get(name)
        if space is None:
            space = self.__dict__[name] = make(self)
        return space

    get.__doc__ = make.__doc__
    return property(get)


def _single_observation_space(self):
    """The observation of one env: a Dict of Box spaces, one per key of reset()'s and step()'s obs (the
    arrays without their leading num_envs axis)."""
    return spaces.observation_space(self.observations(), None, self.horizon)


def _observation_space(self):
    """The batch's observation: single_observation_space with the leading num_envs axis."""
    return spaces.observation_space(self.observations(), self.num_envs, self.horizon)


def _single_action_space(self):
    """The actions of one env: MultiDiscrete [11, 11, 11, 2, 2] per agent slot, shape (max_agents, 5), uint8."""
    return spaces.action_space(self.max_agents)


def _action_space(self):
    """The batch's actions, what step() takes: shape (num_envs, max_agents, 5), uint8."""
    return spaces.action_space(self.max_agents, self.num_envs)


BatchEnv.single_observation_space = _cached("_single_observation_space", _single_observation_space)
BatchEnv.observation_space = _cached("_observation_space", _observation_space)
BatchEnv.single_action_space = _cached("_single_action_space", _single_action_space)
BatchEnv.action_space = _cached("_action_space", _action_space)

# Gymnasium's metadata: auto-reset inside the step that ends a game (info["final_obs"] keeps its last
# observation); render() draws one env as an RGB array.
BatchEnv.metadata = {"render_modes": ["rgb_array"], "autoreset_mode": "same-step", "render_fps": 1 / 0.075}
BatchEnv.render_mode = "rgb_array"


def _render(self, env=0, size=320):
    """Env `env` as it is now, drawn top-down as `hns replay --gif` draws a frame: a uint8 array
    (size, size, 3); a bad env is an IndexError, a size outside [64, 4096] a ValueError. Walls dark grey, boxes brown (blue-grey or red-brown where hiders or seekers locked
    them), ramps olive with their high edge dark, hiders cyan and seekers red with arms and vision cone; the
    floor is tinted and a yellow bar runs along the top during the preparation phase."""
    return self._render_rgb(int(env), int(size))


BatchEnv.render = _render

from .parallel import ParallelEnv  # noqa: E402,F401  (one game in PettingZoo's parallel API)


def read_metrics(path):
    """The iterations of a run's metrics.jsonl as a list of dicts, one per iteration, in file order.

    Reads like `hns report` does: blank lines are skipped, a line that is not an iteration record raises
    ValueError naming the file and line.
    """
    return _json.loads(_read_metrics_json(str(path)))


def detect_stages(rows, scene):
    """The paper's stages in read_metrics() rows of a `scene` run ("quadrant" or "full"; other scenes have
    none), as `hns train` and `hns report` detect them (docs/training.md "Stages").

    Returns a dict with `scene`, `window_episodes` and `stages`: in the paper's order, dicts with `name`,
    `criterion`, `threshold`, `value` (float array, one per row: the window's value, NaN while the window
    holds too few episodes), `on` (bool array), and where the criterion first held: `first_row` (-1: never),
    `first_iteration`, `first_agent_steps`, `first_episodes`.
    """
    scene = str(scene)
    if scene not in scenes:
        raise ValueError("scene %r is not a scene of hns (hns.scenes: %s)" % (scene, ", ".join(scenes)))
    rows = list(rows)
    for i, row in enumerate(rows):
        if not isinstance(row, dict) or "iteration" not in row or "agent_steps" not in row:
            raise ValueError("rows[%d] is not a metrics row (a dict with iteration and agent_steps, as "
                             "read_metrics() gives)" % i)
    try:
        text = _json.dumps(rows, allow_nan=False)
    except ValueError:
        raise ValueError("rows hold NaN or an infinity, which metrics rows never do (read_metrics() gives "
                         "none)") from None
    report = _json.loads(_detect_stages_json(text, scene))
    for stage in report["stages"]:
        stage["value"] = _numpy.asarray([float("nan") if v is None else v for v in stage["value"]], dtype=float)
        stage["on"] = _numpy.asarray([c == "1" for c in stage["on"]], dtype=bool)
    return report


def metrics_column(rows, key, default=float("nan")):
    """One metric of read_metrics() rows as a numpy float array, `default` where a row lacks it.

    Example: metrics_column(rows, "hider_reward") against metrics_column(rows, "agent_steps").
    """
    rows = list(rows)
    for i, row in enumerate(rows):
        if not isinstance(row, dict):
            raise TypeError("rows[%d] is a %s, not a metrics row (a dict, as read_metrics() gives)"
                            % (i, type(row).__name__))
    return _numpy.asarray([row.get(key, default) for row in rows], dtype=float)
