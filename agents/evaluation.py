"""One evaluation loop for baselines, trained models and any policy, on shared task seeds.

Every policy gets its own fresh env (so no policy inherits another's collision cache and
its decision time is its own) and episode e of every policy is ``reset(seed=seed + e)``:
the same tasks for all. The DP oracle always runs, because the gaps of every other policy
are measured against it on those same tasks.

What can be evaluated (:func:`evaluate`'s ``policies``; :data:`POLICY_FORMS`):

- a baseline spec (``paper_rule``, ``receding_dp:4``, …: ``agents.BASELINES``);
- the path of an SB3 model zip (PPO or MaskablePPO, recognised from the file);
- the path of a model's actor exported by ``ikbranch export`` (``.npz``:
  ``agents.exported``, numpy alone);
- ``MODULE:ATTR`` (``MODULE`` may also be a ``.py`` file): the attribute is resolved as
  a Python object below;
- a Python object: an SB3 model (anything with SB3's ``predict``, masks passed where its
  policy takes them), or a callable ``policy(obs, mask) -> action`` (``mask`` (K,) bool,
  the branches it may choose; ``action`` an int or anything ``np.asarray(...).item()``
  makes one), or a *factory*: a class, or a callable that can be called with no argument
  and not with two, called once per evaluated env and its result taken as one of the
  former. Name a policy with a ``(name, policy)`` pair or a mapping ``{name: policy}``;
  otherwise its name is its spec, the callable's ``__name__`` or the model's class name.

The env: an id (with ``env_kwargs``) or a factory returning a fresh env whose innermost
env is an ``IKBranchEnv``, then ``wrappers`` applied in order (Gymnasium wrapper classes
or callables ``env -> env``), so a policy trained under a wrapper is evaluated under it.
Every policy, the oracle and the baselines included, plays that same wrapped env; the
returns are the rewards its ``step`` returns. The branches offered at each step are those
of the outermost wrapper (``agents.base.action_mask``: ``action_masks()`` through
``env.get_wrapper_attr``, narrowed by the latest ``info["action_mask"]``): a wrapper that
forbids a branch is obeyed by every baseline, and a planner forced off its plan re-plans
from where it stands, so under such a wrapper the oracle's row is the best the
planner finds within the wrapper's masks, not necessarily their optimum.

The gaps (one meaning each, here and in docs/results.md), against the oracle on the same
tasks: ``mean_gap`` = (mean R_oracle − mean R) / |mean R_oracle| over the evaluated tasks;
``iqm_gap`` = the interquartile mean over tasks of (R_oracle,i − R_i) / |R_oracle,i|,
tasks with R_oracle,i = 0 left out (``iqm_gap_skipped`` counts them).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike

import ikbranch_gym.envs  # noqa: F401  (registers the env ids)

from . import BASELINES, make_baseline
from .base import Baseline, Policy, action_mask

ORACLE = "dp_oracle"

#: What a policy may be, as the CLI's error messages say it.
POLICY_FORMS = (
    f"a baseline name ({', '.join(BASELINES)}; receding_dp:H, random:SEED, fixed:BRANCH), "
    "the path of an SB3 model zip (PPO or MaskablePPO), the path of a policy exported "
    "from one (.npz, ikbranch export), or MODULE:ATTR (MODULE a module "
    "or a .py file; ATTR a callable (obs, mask) -> action, a factory of one called with no "
    "argument, or an SB3 model)"
)

#: A wrapper: a Gymnasium wrapper class or any callable env -> env.
Wrapper = Callable[[gym.Env], gym.Env]


@dataclass(frozen=True)
class Episode:
    """What one episode cost and how it ended."""

    reward: float  # the return: sum of the env's rewards
    travel: float  # rad-equivalents (prismatic joints at the env's prismatic_scale)
    time: float  # s
    steps: int
    success: bool
    collision: bool
    invalid: bool
    decision_seconds: float  # wall time inside predict, summed over the episode


#: Called after every step of :func:`run_episode` with the action taken, its reward and
#: its ``info``.
StepObserver = Callable[[int, float, dict[str, Any]], None]


def run_episode(policy: Policy, env: gym.Env, seed: int,
                observe: StepObserver | None = None) -> Episode:
    """Play one episode of ``env`` reset with ``seed``, ``policy`` choosing deterministically
    among the branches ``env``'s outermost wrapper allows (``agents.base.action_mask``);
    ``observe(action, reward, info)`` sees each step (``ikbranch plan`` records its plans so)."""
    obs, info = env.reset(seed=seed)
    state, start = None, True
    reward = travel = duration = decision = 0.0
    steps, collision, invalid, success = 0, False, False, False
    done = False
    while not done:
        masks = action_mask(env, info)
        tick = time.perf_counter()
        action, state = policy.predict(
            obs, state=state, episode_start=np.array([start]), deterministic=True,
            action_masks=masks,
        )
        decision += time.perf_counter() - tick
        chosen = int(np.asarray(action).item())
        obs, r, terminated, truncated, info = env.step(chosen)
        if observe is not None:
            observe(chosen, float(r), info)
        start, done = False, terminated or truncated
        reward += float(r)
        travel += float(info["travel"])
        duration += float(info["time"])
        collision |= bool(info["collision"])
        invalid |= bool(info["invalid"])
        success = bool(info.get("is_success", False))
        steps += 1
    return Episode(reward, travel, duration, steps, success, collision, invalid, decision)


#: The baselines whose spec takes an argument after a colon: name -> (keyword, parse).
#: A parse raises ValueError for a value it refuses.
SPEC_ARGUMENTS: dict[str, tuple[str, Any]] = {
    "random": ("seed", lambda text: _integer(text, 0, "seed")),
    "receding_dp": ("horizon", lambda text: _integer(text, 1, "horizon")),
    "fixed": ("branch", str),  # an index or a label: the baseline checks it against the arm
}


def _integer(text: str, minimum: int, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = minimum - 1
    if value < minimum:
        raise ValueError(f"the argument is a {what} (an integer >= {minimum}), got {text!r}")
    return value


def parse_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """A baseline spec (``name`` or ``name:argument``) as ``(name, keyword arguments)``,
    checked without an env: ``ValueError`` for an unknown name, an argument the baseline
    does not take, or a value it refuses (see :func:`build_policy`)."""
    name, colon, argument = spec.partition(":")
    if name not in BASELINES:
        raise ValueError(f"unknown baseline {name!r}; choose one of {', '.join(BASELINES)}")
    if not colon:
        return name, {}
    if name not in SPEC_ARGUMENTS:
        raise ValueError(f"baseline {name!r} takes no argument, got {spec!r}")
    keyword, parse = SPEC_ARGUMENTS[name]
    return name, {keyword: parse(argument)}


# ------------------------------------------------------------------ policies of any kind
class CallablePolicy:
    """A callable ``policy(obs, mask) -> action`` behind SB3's ``predict``.

    ``mask`` is the (K,) bool array of the branches allowed now (None where the env has
    no masks); the callable is asked for the action to take, so ``deterministic`` is not
    passed on.
    """

    def __init__(self, function: Callable[[Any, Any], Any], name: str = "") -> None:
        self.function = function
        self.name = name or _name_of(function)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
        action_masks: np.ndarray | None = None,
    ) -> tuple[np.ndarray, Any]:
        action = np.asarray(self.function(observation, action_masks))
        if action.size != 1:
            raise ValueError(f"policy {self.name!r} returned {action.size} actions for one "
                             "observation; a policy returns one branch index")
        return action.reshape(()), state


def _name_of(thing: Any) -> str:
    return str(getattr(thing, "__name__", None) or type(thing).__name__)


def _is_sb3_model(thing: Any) -> bool:
    if "stable_baselines3" not in sys.modules:  # no SB3 model can exist without it
        return False
    from stable_baselines3.common.base_class import BaseAlgorithm

    return isinstance(thing, BaseAlgorithm)


def _is_factory(thing: Any) -> bool:
    """A class, or a callable that can be called with no argument and not with two."""
    if inspect.isclass(thing):
        return True
    try:
        signature = inspect.signature(thing)
    except (TypeError, ValueError):  # no signature to read (some builtins): a policy
        return False

    def binds(*args: Any) -> bool:
        try:
            signature.bind(*args)
        except TypeError:
            return False
        return True

    return binds() and not binds(None, None)


def as_policy(thing: Any, env: gym.Env, name: str = "", made: bool = False) -> tuple[str, Policy]:
    """``(name, policy)`` for a Python object bound to ``env`` (module docstring).

    ``made`` marks a factory's result, which may not be a factory again.
    """
    if isinstance(thing, Baseline):
        raise ValueError(f"{type(thing).__name__} is bound to the env it was made with: pass "
                         f"the baseline by its name ({thing.name!r})")
    if _is_sb3_model(thing):
        from .sb3 import SB3Policy

        model = SB3Policy.wrap(thing, env, name)
        return model.name, model
    if callable(getattr(thing, "predict", None)):  # SB3's predict already
        return name or _name_of(thing), thing
    if not callable(thing):
        raise ValueError(f"{name or _name_of(thing)!r} is {type(thing).__name__}, not a "
                         "policy: a callable (obs, mask) -> action, a factory of one, or an "
                         "SB3 model")
    if _is_factory(thing):
        if made:
            raise ValueError(f"the factory {name or _name_of(thing)!r} returned another "
                             "factory; it must return a policy")
        return as_policy(thing(), env, name or _name_of(thing), made=True)
    policy = CallablePolicy(thing, name)
    return policy.name, policy


def resolve(spec: str) -> Any:
    """The object ``MODULE:ATTR`` names (``ATTR`` may be dotted; ``MODULE`` a module name
    or the path of a ``.py`` file). A module not found on ``sys.path`` is looked for in the
    working directory too (appended, so it shadows nothing). ``ValueError`` if neither."""
    module_name, _, attribute = spec.rpartition(":")
    if not module_name or not attribute:
        raise ValueError(f"{spec!r} is not MODULE:ATTR")
    if module_name.endswith(".py") or os.sep in module_name or "/" in module_name:
        path = Path(module_name)
        if not path.is_file():
            raise ValueError(f"{spec!r}: no file {path}")
        digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:12]
        unique = f"_ikbranch_policy_{path.stem}_{digest}"  # one module per file
        module = sys.modules.get(unique)
        if module is None:
            loader_spec = importlib.util.spec_from_file_location(unique, path)
            if loader_spec is None or loader_spec.loader is None:
                raise ValueError(f"{spec!r}: {path} cannot be imported")
            module = importlib.util.module_from_spec(loader_spec)
            sys.modules[unique] = module  # dataclasses and pickle look modules up by name
            try:
                loader_spec.loader.exec_module(module)
            except BaseException:
                del sys.modules[unique]
                raise
    else:
        try:
            module = _import(module_name)
        except ModuleNotFoundError as error:
            raise ValueError(f"{spec!r}: no module {error.name!r} (working directory "
                             f"{Path.cwd()})") from error
    value: Any = module
    for part in attribute.split("."):
        try:
            value = getattr(value, part)
        except AttributeError as error:
            raise ValueError(f"{spec!r}: {module_name} has no attribute {attribute!r}") from error
    return value


def _import(module_name: str) -> Any:
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        missing = error.name or ""
        ours = module_name == missing or module_name.startswith(missing + ".")
        cwd = os.getcwd()
        if not ours or cwd in sys.path or "" in sys.path:
            raise
        sys.path.append(cwd)  # after everything else: a folder here shadows no package
        return importlib.import_module(module_name)


def build_policy(spec: str, env: gym.Env, seed: int) -> tuple[str, Policy]:
    """``(name, policy)`` for a command-line spec bound to ``env``.

    A spec is a baseline name with an optional argument after a colon
    (``SPEC_ARGUMENTS``): ``fixed:2`` or ``fixed:back/elbow-up/wrist+`` (the branch),
    ``receding_dp:4`` (the horizon), ``random:7`` (the generator's seed; default the
    evaluation seed); or a path ending in ``.zip`` (an SB3 model; its name is the path
    without ``.zip``: training writes every run's model as ``model.zip``) or ``.npz`` (an
    exported actor, ``agents.exported``; its name the path without ``.npz``); or
    ``MODULE:ATTR`` (:func:`resolve`, then :func:`as_policy`; its name is the spec).
    ``ValueError`` for anything else, saying what is accepted (:data:`POLICY_FORMS`).
    """
    name, colon, _ = spec.partition(":")
    if name in BASELINES:
        name, kwargs = parse_spec(spec)
        if name == "random":
            kwargs.setdefault("seed", seed)
        return spec, make_baseline(name, env, **kwargs)
    if spec.endswith(".zip"):
        from .sb3 import SB3Policy  # torch is imported only when a model is evaluated

        return spec.removesuffix(".zip"), SB3Policy.load(spec, env)
    if spec.endswith(".npz"):
        from .exported import ExportedPolicy

        return spec.removesuffix(".npz"), ExportedPolicy.load(spec, env)
    if colon and not spec.endswith(":"):
        return as_policy(resolve(spec), env, spec)
    hint = ""
    if Path(spec).suffix:
        hint = (" To evaluate a model saved in another format, write a function that loads "
                "it and returns a callable (obs, mask) -> action, and pass MODULE:FUNCTION.")
    raise ValueError(f"unknown policy {spec!r}: a policy is {POLICY_FORMS}.{hint}")


# ------------------------------------------------------------------------------- gaps
def iqm(values: ArrayLike) -> float:
    """Interquartile mean of all entries: the mean of the values left after the lowest and
    the highest ``floor(n / 4)`` are dropped. It is rliable's IQM
    (``scipy.stats.trim_mean(values, 0.25, axis=None)``) to the bit: the same partition and
    the same mean, without scipy's handling of its arguments."""
    flat = np.asarray(values, dtype=float).ravel()
    if flat.size == 0:
        raise ValueError("the interquartile mean of no values")
    return float(iqm_rows(flat[None])[0])


