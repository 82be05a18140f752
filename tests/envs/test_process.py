"""Process continuity (envs/process.py) and how the env, its vector env and every planner
keep it: inside a process segment no move changes the arm's configuration or steps a
joint beyond the limit.

The job used throughout turns a KUKA KR 6 R700's tool about its own axis 25° per waypoint,
29 times (725° in all): more than j6's ±350° allow, so every branch sequence must unwind
j6 (a 335° step) once. As one segment the job is impossible; split where the unwind must
happen it is not, and the unwind is the air move between the two segments.
"""

from __future__ import annotations

import itertools
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence

from ikbranch_gym.agents.evaluation import build_policy
from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.rotations import rot_x
from ikbranch_gym.envs.process import (
    MAX_LIMIT,
    UNKNOWN,
    blocked,
    continuity,
    followable,
    inside_moves,
    least_limits,
    linear_path,
    segment_index,
)
from ikbranch_gym.envs.tasks.waypoint_file import write_waypoints
from ikbranch_gym.envs.vector_env import IKBranchVectorEnv
from tests.agents.brute_force import brute_force
from tests.envs.env_cases import least_onward_travel, raw_onward

ARM = "kuka_kr6_r700"
TURN = math.radians(25.0)
N_SPIN = 30
#: The first waypoint after the unwind every sequence must make (found by hand: j6 spans
#: 700°, the 22nd turn of 25° leaves it).
UNWIND = 22
PLANNERS = ("dp_oracle", "receding_dp", "paper_rule", "paper_pair_rule")


def _spin_poses(count: int = N_SPIN) -> np.ndarray:
    arm = make_arm(ARM)
    base = arm.fk(np.array([0.0, -1.2, 1.6, 0.0, 1.0, 0.0]))
    poses = []
    for i in range(count):
        c, s = math.cos(TURN * i), math.sin(TURN * i)
        turn = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
        poses.append(base @ turn)
    return np.array(poses)


@pytest.fixture(scope="module")
def spin_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("spin") / "spin.csv"
    write_waypoints(path, _spin_poses())
    return str(path)


def _env(path: str, **kwargs) -> IKBranchEnv:
    return IKBranchEnv(arm=ARM, scene="empty", task="file", task_file=path, **kwargs)


def _play(env: IKBranchEnv, spec: str) -> tuple[np.ndarray, list[int], bool]:
    """The configurations and branches of ``spec``'s episode, and its success."""
    _, policy = build_policy(spec, env, 0)
    obs, info = env.reset(seed=0)
    qs, branches, done = [], [], False
    while not done:
        action, _ = policy.predict(obs, action_masks=info["action_mask"], deterministic=True)
        assert info["action_mask"][int(action)]
        obs, _, done, _, info = env.step(int(action))
        qs.append(env.q.copy())
        branches.append(int(action))
    return np.array(qs), branches, bool(info["is_success"])


def _reconfigurations(arm, qs: np.ndarray, branches: list[int], limit: float) -> list[int]:
    """Waypoints whose move in changed the closed-form branch or stepped a revolute joint
    beyond ``limit`` (computed here from the joint values, not by the module)."""
    closed = arm.branch_closed_form
    out = []
    for w in range(1, len(qs)):
        step = np.abs(qs[w] - qs[w - 1])[arm.revolute_mask].max()
        if closed[branches[w]] != closed[branches[w - 1]] or step > limit:
            out.append(w)
    return out


# ------------------------------------------------------------------------ the functions

def test_a_file_task_met_again_keeps_its_continuity(spin_file):
    """The ladder of a task met again (every reset of a file task) has the continuity and
    followable branches solved the first time, equal to a new env's."""
    env = _env(spin_file, max_joint_step="auto", task_segments=[UNWIND])
    env.reset(seed=0)
    first = env.ladder
    env.reset(seed=1)
    assert env.ladder.continuity is first.continuity
    assert env.ladder.valid is first.valid
    other = _env(spin_file, max_joint_step="auto", task_segments=[UNWIND])
    other.reset(seed=0)
    np.testing.assert_array_equal(other.ladder.valid, first.valid)
    np.testing.assert_array_equal(other.ladder.candidates, first.candidates)
    np.testing.assert_array_equal(other.ladder.inside, first.inside)
    assert other.ladder.limit == first.limit

