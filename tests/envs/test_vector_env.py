"""The natively batched vector env is Gymnasium's ``SyncVectorEnv`` of single envs, bit
for bit: observations, rewards, terminations, truncations and batched infos, through
autoresets of either mode, with masks from ``info["action_mask"]`` (some actions outside
them, as an unmasked learner picks)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode

import ikbranch_gym.envs as envs
from ikbranch_gym.envs.vector_env import IKBranchVectorEnv
from tests.envs.env_cases import FAST, IDS

MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)


def _pair(env_id: str, n: int, mode: AutoresetMode, **kwargs):
    native = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                          autoreset_mode=mode, **kwargs)
    sync = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kwargs)
    return native, sync


def _actions(masks: np.ndarray, rng: np.random.Generator, p_unmasked: float) -> np.ndarray:
    """Per row a random valid branch, or with probability ``p_unmasked`` any branch."""
    valid = (rng.random(masks.shape) * masks).argmax(axis=1)
    anything = rng.integers(masks.shape[1], size=len(masks))
    return np.where(rng.random(len(masks)) < p_unmasked, anything, valid)


def _step_alike(vec, other, infos, rng: np.random.Generator, steps: int,
                p_unmasked: float) -> tuple[dict, int]:
    """Step the native ``vec`` and ``other`` ``steps`` times with the same actions (from
    the masks of ``infos``, then of each step's): every step's returns equal bit for bit,
    and ``vec``'s ``action_masks()`` its info's masks. Returns the last infos and how many
    episodes ended."""
    ends = 0
    for _ in range(steps):
        actions = _actions(infos["action_mask"], rng, p_unmasked)
        step = vec.step(actions)
        assert data_equivalence(step, other.step(actions), exact=True)
        infos = step[4]
        np.testing.assert_array_equal(vec.unwrapped.action_masks(), infos["action_mask"])
        ends += int(step[2].sum())
    return infos, ends


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name.lower())
@pytest.mark.parametrize("env_id", IDS)
def test_sub_envs_are_the_single_envs_bit_for_bit(env_id, mode):
    native, sync = _pair(env_id, 3, mode, **FAST)
    first = native.reset(seed=11)
    assert data_equivalence(first, sync.reset(seed=11), exact=True)
    _, ends = _step_alike(native, sync, first[1], np.random.default_rng(12),
                          30 if "UR5e" not in env_id else 12, p_unmasked=0.1)
    assert ends >= 2  # autoresets were exercised
    native.close()
    sync.close()


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name.lower())
@pytest.mark.parametrize("env_id", IDS)
def test_threads_change_nothing(env_id, mode):
    # Five sub-envs in groups of three and two, stepped in two threads, are the five in
    # one group bit for bit: through autoresets, a partial reset whose rows lie in both
    # groups, and actions outside the masks.
    kwargs = {"num_envs": 5, "vectorization_mode": "vector_entry_point",
              "autoreset_mode": mode, **FAST}
    one, two = gym.make_vec(env_id, **kwargs), gym.make_vec(env_id, threads=2, **kwargs)
    assert [len(group.envs) for group in two.unwrapped._groups] == [3, 2]
    first = one.reset(seed=21)
    assert data_equivalence(first, two.reset(seed=21), exact=True)
    rng = np.random.default_rng(22)
    infos, ends = _step_alike(one, two, first[1], rng, 3, p_unmasked=0.1)
    if mode == AutoresetMode.SAME_STEP:
        options = {"reset_mask": np.array([False, True, False, True, False])}
        reset = one.reset(options=options)
        assert data_equivalence(reset, two.reset(options=options), exact=True)
        infos = reset[1]
    _, more = _step_alike(one, two, infos, rng, 13 if "UR5e" not in env_id else 3,
                          p_unmasked=0.1)
    ends += more
    np.testing.assert_array_equal(one.unwrapped.action_masks(), two.unwrapped.action_masks())
    assert ends >= 1
    one.close()
    two.close()


def test_a_failed_step_needs_a_reset_and_a_reset_recovers():
    # One group failing leaves the other's sub-envs moved on: the env refuses to step
    # (or to reset only some sub-envs) until all are reset, and is then itself again.
    kwargs = {"num_envs": 4, "vectorization_mode": "vector_entry_point", "threads": 2, **FAST}
    vec, fresh = (gym.make_vec("IKBranch/Cartesian-v3", **kwargs) for _ in range(2))
    _, infos = vec.reset(seed=5)
    group = vec.unwrapped._groups[1]

    def fail(*args, **kwargs):
        raise RuntimeError("a task generator gave up")

    group.step = fail
    actions = infos["action_mask"].argmax(axis=1)
    with pytest.raises(RuntimeError, match="gave up"):
        vec.step(actions)
    del group.step
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
        vec.step(actions)
    with pytest.raises(ValueError, match="every sub-env must be reset first"):
        vec.reset(options={"reset_mask": np.array([True, False, False, False])})
    first = vec.reset(seed=9)
    assert data_equivalence(first, fresh.reset(seed=9), exact=True)
    _step_alike(vec, fresh, first[1], np.random.default_rng(10), 8, p_unmasked=0.0)


def test_the_first_reset_resets_every_sub_env():
    vec = IKBranchVectorEnv(num_envs=2, arm="cartesian", **FAST)
    with pytest.raises(ValueError, match="every sub-env must be reset first"):
        vec.reset(seed=0, options={"reset_mask": np.array([True, False])})
    vec.reset(seed=0, options={"reset_mask": np.array([True, True])})


def test_kernels_run_without_pythons_lock():
    # What lets groups overlap: every kernel the stages call releases the lock.
    from ikbranch_gym.agents import dp
    from ikbranch_gym.envs import random_chain, stepping
    from ikbranch_gym.envs.kinematics import compiled
    from ikbranch_gym.envs.models.filter import kernels

    for kernel in (stepping.survey, stepping.advance, stepping.masks, random_chain._chain,
                   kernels.bound_configurations, kernels.check_paths,
                   compiled.compiled_solve_poses(), dp._backward):
        assert kernel.targetoptions.get("nogil") is True, kernel


def test_reset_masks_and_disabled_autoreset_are_gymnasiums():
    mode = AutoresetMode.DISABLED
    native, sync = _pair("IKBranch/Cartesian-v2", 4, mode, **FAST)
    assert data_equivalence(native.reset(seed=3), sync.reset(seed=3), exact=True)
    rng = np.random.default_rng(4)
    masks = native.unwrapped.action_masks()
    for _ in range(25):
        actions = _actions(masks, rng, p_unmasked=0.0)
        step = native.step(actions)
        assert data_equivalence(step, sync.step(actions), exact=True)
        masks = step[4]["action_mask"]
        if step[2].any():
            mask = step[2].copy()
            again = native.reset(options={"reset_mask": mask})
            assert data_equivalence(again, sync.reset(options={"reset_mask": mask.copy()}),
                                    exact=True)
            masks = again[1]["action_mask"]
    with pytest.raises(TypeError, match="bool"):
        native.reset(options={"reset_mask": np.ones(4, dtype=int)})
    with pytest.raises(ValueError, match="shape"):
        native.reset(options={"reset_mask": np.ones(3, dtype=bool)})
    with pytest.raises(ValueError, match="at least one"):
        native.reset(options={"reset_mask": np.zeros(4, dtype=bool)})


def test_disabled_autoreset_refuses_to_step_an_ended_episode():
    vec = IKBranchVectorEnv(num_envs=2, autoreset_mode="disabled", arm="cartesian",
                            n_waypoints=1)
    _, infos = vec.reset(seed=0)
    vec.step(infos["action_mask"].argmax(axis=1))  # one waypoint: both episodes end
    with pytest.raises(RuntimeError, match=r"sub-envs \[0, 1\] have ended"):
        vec.step(np.zeros(2, dtype=np.int64))


def test_masks_ride_in_every_info_of_the_single_env_too():
    env = gym.make("IKBranch/KukaKR6-v0")
    _, info = env.reset(seed=5)
    for _ in range(20):
        mask = info["action_mask"]
        np.testing.assert_array_equal(mask, env.unwrapped.action_masks())
        assert mask.dtype == bool and mask.shape == (env.action_space.n,)
        _, _, terminated, _, info = env.step(int(np.flatnonzero(mask)[0]))
        if terminated:
            assert info["action_mask"].all()  # the episode is over: any action
            _, info = env.reset()


def test_spaces_and_metadata():
    vec = gym.make_vec("IKBranch/ToolTransfer-v1", num_envs=5,
                       vectorization_mode="vector_entry_point", autoreset_mode="same_step")
    single = gym.make("IKBranch/ToolTransfer-v1")
    assert vec.single_observation_space == single.observation_space
    assert vec.single_action_space == single.action_space
    assert vec.observation_space.shape == (5, *single.observation_space.shape)
    assert isinstance(vec.action_space, gym.spaces.MultiDiscrete)
    assert vec.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    obs, _ = vec.reset(seed=0)
    assert vec.observation_space.contains(obs)
    assert vec.get_attr("n_waypoints") == (8,) * 5
    assert len(vec.call("action_masks")) == 5


@pytest.mark.parametrize("env_id", ["IKBranch/Cartesian-v2", "IKBranch/IRB4600ToolTransfer-v0"])
def test_every_registered_id_has_a_vector_entry_point(env_id):
    for registered in envs.ENV_IDS:
        assert (gym.spec(registered).vector_entry_point
                == "ikbranch_gym.envs.vector_env:IKBranchVectorEnv")
    vec = gym.make_vec(env_id, num_envs=2)  # the default mode for such an id
    assert isinstance(vec.unwrapped, IKBranchVectorEnv)


def test_bad_input_is_refused_with_its_name():
    with pytest.raises(ValueError, match="num_envs must be an integer >= 1"):
        IKBranchVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="autoreset_mode"):
        IKBranchVectorEnv(num_envs=1, autoreset_mode="sometimes")
    for threads in (0, 4, 1.5, True):
        with pytest.raises(ValueError, match=r"threads must be .* from 1 to num_envs \(3\)"):
            IKBranchVectorEnv(num_envs=3, threads=threads, arm="cartesian")
    vec = IKBranchVectorEnv(num_envs=3, arm="anthropomorphic", **FAST)
    with pytest.raises(RuntimeError, match="reset"):
        vec.step(np.zeros(3, dtype=np.int64))
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        vec.step(np.zeros(2, dtype=np.int64))
    with pytest.raises(ValueError, match="integers"):
        vec.step(np.zeros(3))
    with pytest.raises(ValueError, match=r"action 8 of sub-env 1 is not a branch index"):
        vec.step(np.array([0, 8, 0]))
    with pytest.raises(ValueError, match="seed"):
        vec.reset(seed=[1, 2])
    # A KR 6's turn branches outside the limits are masked: an action there is refused
    # with enforce_masks, and is the env's invalid move (as in the single env) without.
    kwargs = {"arm": "kuka_kr6_r700", **FAST}
    strict = IKBranchVectorEnv(num_envs=2, enforce_masks=True, **kwargs)
    loose = IKBranchVectorEnv(num_envs=2, **kwargs)
    _, infos = strict.reset(seed=0)
    loose.reset(seed=0)
    masks = infos["action_mask"]
    outside = int(np.flatnonzero(~masks[1])[0])
    actions = np.array([int(masks[0].argmax()), outside])
    with pytest.raises(ValueError, match=f"action {outside} of sub-env 1 is outside its mask"):
        strict.step(actions)
    _, reward, terminated, _, info = loose.step(actions)
    assert terminated[1] and info["invalid"][1] and reward[1] < -loose.envs[1].invalid_penalty


def test_rendering_gives_every_sub_envs_frame():
    vec = IKBranchVectorEnv(num_envs=2, render_mode="rgb_array", width=64, height=48,
                            arm="cartesian", **FAST)
    vec.reset(seed=0)
    frames = vec.render()
    assert len(frames) == 2 and all(f.shape == (48, 64, 3) for f in frames)
    assert frames[0].std() > 0
    vec.close()


def test_a_cell_engineers_file_task_in_a_scene_file_is_batched_alike():
    # The waypoint file, scene file and tool of the welding example: a task from a finite
    # pose set (solved through each sub-env's pose cache) in a cell read from MJCF.
    import json
    from pathlib import Path

    examples = Path(__file__).resolve().parents[2] / "examples"
    kwargs = {"arm": "abb_irb2400", "scene": "file", "task": "file",
              "scene_file": str(examples / "welding_cell.xml"),
              "task_file": str(examples / "welding_seam.csv"),
              "tool": json.loads((examples / "welding_torch.json").read_text()),
              "lookahead": 1}
    native = IKBranchVectorEnv(num_envs=2, autoreset_mode="same_step", **kwargs)
    sync = gym.vector.SyncVectorEnv([lambda: gym.make("IKBranch/Cartesian-v2", **kwargs)] * 2,
                                    autoreset_mode=AutoresetMode.SAME_STEP)
    first = native.reset(seed=3)
    assert data_equivalence(first, sync.reset(seed=3), exact=True)
    _step_alike(native, sync, first[1], np.random.default_rng(5), 12, p_unmasked=0.0)
