"""New episodes for a batch of envs: a reset, with what several envs can do at once done
at once.

A reset seeds the env, lays its clutter, draws its task, solves every waypoint's IK and
checks every candidate, then begins the episode. The single env resets a batch of one; a
vector env the sub-envs whose episodes ended, together:

- per env: the seed, the clutter (its own scene, or the one ``reset`` options name) and
  the task (from the env's generator, or from ``task_seed``'s) — the random task's chain
  of configurations in one compiled call each (``envs.random_chain``), other tasks from
  their generators;
- at once: the waypoint poses of every random chain (one ``arm.fk`` call), the IK of
  every waypoint (one call of the compiled driver: a pose's branches never depend on its
  batch) and the endpoint check of every candidate (one call of the filter, each in its
  env's scene; turn copies share a check, ``envs.moves.endpoint_collision``);
- per env: its ladder and observation templates, the episode begun.

Tasks from a finite pose set (the milling cell's tool changes, a waypoint file) are
solved through each env's pricer instead, whose pose cache answers them once met.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbranch_gym.envs.models.filter import CompiledFilter, FilterStack
from ikbranch_gym.envs.models.filter.kernels import BY_MUJOCO
from ikbranch_gym.envs.moves import TaskMoves, endpoint_collision
from ikbranch_gym.envs.random_chain import random_chain_configurations
from ikbranch_gym.envs.tasks import Task
from ikbranch_gym.envs.tasks.random_reachable import random_reachable

if TYPE_CHECKING:
    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv


#: What ``reset(options=…)`` of a single env may name (a vector env: N of each).
RESET_OPTIONS = ("scene_seed", "task_seed")


def begin_episodes(envs: Sequence[IKBranchEnv], seeds: Sequence[int | None],
                   checks: CompiledFilter | FilterStack, scenes: np.ndarray,
                   options: Sequence[dict[str, int]] | None = None) -> list[dict[str, Any]]:
    """Reset ``envs`` (env i with ``seeds[i]`` and the checked ``options[i]``, a dict of
    :data:`RESET_OPTIONS`; ``scenes[i]`` its scene in ``checks``, the filter of the lone
    env or the vector env's stack): each begins a new episode. Returns each reset's
    ``info`` (without the action mask).

    ``scene_seed`` lays that clutter instead of drawing one, ``task_seed`` draws the task
    from a generator of its own seeded with it: the env's ``np_random`` makes neither draw
    (the option replaces it)."""
    chosen = [{} for _ in envs] if options is None else list(options)
    infos = [env._reset_scene(seed, option.get("scene_seed"))
             for env, seed, option in zip(envs, seeds, chosen, strict=True)]
    rngs = [env.np_random if option.get("task_seed") is None
            else np.random.default_rng(option["task_seed"])
            for env, option in zip(envs, chosen, strict=True)]
    for info, option in zip(infos, chosen, strict=True):
        if option.get("task_seed") is not None:
            info["task_seed"] = option["task_seed"]
    tasks = _draw_tasks(envs, rngs)
    solved = [i for i, env in enumerate(envs) if not getattr(env._generator, "finite_poses",
                                                             False)]
    ladders: list[TaskMoves | None] = [None] * len(envs)
    if solved:
        for i, ladder in zip(solved, _solve([envs[i] for i in solved], [tasks[i] for i in solved],
                                            checks, scenes[solved]), strict=True):
            ladders[i] = ladder
    for i, env in enumerate(envs):
        solved_ladder = ladders[i]
        ladder = solved_ladder if solved_ladder is not None else env.pricer.task(tasks[i])
        env._start(tasks[i], ladder)
        if env.optimal_return is not None:
            infos[i]["optimal_return"] = env.optimal_return
    return infos


def _draw_tasks(envs: Sequence[IKBranchEnv], rngs: Sequence[np.random.Generator]) -> list[Task]:
    """Each env's task (env i's from ``rngs[i]``), in the cell frame turned into the fk
    frame: the random task's chains drawn one env at a time, their poses in one call."""
    tasks: list[Task | None] = [None] * len(envs)
    chained = [i for i, env in enumerate(envs) if env._generator is random_reachable]
    for i, env in enumerate(envs):
        if i not in chained:
            pricer, limit = env.pricer, env.pricer.max_joint_step
            # A generator that keeps its segments followable keeps them so within the
            # env's own limit ("auto", derived from the task drawn, cannot be known yet).
            options = ({"max_step": float(limit)}
                       if getattr(env._generator, "step_limited", False)
                       and limit is not None and not isinstance(limit, str) else {})
            tasks[i] = env._generator(env._task_arm, rngs[i], env.n_waypoints,
                                      pricer.is_workable, pricer.is_path_free, **options)
    if chained:
        chains = np.array([
            random_chain_configurations(envs[i]._task_arm, rngs[i],
                                        envs[i].n_waypoints, envs[i].compiled_filter,
                                        envs[i].checker.lever, envs[i].checker.resolution)
            for i in chained])
        count, length, dof = chains.shape
        poses = envs[chained[0]]._task_arm.fk(chains[:, 1:].reshape(-1, dof))
        poses = poses.reshape(count, length - 1, 4, 4)
        for j, i in enumerate(chained):
            tasks[i] = Task(start=chains[j, 0], poses=poses[j])
    drawn = [task for task in tasks if task is not None]
    assert len(drawn) == len(envs)  # every env's task, from its generator or its chain
    return [env._in_fk_frame(task) for env, task in zip(envs, drawn, strict=True)]


def _solve(envs: Sequence[IKBranchEnv], tasks: Sequence[Task],
           checks: CompiledFilter | FilterStack, scenes: np.ndarray) -> list[TaskMoves]:
    """The ladders of ``tasks`` (of ``envs``, env i in scene ``scenes[i]``): one IK call
    and one endpoint check for all."""
    arm = envs[0].arm
    n = tasks[0].n_waypoints
    poses = np.ascontiguousarray(np.concatenate([task.poses for task in tasks]))
    candidates, valid = arm.ik(poses)
    pose_scenes = np.repeat(np.asarray(scenes, dtype=np.int64), n)
    if isinstance(checks, FilterStack):
        stack = checks

        def decide(rows: np.ndarray, where: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            out, how = stack.collide_how(where, rows)
            return out > 0, how != BY_MUJOCO

        def recheck(rows: np.ndarray, where: np.ndarray) -> np.ndarray:
            return stack.collide(where, rows) > 0
    else:  # one env's own filter: every pose in its one scene
        own = checks

        def decide(rows: np.ndarray, where: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            out, how = own.collide_how(rows)
            return out > 0, how != BY_MUJOCO

        def recheck(rows: np.ndarray, where: np.ndarray) -> np.ndarray:
            return own.collide(rows) > 0
    endpoint = endpoint_collision(arm, candidates, valid, decide, recheck, pose_scenes)
    ladders = []
    for i, (env, task) in enumerate(zip(envs, tasks, strict=True)):
        rows = slice(i * n, (i + 1) * n)
        ladders.append(env.pricer.solved(task, candidates[rows], valid[rows], endpoint[rows]))
    return ladders