def test_segments_and_moves_inside_them():
    np.testing.assert_array_equal(segment_index(6, [0, 2, 5]), [0, 0, 1, 1, 1, 2])
    np.testing.assert_array_equal(segment_index(3, []), [0, 0, 0])
    np.testing.assert_array_equal(inside_moves(np.array([0, 0, 1, 1, 2])),
                                  [False, True, False, True, False])
    for starts in ([3], [-1], [2, 2], [2, 1]):
        with pytest.raises(ValueError, match="segment starts"):
            segment_index(3, starts)


def test_a_move_is_blocked_by_a_new_configuration_or_a_long_step():
    revolute = np.array([True, True, False])
    q0 = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    q1 = np.array([[0.3, -0.3, 5.0],  # at the limit (0.3), the prismatic joint free
                   [0.0, 0.31, 0.0],  # beyond it
                   [np.nan, 0.0, 0.0]])  # no configuration: no move
    config1 = np.array([4, 4, 4])
    out = blocked(q0, np.array([4, 5]), q1, config1, 0.3, revolute)
    np.testing.assert_array_equal(out, [[False, True, False], [True, True, True]])
    unknown = blocked(q0[:1], np.array([UNKNOWN]), q1, np.array([9, 9, 9]), 0.3, revolute)
    np.testing.assert_array_equal(unknown, [[False, True, False]])


def _random_ladder(rng, n=5, k=6, dof=3):
    candidates = rng.normal(0.0, 0.6, size=(n, k, dof))
    valid = rng.random((n, k)) < 0.8
    valid[:, 0] = True
    candidates[~valid] = np.nan
    configuration = np.array([0, 0, 1, 1, 2, 2])
    return candidates, valid, configuration, np.array([True, True, False])


def _sequences(candidates, valid, configuration, revolute, first, last):
    """Every valid branch sequence over waypoints [first, last] keeping one configuration,
    with its largest revolute step."""
    k = valid.shape[1]
    for seq in itertools.product(range(k), repeat=last - first + 1):
        waypoints = range(first, last + 1)
        if not all(valid[w, b] for w, b in zip(waypoints, seq, strict=True)):
            continue
        if len({configuration[b] for b in seq}) != 1:
            continue
        steps = [np.abs(candidates[w + 1, b] - candidates[w, a])[revolute].max()
                 for w, a, b in zip(waypoints, seq, seq[1:], strict=False)]
        yield seq, max(steps, default=0.0)


@pytest.mark.parametrize("seed", range(4))
def test_least_limits_and_followable_branches_equal_enumeration(seed):
    rng = np.random.default_rng(seed)
    candidates, valid, configuration, revolute = _random_ladder(rng)
    segments = np.array([0, 0, 0, 1, 1])
    inside = inside_moves(segments)
    need = least_limits(candidates, valid, inside, configuration, revolute)
    for w in range(5):
        first = 0 if w < 3 else 3
        options = [step for _, step in _sequences(candidates, valid, configuration, revolute,
                                                   first, w)]
        assert need[w] == min(options, default=np.inf)
    limit = float(np.median(need[np.isfinite(need)])) + 0.05
    alive = followable(candidates, valid, inside, configuration, limit, revolute)
    for w in range(5):
        last = 2 if w < 3 else 4
        for b in range(6):
            expected = valid[w, b] and any(
                seq[0] == b and step <= limit for seq, step in _sequences(
                    candidates, valid, configuration, revolute, w, last))
            assert alive[w, b] == expected, (w, b)