def iqm_rows(samples: np.ndarray) -> np.ndarray:
    """(R,) :func:`iqm` of every entry of each of ``samples`` (R, …) at once (R bootstrap
    resamples): each row partitioned and averaged as one, so every value is the bits
    :func:`iqm` gives that row."""
    flat = samples.reshape(len(samples), -1)
    n = flat.shape[1]
    cut = n // 4
    return np.partition(flat, (cut, n - cut - 1), axis=1)[:, cut:n - cut].mean(axis=1)


def mean_gap(returns: ArrayLike, oracle_returns: ArrayLike) -> float | None:
    """(mean R_oracle − mean R)/|mean R_oracle|: ``returns`` of one run (tasks,) or several
    (runs, tasks) against the oracle's (tasks,) on the same tasks. With no scale (the
    oracle's mean return 0): 0.0 where the means are equal, else None."""
    best = float(np.asarray(oracle_returns, dtype=float).mean())
    mean = float(np.asarray(returns, dtype=float).mean())
    if best != 0.0:
        return (best - mean) / abs(best)
    return 0.0 if mean == best else None


def task_gaps(returns: ArrayLike, oracle_returns: ArrayLike) -> np.ndarray:
    """Per task (R_oracle,i − R_i)/|R_oracle,i| of ``returns`` (tasks,) or (runs, tasks)
    against the oracle's (tasks,), the tasks where the oracle returns 0 left out (they
    have no scale): the values the IQM gap summarises."""
    mine, best = np.asarray(returns, dtype=float), np.asarray(oracle_returns, dtype=float)
    scaled = best != 0.0
    return (best[scaled] - mine[..., scaled]) / np.abs(best[scaled])