def test_the_derived_limit_and_its_bounds():
    candidates = np.zeros((3, 1, 1))
    candidates[:, 0, 0] = [0.0, 0.02, 0.5]
    valid = np.ones((3, 1), dtype=bool)
    one = np.zeros(1, dtype=np.int64)
    revolute = np.array([True])
    kept, _ = continuity(candidates, valid, np.array([0, 0, 1]), one, revolute, "auto")
    assert kept.derived and kept.limit == math.radians(10.0)  # 2 × 0.02 rad is less
    kept, _ = continuity(candidates, valid, np.array([0, 0, 0]), one, revolute, "auto")
    assert kept.limit == 2 * 0.48 and kept.needed.tolist() == [0.48]
    candidates[2, 0, 0] = 2.0  # a step of 1.98 rad: twice that is past the ceiling
    kept, _ = continuity(candidates, valid, np.array([0, 0, 0]), one, revolute, "auto")
    assert kept.limit == MAX_LIMIT
    with pytest.raises(ValueError, match="must lie in"):
        continuity(candidates, valid, np.array([0, 0, 0]), one, revolute, math.pi)
    with pytest.raises(ValueError, match="'auto' or None"):
        continuity(candidates, valid, np.array([0, 0, 0]), one, revolute, "smooth")


# ---------------------------------------------------------------------------- the env
def test_a_segment_no_sequence_follows_is_an_error_naming_where(spin_file):
    with pytest.raises(ValueError, match=rf"process segment 0 \(waypoints 0–29\).*between "
                                         rf"waypoint {UNWIND - 1} and waypoint {UNWIND}.*"
                                         "start a new segment there"):
        _env(spin_file, max_joint_step="auto").reset(seed=0)
    with pytest.raises(ValueError, match=r"needs a step limit of 25\.00° there"):
        _env(spin_file, max_joint_step=math.radians(20.0), task_segments=[UNWIND]).reset(seed=0)


@pytest.mark.parametrize("spec", PLANNERS)
def test_every_planner_keeps_the_configuration_inside_segments(spin_file, spec):
    arm = make_arm(ARM)
    env = _env(spin_file, max_joint_step="auto", task_segments=[UNWIND])
    qs, branches, success = _play(env, spec)
    limit = env.ladder.limit
    assert limit == pytest.approx(2 * TURN, abs=1e-12)  # derived: twice the 25° needed
    assert success and len(qs) == N_SPIN
    assert _reconfigurations(arm, qs, branches, limit) == [UNWIND]  # the air move only
    free = _env(spin_file)  # the same job without continuity
    qs, branches, success = _play(free, spec)
    moved = _reconfigurations(arm, qs, branches, limit)
    assert success and moved  # the unwind is unavoidable
    if spec != "dp_oracle":  # the travel rules unwind inside the first segment
        assert any(w != UNWIND for w in moved), moved


def test_continuity_kernels_run_one_compiled_version_whatever_the_arrays(spin_file):
    # A ladder's configurations are frozen and a contiguous broadcast of origins is a
    # read-only view: numba would compile each kernel again for every read-only argument,
    # on first use, so the kernels get writable arrays.
    from numba.core import types

    from ikbranch_gym.envs import moves, process

    for spec in PLANNERS:
        _play(_env(spin_file, max_joint_step="auto", task_segments=[UNWIND]), spec)
    frozen = np.zeros((2, 3))
    configuration = np.zeros(2, dtype=np.int64)
    revolute = np.ones(3, dtype=bool)
    for array in (frozen, configuration, revolute):
        array.flags.writeable = False
    assert not blocked(frozen, configuration, frozen, configuration, 1.0, revolute).any()
    for kernel in (moves._block_moves, moves._price, process._blocked):
        assert kernel.signatures, kernel
        for signature in kernel.signatures:
            assert all(getattr(a, "mutable", True) for a in signature
                       if isinstance(a, types.Array)), (kernel, signature)


def test_masks_leave_out_exactly_the_reconfiguring_moves(spin_file):
    arm = make_arm(ARM)
    env = _env(spin_file, max_joint_step=math.radians(40.0), task_segments=[UNWIND])
    rng = np.random.default_rng(1)
    _, info = env.reset(seed=0)
    closed, last = arm.branch_closed_form, None
    for w in range(N_SPIN):
        mask = info["action_mask"]
        np.testing.assert_array_equal(mask, env.action_masks())
        candidates, valid = env.candidates[w], env.valid[w]
        expected = valid.copy()
        if w not in (0, UNWIND):
            steps = np.abs(candidates - env.q)[:, arm.revolute_mask].max(axis=1)
            expected &= (closed == closed[last]) & (steps <= math.radians(40.0))
        np.testing.assert_array_equal(mask, expected)
        assert mask.any()
        if w == 3:  # a valid branch outside the mask is an invalid action
            outside = np.flatnonzero(valid & ~mask)
            assert len(outside)
            before = env.q.copy()
            probe = _env(spin_file, max_joint_step=math.radians(40.0), task_segments=[UNWIND])
            probe.__setstate__(env.__getstate__())
            _, reward, terminated, _, probe_info = probe.step(int(outside[0]))
            assert terminated and probe_info["invalid"] and not probe_info["collision"]
            assert probe_info["travel"] == 0.0
            np.testing.assert_array_equal(probe.q, before)
            assert reward == probe_info["reward_invalid"] + probe_info["reward_unfinished"]
        last = int(rng.choice(np.flatnonzero(mask)))
        _, _, _, _, info = env.step(last)


def test_followable_branches_are_the_only_valid_ones(spin_file):
    """A branch from which its segment cannot be followed is taken out of the ladder."""
    arm = make_arm(ARM)
    free, kept = _env(spin_file), _env(spin_file, max_joint_step="auto", task_segments=[UNWIND])
    free.reset(seed=0)
    kept.reset(seed=0)
    assert kept.valid.sum() < free.valid.sum()
    assert not (kept.valid & ~free.valid).any()
    assert np.isnan(kept.candidates[~kept.valid]).all()
    expected = followable(free.candidates, free.valid, inside_moves(segment_index(N_SPIN,
                                                                                  [UNWIND])),
                          arm.branch_closed_form, kept.ladder.limit, arm.revolute_mask)
    np.testing.assert_array_equal(kept.valid, expected)


def test_the_dp_is_the_optimum_under_continuity(tmp_path):
    """Five waypoints of the spin job in one segment: every mask-respecting sequence
    enumerated (reconfiguring moves priced as the invalid actions they are)."""
    path = tmp_path / "short.csv"
    write_waypoints(path, _spin_poses(5))
    env = IKBranchEnv(arm=ARM, scene="empty", task="file", task_file=str(path),
                      max_joint_step=math.radians(30.0), time_weight=0.5)
    _, policy = build_policy("dp_oracle", env, 0)
    obs, info = env.reset(seed=0)
    total, done = 0.0, False
    best = brute_force(env)
    while not done:
        action, _ = policy.predict(obs, action_masks=info["action_mask"], deterministic=True)
        obs, reward, done, _, info = env.step(int(action))
        total += reward
    assert info["is_success"]
    assert total == pytest.approx(best, rel=1e-12, abs=1e-12)


def test_the_vector_env_is_the_single_env_bit_for_bit(spin_file):
    kwargs = {"arm": ARM, "scene": "empty", "task": "file", "task_file": spin_file,
              "max_joint_step": "auto", "task_segments": [UNWIND]}
    native = IKBranchVectorEnv(num_envs=3, **kwargs)
    sync = gym.vector.SyncVectorEnv([lambda: gym.make("IKBranch/Cartesian-v2", **kwargs)] * 3)
    first = native.reset(seed=2)
    assert data_equivalence(first, sync.reset(seed=2), exact=True)
    infos, rng = first[1], np.random.default_rng(5)
    for _ in range(70):
        masks = infos["action_mask"]
        actions = (rng.random(masks.shape) * masks).argmax(axis=1)
        unmasked = rng.random(3) < 0.05
        actions[unmasked] = rng.integers(masks.shape[1], size=unmasked.sum())
        step = native.step(actions)
        assert data_equivalence(step, sync.step(actions), exact=True)
        infos = step[4]