def gaps(returns: ArrayLike, oracle_returns: ArrayLike) -> dict[str, Any]:
    """``mean_gap``, ``iqm_gap`` and ``iqm_gap_skipped`` of ``returns`` against the
    oracle's returns on the same tasks (module docstring). A gap is None where it has no
    scale: ``mean_gap`` when the oracle's mean return is 0 (0.0 if the policy's is too),
    ``iqm_gap`` when the oracle's return is 0 on every task."""
    mine, best = np.asarray(returns, dtype=float), np.asarray(oracle_returns, dtype=float)
    if mine.shape != best.shape:
        raise ValueError(f"{len(mine)} returns against {len(best)} of the oracle: "
                         "the gaps compare the same tasks")
    per_task = task_gaps(mine, best)
    return {"mean_gap": mean_gap(mine, best),
            "iqm_gap": iqm(per_task) if per_task.size else None,
            "iqm_gap_skipped": int((best == 0.0).sum())}


def summarise(episodes: list[Episode], oracle_returns: ArrayLike | None = None) -> dict[str, Any]:
    """The metrics of one policy; the gaps need the oracle's returns on the same tasks
    (None without them)."""
    rewards = np.array([e.reward for e in episodes])
    travel = np.array([e.travel for e in episodes])
    durations = np.array([e.time for e in episodes])
    steps = sum(e.steps for e in episodes)
    measured = (gaps(rewards, oracle_returns) if oracle_returns is not None else
                {"mean_gap": None, "iqm_gap": None, "iqm_gap_skipped": None})
    return {
        "success_rate": float(np.mean([e.success for e in episodes])),
        "mean_return": float(rewards.mean()),
        "std_return": float(rewards.std()),
        "mean_travel": float(travel.mean()),
        "std_travel": float(travel.std()),
        "mean_travel_deg": float(np.degrees(travel.mean())),
        "mean_time": float(durations.mean()),
        "std_time": float(durations.std()),
        "collision_rate": float(np.mean([e.collision for e in episodes])),
        "invalid_rate": float(np.mean([e.invalid for e in episodes])),
        **measured,
        "mean_steps": steps / len(episodes),
        # Wall time per decision, planning included: a planner's reset-time work is done
        # inside its first predict call, so this is its planning cost amortised per step.
        "decision_ms": 1e3 * sum(e.decision_seconds for e in episodes) / steps,
        "returns": rewards.tolist(),
        "successes": [bool(e.success) for e in episodes],
    }