def test_the_free_travel_several_moves_on_keeps_the_configuration(spin_file):
    # Inside a segment only moves that keep the configuration and the step limit lead on:
    # the observation equals enumeration with the ladder's own blocked moves at every
    # step, and differs from enumeration without them somewhere.
    env = _env(spin_file, max_joint_step=math.radians(40.0), task_segments=[UNWIND],
               onward_moves=3)
    layout, scale = env.observation_layout, env.pricer.travel_scale

    def paths_collide(start, ends):
        return env.pricer.paths_collide(np.broadcast_to(start, ends.shape), ends)

    rng = np.random.default_rng(2)
    obs, info = env.reset(seed=0)
    differs, done = 0, False
    while not done:
        expected = least_onward_travel(env, 3, paths_collide)
        np.testing.assert_array_equal(obs[slice(*layout["slot0/free_travel_onward"])],
                                      np.minimum(expected / (3 * scale), 1.0).astype(np.float32))
        np.testing.assert_array_equal(raw_onward(env)[1], expected)  # exact before rounding
        free = least_onward_travel(env, 3, paths_collide, continuity=False)
        differs += int((free != expected).sum())
        obs, _, done, _, info = env.step(int(rng.choice(np.flatnonzero(info["action_mask"]))))
    assert differs


def test_continuity_needs_a_file_task_and_a_limit_below_half_a_turn(spin_file):
    with pytest.raises(ValueError, match=r"max_joint_step .* is for task='file' or 'deburring'"):
        IKBranchEnv(arm=ARM, scene="empty", max_joint_step="auto")
    with pytest.raises(ValueError, match="task_segments, task_units, task_columns and "
                                         "task_skip_unreachable are for task='file'"):
        IKBranchEnv(arm=ARM, scene="empty", task_segments=[2])
    with pytest.raises(ValueError, match="must lie in"):
        _env(spin_file, max_joint_step=4.0)
    with pytest.raises(ValueError, match="'auto' or None"):
        _env(spin_file, max_joint_step="yes").reset(seed=0)
    with pytest.raises(ValueError, match="task_segments must be a list"):
        _env(spin_file, task_segments=[1.5])
    with pytest.raises(ValueError, match="segment starts must"):
        _env(spin_file, task_segments=[40])


def test_branches_near_a_singularity_are_left_out(spin_file, tmp_path):
    from ikbranch_gym.envs.kinematics.singularities import singularity_margins

    generated = IKBranchEnv(arm="ur5e", scene="empty", task="random", n_waypoints=6)
    generated.reset(seed=2)  # a UR5e task whose branches lie at many distances
    path = write_waypoints(tmp_path / "ur.csv", generated.task.poses)
    kwargs = {"arm": "ur5e", "scene": "empty", "task": "file", "task_file": str(path)}
    free = IKBranchEnv(**kwargs)
    free.reset(seed=0)
    margin, shoulder = math.radians(20.0), 0.05
    kept = IKBranchEnv(**kwargs, singularity_margin=margin, shoulder_margin=shoulder)
    kept.reset(seed=0)
    margins = singularity_margins(make_arm("ur5e"), free.candidates)
    with np.errstate(invalid="ignore"):
        clear = (free.valid & (margins.wrist >= margin) & (margins.elbow >= margin)
                 & (margins.shoulder >= shoulder))
    assert 0 < clear.sum() < free.valid.sum() and clear.any(axis=1).all()
    np.testing.assert_array_equal(kept.valid, clear)
    assert np.isnan(kept.candidates[~clear]).all()
    with pytest.raises(ValueError, match=r"every branch lies within the singularity margins "
                                         r"\(wrist and elbow 60°\)"):
        _env(spin_file, singularity_margin=math.radians(60.0)).reset(seed=0)
    with pytest.raises(ValueError, match="singularity_margin is for task='file' or 'deburring'"):
        IKBranchEnv(arm=ARM, scene="empty", singularity_margin=0.1)
    with pytest.raises(ValueError, match="anthropomorphic has no singularity rules"):
        IKBranchEnv(arm="anthropomorphic", scene="empty", task="file",
                    task_file="examples/paper_worked_example.csv", singularity_margin=0.1)
    with pytest.raises(ValueError, match=r"shoulder_margin must be a finite number >= 0 \(m\)"):
        _env(spin_file, shoulder_margin=-1.0)
    with pytest.raises(ValueError, match="below π/2"):
        _env(spin_file, singularity_margin=2.0)


# --------------------------------------------------------------------- leaving the line
def test_a_j1_move_leaves_the_line_by_its_arcs_sagitta():
    from ikbranch_gym.envs.process import line_deviation

    arm = make_arm(ARM)
    q0 = np.array([0.0, -1.2, 1.6, 0.0, 1.0, 0.0])
    turn = 0.3
    q1 = q0 + np.array([turn, 0, 0, 0, 0, 0])
    flange = arm.fk(q0)[:3, 3]
    radius = math.hypot(flange[0], flange[1])  # the flange circles the j1 axis
    distance, rotation = line_deviation(arm.fk, q0, q1, arm.revolute_mask)
    sagitta = radius * (1 - math.cos(turn / 2))
    # Sampled every 0.25° of the turn (69 intervals): the nearest sample to the middle lies
    # at most half an interval off, where the arc is lower by a relative ≈ (2·δt)² = 2.1e-4.
    assert 0.0 <= sagitta - distance <= 2.2e-4 * sagitta
    # Its orientation turns about z at the rate the joint does; a linear move at the same
    # point of the chord has turned by the chord's fraction: equal at the middle and ends.
    assert rotation < 1e-3
    tcp = np.eye(4)
    tcp[:3, 3] = (0.0, 0.0, 0.2)  # a TCP 0.2 m along the flange's z axis
    spin = q0 + np.array([0, 0, 0, 0, 0, 1.0])  # j6 turns the tool about that axis
    distance, rotation = line_deviation(arm.fk, q0, spin, arm.revolute_mask, tcp)
    assert distance < 1e-12 and rotation < 1e-9


def test_slerp_turns_about_the_fixed_axis_also_at_half_a_turn():
    from ikbranch_gym.envs.kinematics.rotations import rot_x, rot_z
    from ikbranch_gym.envs.process import _slerp

    start = rot_z(0.2)
    for angle in (1.0, math.pi):
        turned = _slerp(start, start @ rot_x(angle), np.array([0.0, 0.3, 1.0]))
        for got, fraction in zip(turned, (0.0, 0.3, 1.0), strict=True):
            np.testing.assert_allclose(got, start @ rot_x(angle * fraction), atol=1e-12)


def _kr6_start():
    """A KR 6 R700 configuration with its wrist 5° from singular, and its closed form."""
    arm = make_arm("kuka_kr6_r700")
    q0 = np.array([0.2, -1.4, 1.8, 0.5, math.radians(5.0), 0.3])
    rows, ok = arm.ik(arm.fk(q0))
    k = int(np.argmin(np.where(ok, np.abs(rows - q0).max(axis=1), np.inf)))
    assert np.abs(rows[k] - q0).max() < 1e-9
    return arm, q0, int(arm.branch_closed_form[k])