def with_gaps(results: dict[str, Any]) -> dict[str, Any]:
    """``results`` with ``mean_gap`` and ``iqm_gap`` in every policy's metrics, for files
    written before both existed: ``mean_gap`` from their ``optimality_gap`` (the same
    quantity), else both from the stored per-task returns of the policy and the oracle
    (None where the file has none)."""
    policies = results.get("policies", {})
    oracle = policies.get(ORACLE, {}).get("returns")
    upgraded = {}
    for name, metrics in policies.items():
        metrics = dict(metrics)
        if "mean_gap" not in metrics or "iqm_gap" not in metrics:
            returns = metrics.get("returns")
            if oracle is not None and returns is not None and len(returns) == len(oracle):
                measured = gaps(returns, oracle)
            else:
                measured = {"mean_gap": None, "iqm_gap": None, "iqm_gap_skipped": None}
            if metrics.get("optimality_gap") is not None:  # the same quantity, as stored
                measured["mean_gap"] = metrics["optimality_gap"]
            metrics = {**measured, **metrics}  # what the file has wins
        upgraded[name] = metrics
    return {**results, "policies": upgraded}


# ------------------------------------------------------------------------- evaluation
def _env_label(env: gym.Env, factory: Callable[[], gym.Env]) -> str:
    """The id of the env a factory made (its innermost spec), else the factory's name."""
    spec = getattr(env.unwrapped, "spec", None)
    return str(getattr(spec, "id", None) or _label(factory))