def test_a_linear_path_follows_the_line_in_its_configuration():
    arm, q0, configuration = _kr6_start()
    tcp = np.eye(4)
    tcp[:3, 3] = [0.0, 0.03, 0.12]  # an off-axis TCP: the flange does not move on a line
    end = arm.fk(q0) @ tcp
    end[:3, 3] += [0.04, -0.05, 0.03]
    end[:3, :3] = end[:3, :3] @ rot_x(0.2)
    rows, ok = arm.ik(end @ np.linalg.inv(tcp))
    mine = [r for r, o, c in zip(rows, ok, arm.branch_closed_form, strict=True)
            if o and c == configuration]
    q1 = min(mine, key=lambda r: np.abs(r - q0).max())
    path = linear_path(arm, q0, q1, configuration, math.radians(10.0), tcp)
    assert path.problem is None
    samples = path.samples
    assert np.array_equal(samples[0], q0) and np.array_equal(samples[-1], q1)
    poses = arm.fk(samples) @ tcp
    start = arm.fk(q0) @ tcp
    count = len(samples) - 1  # 2 mm and 1° at most per step: 71 mm and 11.5° here
    assert count == math.ceil(np.linalg.norm([0.04, -0.05, 0.03]) / 0.002)
    for i, pose in enumerate(poses):
        s = i / count
        np.testing.assert_allclose(pose[:3, 3], start[:3, 3] + s * (end[:3, 3] - start[:3, 3]),
                                   atol=1e-12)
        np.testing.assert_allclose(pose[:3, :3], start[:3, :3] @ rot_x(0.2 * s), atol=1e-12)
    steps = np.abs(np.diff(samples, axis=0)).max(axis=1)
    assert steps.max() < math.radians(5.0)  # no whip (the wrist starts 5° from singular)


def test_a_linear_path_names_a_singularity_on_the_line_and_another_turn():
    arm, q0, configuration = _kr6_start()
    across = q0.copy()  # the wrist turned over: the line between passes A5 = 0
    across[3] += math.pi
    across[5] -= math.pi
    rows, ok = arm.ik(arm.fk(across))
    q1 = next(r for r, o, c in zip(rows, ok, arm.branch_closed_form, strict=True)
              if o and c == configuration)
    path = linear_path(arm, q0, q1, configuration, math.radians(10.0))
    assert path.problem.startswith("a joint steps") and "singularity" in path.problem
    assert 1 < len(path.samples) < 80  # the samples stop where it breaks
    turned = q0.copy()
    turned[5] += 2.0 * math.pi  # the same pose, A6 a turn on
    path = linear_path(arm, q0, turned, configuration, math.radians(10.0))
    assert path.problem == ("the line arrives in another turn or configuration than the "
                            "waypoint's (360.0°)")


def _least_limits_by_arrays(candidates, valid, inside, configuration, revolute):
    """least_limits as (K, K) arrays a waypoint: every move's largest revolute step, the
    moves of one configuration between valid branches, the larger of the origin's limit and
    the step, least over the origins."""
    n = len(candidates)
    need = np.empty(n)
    best = np.where(valid[0], 0.0, np.inf)
    need[0] = best.min()
    for w in range(1, n):
        if not inside[w]:
            best = np.where(valid[w], 0.0, np.inf)
        else:
            delta = np.abs(candidates[w][None, :] - candidates[w - 1][:, None])[..., revolute]
            steps = delta.max(axis=-1) if delta.shape[-1] else np.zeros(delta.shape[:-1])
            same = configuration[:, None] == configuration[None, :]
            usable = same & valid[w - 1][:, None] & valid[w][None, :]
            best = np.where(usable, np.maximum(best[:, None], steps), np.inf).min(axis=0)
        need[w] = best.min()
    return need


@pytest.mark.parametrize("seed", range(6))
def test_least_limits_are_those_of_every_move(seed):
    """The compiled least limits equal the arrays' bit for bit: invalid branches (NaN
    rows), several segments, configurations, and an arm without revolute joints too."""
    rng = np.random.default_rng(seed)
    n, k, dof = 7, 24, 6
    candidates = rng.uniform(-4.0, 4.0, size=(n, k, dof))
    valid = rng.random((n, k)) < 0.7
    candidates[~valid] = np.nan
    segments = np.cumsum(rng.random(n) < 0.3)
    configuration = rng.integers(0, 4, size=k)
    revolute = rng.random(dof) < (0.0 if seed == 5 else 0.8)
    inside = inside_moves(segments)
    np.testing.assert_array_equal(
        least_limits(candidates, valid, inside, configuration, revolute),
        _least_limits_by_arrays(candidates, valid, inside, configuration, revolute))