def _label(thing: Any) -> str:
    return thing if isinstance(thing, str) else str(getattr(thing, "__qualname__", None)
                                                    or _name_of(thing))


def evaluate(
    env_id: str | Callable[[], gym.Env],
    policies: Sequence[Any] | Mapping[str, Any],
    episodes: int,
    seed: int,
    env_kwargs: dict[str, Any] | None = None,
    wrappers: Sequence[Wrapper] = (),
) -> dict[str, Any]:
    """Evaluate every policy on episodes seeded ``seed, seed + 1, …``.

    ``env_id``: an env id (made with ``env_kwargs``) or a factory of fresh envs (then
    ``env_kwargs`` must be empty); ``wrappers`` are applied to every env in order.
    ``policies``: a list of specs, objects and ``(name, object)`` pairs, or a mapping
    ``{name: spec or object}`` (module docstring). Returns ``{"env", "env_kwargs",
    "wrappers", "episodes", "seed", "policies": {name: metrics}}``, the oracle included
    (run first, whether asked for or not). ``ValueError`` for a policy, model or wrapper
    that does not fit, before any episode is played.
    """
    if episodes < 1:
        raise ValueError("episodes must be >= 1")
    env_kwargs = dict(env_kwargs or {})
    if not isinstance(env_id, str) and env_kwargs:
        raise ValueError("env_kwargs go with an env id; an env factory sets its own")
    wrappers = list(wrappers)
    for wrapper in wrappers:
        if not callable(wrapper):
            raise ValueError(f"a wrapper is a wrapper class or a callable env -> env, got "
                             f"{type(wrapper).__name__}")

    def make() -> gym.Env:
        env = gym.make(env_id, **env_kwargs) if isinstance(env_id, str) else env_id()
        for wrapper in wrappers:
            wrapped = wrapper(env)
            if not isinstance(wrapped, gym.Env):
                raise ValueError(f"wrapper {_label(wrapper)} returned "
                                 f"{type(wrapped).__name__}, not an env")
            env = wrapped
        return env

    items = list(policies.items()) if isinstance(policies, Mapping) else [
        item if isinstance(item, tuple) else ("", item) for item in policies]
    items = [(name, str(item) if isinstance(item, Path) else item) for name, item in items]
    # The oracle first, once, whether asked for or not.
    items = [("", ORACLE), *((name, item) for name, item in items
                             if name or not (isinstance(item, str) and item == ORACLE))]
    # Build every policy before playing any, so a bad spec or model fails at once.
    opened: list[gym.Env] = []
    players: dict[str, tuple[gym.Env, Policy]] = {}
    try:
        for given, item in items:
            opened.append(env := make())
            if isinstance(item, str):
                name, policy = build_policy(item, env, seed)
            else:
                name, policy = as_policy(item, env, given)
            name = given or name
            unique, copy = name, 2
            while unique in players:  # the same spec or model twice
                unique, copy = f"{name}#{copy}", copy + 1
            players[unique] = (env, policy)
        runs = {
            name: [run_episode(policy, env, seed + e) for e in range(episodes)]
            for name, (env, policy) in players.items()
        }
        label = env_id if isinstance(env_id, str) else _env_label(opened[0], env_id)
    finally:
        for env in opened:
            env.close()
    oracle = next(iter(runs))  # built first
    oracle_returns = [e.reward for e in runs[oracle]]
    return {
        "env": label,
        "env_kwargs": env_kwargs,
        "wrappers": [_label(wrapper) for wrapper in wrappers],
        "episodes": episodes,
        "seed": seed,
        "policies": {name: summarise(eps, oracle_returns) for name, eps in runs.items()},
    }
