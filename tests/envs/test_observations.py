"""Observation layouts: the compact one grows O(K), its travel summaries are exact, and
both stay inside the observation space."""

from __future__ import annotations

import itertools

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs as envs
from ikbranch_gym.envs.moves import TaskMoves
from ikbranch_gym.envs.observations import OBSERVATIONS
from tests.envs.env_cases import IDS, least_onward_travel, raw_onward, same_info


@pytest.mark.parametrize("kind", OBSERVATIONS)
def test_layout_sizes(kind):
    env = gym.make("IKBranch/ToolTransfer-v0", observation=kind, lookahead=2)
    base = env.unwrapped
    k, dof = base.arm.n_branches, base.arm.dof
    per_slot = 1 + k * dof + 2 * k
    if kind == "compact":
        # travel_out in every slot; slot 0: travel, path_collision, free_travel_out;
        # slots 1, 2: travel_in.
        expected = dof + 1 + 3 * (per_slot + k) + 3 * k + 2 * k
    else:
        expected = dof + 1 + 3 * per_slot + 2 * k + 2 * k * k
    assert env.observation_space.shape == (expected,)
    ends = sorted(base.observation_layout.values())
    assert ends[0][0] == 0 and all(a[1] == b[0] for a, b in itertools.pairwise(ends))


def test_compact_grows_linearly_in_the_branches():
    small = gym.make("IKBranch/ToolTransfer-v0", observation="compact").observation_space
    env = gym.make("IKBranch/ToolTransfer-v0", arm="ur5e", scene="random_clutter",
                   task="random", observation="compact")
    k = env.unwrapped.arm.n_branches
    assert k == 256 and env.observation_space.shape[0] < 40 * k
    assert small.shape[0] < 40 * 8


@pytest.mark.parametrize("env_id", IDS)
def test_compact_travel_summaries_are_the_least_travel(env_id):
    env = gym.make(env_id, observation="compact", lookahead=2, n_waypoints=4)
    base = env.unwrapped
    obs, _ = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    layout, ladder, cost = base.observation_layout, base.ladder, base.cost
    scale = base.pricer.travel_scale
    for h in range(3):
        i = base.index + h
        rows = slice(*layout[f"slot{h}/travel_out"])
        if i + 1 < ladder.n_waypoints:
            travel = cost.travel(ladder.candidates[i][:, None], ladder.candidates[i + 1][None])
            free_after = ladder.valid[i + 1] & ~ladder.endpoint_collision[i + 1]
            both = ladder.valid[i][:, None] & free_after[None]
            least = np.where(both, travel, np.inf).min(axis=1)
            expected = np.where(np.isfinite(least), np.minimum(least / scale, 1.0), 1.0)
            np.testing.assert_allclose(obs[rows], expected.astype(np.float32), rtol=1e-6)
        if h:
            previous = cost.travel(ladder.candidates[i - 1][:, None], ladder.candidates[i][None])
            free_before = ladder.valid[i - 1] & ~ladder.endpoint_collision[i - 1]
            both = free_before[:, None] & ladder.valid[i][None]
            least = np.where(both, previous, np.inf).min(axis=0)
            expected = np.where(np.isfinite(least), np.minimum(least / scale, 1.0), 1.0)
            np.testing.assert_allclose(obs[slice(*layout[f"slot{h}/travel_in"])],
                                       expected.astype(np.float32), rtol=1e-6)


@pytest.mark.parametrize("env_id", ["IKBranch/Anthropomorphic-v2", "IKBranch/ToolTransfer-v1",
                                     "IKBranch/DualRRRPPP-v1", "IKBranch/KukaKR6-v0"])
def test_free_travel_out_is_the_cheapest_collision_free_continuation(env_id):
    # Brute force: every path from each slot-0 branch to every branch of the waypoint
    # after, checked by a separate checker (the loop backend), at every step of episodes
    # played by random valid actions.
    from ikbranch_gym.envs.models import CollisionChecker

    env = gym.make(env_id, n_waypoints=4)
    base = env.unwrapped
    rng = np.random.default_rng(0)
    checked = 0
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        loop = CollisionChecker(base.model, dof=base.arm.dof, backend="loop")
        done = False
        while not done:
            i, ladder, layout = base.index, base.ladder, base.observation_layout
            onward = obs[slice(*layout["slot0/free_travel_out"])]
            reachable = ladder.valid[i] & ~obs[slice(*layout["slot0/path_collision"])].astype(bool)
            for k in range(base.arm.n_branches):
                expected = np.inf
                if reachable[k] and i + 1 < ladder.n_waypoints:
                    ends = ladder.candidates[i + 1][ladder.valid[i + 1]]
                    free = ~loop.paths_collide(ladder.candidates[i][k], ends)
                    travel = base.cost.travel(ladder.candidates[i][k], ends)
                    expected = travel[free].min(initial=np.inf)
                    checked += 1
                value = min(expected / base.pricer.travel_scale, 1.0)
                assert onward[k] == np.float32(value), (seed, i, k)
            masks = base.action_masks()
            obs, _, done, _, _ = env.step(int(rng.choice(np.flatnonzero(masks))))
    assert checked > 10


@pytest.mark.parametrize(("env_id", "moves"), [
    ("IKBranch/Anthropomorphic-v4", 3), ("IKBranch/KukaKR6-v1", 2),
    ("IKBranch/ToolTransfer-v2", 2), ("IKBranch/DualRRRPPP-v2", 3)])
def test_free_travel_onward_is_the_cheapest_way_on_over_several_moves(env_id, moves):
    # Brute force: every path of the next moves, each checked by a separate checker (the
    # loop backend), at every step of episodes played by random valid actions; the one-move
    # free travel beside it is unchanged. Anthropomorphic-v4's task 28 meets a trap.
    from ikbranch_gym.envs.models import CollisionChecker

    env = gym.make(env_id, n_waypoints=5, onward_moves=moves)
    base = env.unwrapped
    layout, scale = base.observation_layout, base.pricer.travel_scale
    blocked = 0
    for seed in (0, 1, 28):
        rng = np.random.default_rng(seed)
        obs, _ = env.reset(seed=seed)
        loop = CollisionChecker(base.model, dof=base.arm.dof, backend="loop")
        done = False
        while not done:
            onward = obs[slice(*layout["slot0/free_travel_onward"])]
            several = least_onward_travel(base, moves, loop.paths_collide)
            one = least_onward_travel(base, 1, loop.paths_collide)
            # Exact before rounding: the same sums, in the same order, as enumeration's.
            raw_one, raw_several = raw_onward(base)
            np.testing.assert_array_equal(raw_several, several)
            np.testing.assert_array_equal(raw_one, one)
            np.testing.assert_array_equal(
                onward, np.minimum(several / (moves * scale), 1.0).astype(np.float32))
            np.testing.assert_array_equal(obs[slice(*layout["slot0/free_travel_out"])],
                                          np.minimum(one / scale, 1.0).astype(np.float32))
            blocked += int((np.isinf(several) & np.isfinite(one)).sum())
            obs, _, done, _, _ = env.step(int(rng.choice(np.flatnonzero(base.action_masks()))))
    if env_id == "IKBranch/Anthropomorphic-v4":  # a trap: free one move on, blocked after
        assert blocked


@pytest.mark.parametrize(("env_id", "checked"), [("IKBranch/KukaKR6-v1", 3),
                                                 ("IKBranch/UR5e-v2", 8)])
def test_checked_moves_are_those_of_least_travel_until_so_many_are_free(env_id, checked):
    # Enumeration by a separate checker (the loop backend): the masked moves in order of
    # least travel (ties: the lower branch) are checked until `checked` are free; those
    # read their verdict, the others 1, and so do the onward values from them, which are
    # otherwise the values of the env that checks every move. Played side by side with
    # that env on the same random valid actions (half of them, where there is one, a free
    # move left unchecked),
    # every reward, flag and info is the same, also where the move taken was left
    # unchecked, free or colliding.
    from ikbranch_gym.envs.models import CollisionChecker

    every = gym.make(env_id, n_waypoints=4)
    some = gym.make(env_id, n_waypoints=4, checked_moves=checked)
    base = some.unwrapped
    layout = base.observation_layout
    path = slice(*layout["slot0/path_collision"])
    onward = [slice(*layout[name]) for name in ("slot0/free_travel_out",
                                                "slot0/free_travel_onward") if name in layout]
    left_unchecked, taken = 0, {True: 0, False: 0}  # unchecked moves taken, by verdict
    for seed in range(3):
        rng = np.random.default_rng(seed)
        full, full_info = every.reset(seed=seed)
        obs, info = some.reset(seed=seed)
        assert same_info(info, full_info)
        loop = CollisionChecker(base.model, dof=base.arm.dof, backend="loop")
        done = False
        while not done:
            i, ladder = base.index, base.ladder
            # Outside the mask 0, as with every move checked.
            expected = np.zeros(base.arm.n_branches, dtype=np.float32)
            allowed = np.flatnonzero(base.action_masks())
            known = np.zeros(base.arm.n_branches, dtype=bool)  # checked and free
            left = np.zeros(base.arm.n_branches, dtype=bool)  # not checked
            if i == 0 and ladder.task.free_start:  # the arm starts in the branch it picks
                expected[allowed] = ladder.endpoint_collision[0, allowed]
            else:
                order = allowed[np.argsort(base.cost.travel(base.q, ladder.candidates[i][allowed]),
                                           kind="stable")]
                hits = loop.paths_collide(base.q, ladder.candidates[i][order])
                count = np.searchsorted(np.cumsum(~hits), checked) + 1
                expected[order] = 1.0
                expected[order[:count]] = hits[:count]
                left[order[count:]] = True
                left_unchecked += int(left.sum())
            np.testing.assert_array_equal(obs[path], expected)
            known[allowed] = expected[allowed] == 0
            np.testing.assert_array_equal(obs[path][known], full[path][known])
            for part in onward:
                np.testing.assert_array_equal(obs[part], np.where(known, full[part], 1.0))
            unchecked = np.flatnonzero(left & (full[path] == 0))
            if len(unchecked) and rng.random() < 0.5:  # a free move the env left unchecked
                action = int(rng.choice(unchecked))
            else:
                action = int(rng.choice(allowed))
            if left[action]:
                taken[bool(full[path][action])] += 1
            full, full_reward, full_done, _, full_info = every.step(action)
            obs, reward, done, _, info = some.step(action)
            assert (reward, done) == (full_reward, full_done) and same_info(info, full_info)
    assert left_unchecked and taken[True] and taken[False]


def test_checked_moves_bad_values_are_refused():
    for bad in (0, -1, 1.5, True, "8"):
        with pytest.raises(ValueError, match="checked_moves"):
            gym.make("IKBranch/ToolTransfer-v2", checked_moves=bad)


def test_onward_moves_shape_the_layout_and_bad_values_are_refused():
    one = gym.make("IKBranch/ToolTransfer-v2").unwrapped
    three = gym.make("IKBranch/ToolTransfer-v2", onward_moves=3).unwrapped
    assert "slot0/free_travel_onward" not in one.observation_layout
    start, stop = three.observation_layout["slot0/free_travel_onward"]
    assert stop - start == three.arm.n_branches
    assert three.observation_space.shape[0] == one.observation_space.shape[0] + (stop - start)
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="onward_moves"):
            gym.make("IKBranch/ToolTransfer-v2", onward_moves=bad)
    with pytest.raises(ValueError, match="onward_moves=2 needs observation='compact'"):
        gym.make("IKBranch/ToolTransfer-v0", onward_moves=2)


def test_ids_with_models_trained_on_the_ladder_layout_keep_it():
    # The single-seed results (docs/results/*.json) were trained on the ladder layout, and
    # tests/train/test_results.py plays those models on these ids.
    legacy = {"Cartesian-v1", "Cylindrical-v1", "Spherical-v1", "Anthropomorphic-v1",
              "Cylindrical4-v1", "ToolTransfer-v0", "DualRRPRPP-v0", "DualRRRPPP-v0",
              "DualPPRPRR-v0", "RodMechanism-v1"}
    for env_id, kwargs in envs.ENV_SPECS.items():
        ladder = kwargs["observation"] == "ladder"
        assert ladder == (env_id.split("/")[1] in legacy), env_id
        if ladder:
            assert "slot1/travel" in gym.make(env_id).unwrapped.observation_layout


def test_unknown_layout_is_refused():
    with pytest.raises(ValueError, match="observation"):
        gym.make("IKBranch/ToolTransfer-v0", observation="dense")


@pytest.mark.parametrize("kind", OBSERVATIONS)
def test_a_task_met_again_takes_its_templates_from_the_cache(kind, monkeypatch):
    # The milling cell's tool changes come from a finite set: from its second sighting a
    # task's templates come from the cache (they depend on its candidates, validity and
    # endpoint hits only).
    env = gym.make("IKBranch/ToolTransfer-v0", observation=kind)
    base = env.unwrapped
    builder = base._observations
    env.reset(seed=3)
    ladder = base.ladder
    first = builder.templates(ladder)  # its second sighting (reset was the first): kept
    np.testing.assert_array_equal(first, builder._assemble(ladder))
    np.testing.assert_array_equal(base._episode.templates[0], first)
    assert not first.flags.writeable and len(builder._cache) == 1
    kept = builder.templates(ladder)
    assert kept is first and len(builder._cache) == 1
    # Past its bound the cache starts afresh (here: room for one task).
    monkeypatch.setattr("ikbranch_gym.envs.observations.TEMPLATE_CACHE_BYTES", first.nbytes)
    seed = 4
    while np.array_equal(base.ladder.candidates, ladder.candidates):
        env.reset(seed=seed)
        seed += 1
    builder.templates(base.ladder)  # the other task, met a second time: kept, the first dropped
    assert len(builder._cache) == 1
    again = builder.templates(ladder)
    assert again is not kept
    np.testing.assert_array_equal(again, first)


def test_a_task_seen_once_is_not_kept():
    env = gym.make("IKBranch/ToolTransfer-v0")
    env.reset(seed=3)
    builder = env.unwrapped._observations
    assert not builder._cache and len(builder._sighted) == 1


def test_tasks_that_never_repeat_fill_no_template_cache():
    env = gym.make("IKBranch/Cartesian-v2")
    for seed in range(30):
        env.reset(seed=seed)
    builder = env.unwrapped._observations
    assert not builder._cache and len(builder._sighted) == 30


@pytest.mark.parametrize("env_id", IDS)
def test_travel_summaries_are_the_priced_travel(env_id):
    # Bit for bit the travel step pays (envs.moves._price), least over the free branches;
    # a move that step prices as invalid (one reconfiguring the arm inside a process
    # segment) is no move.
    from ikbranch_gym.envs.observations import _travel_summaries

    env = gym.make(env_id, n_waypoints=4)
    env.reset(seed=5)
    ladder, scale = env.unwrapped.ladder, float(env.unwrapped.pricer.travel_scale)
    n, k = ladder.valid.shape
    free = ladder.valid & ~ladder.endpoint_collision
    leaving, arriving = np.empty((n, k)), np.empty((n, k))
    _travel_summaries(ladder.candidates, ladder.valid, free, ladder.pricer.cost.weights, scale,
                      ladder.inside, ladder.configuration, float(ladder.limit),
                      ladder.revolute, leaving, arriving)
    expected_out, expected_in = np.ones((n, k)), np.ones((n, k))
    for i in range(n - 1):
        here = ladder.candidates[i]
        terms = ladder.terms(here, i + 1, collision=np.zeros((k, k), dtype=bool))
        travel = np.where(terms["invalid"], np.inf, terms["travel"])
        out = np.where(ladder.valid[i][:, None] & free[i + 1][None], travel, np.inf)
        into = np.where(free[i][:, None] & ladder.valid[i + 1][None], travel, np.inf)
        expected_out[i] = np.minimum(out.min(axis=1) / scale, 1.0)
        expected_in[i + 1] = np.minimum(into.min(axis=0) / scale, 1.0)
    np.testing.assert_array_equal(leaving, expected_out)
    np.testing.assert_array_equal(arriving, expected_in)


@pytest.mark.parametrize("env_id", ["IKBranch/UR5e-v0", "IKBranch/UR5e-v4",
                                    "IKBranch/KukaKR6-v0", "IKBranch/IRB2600Screwing-v0"])
def test_factored_travel_summaries_are_the_general_ones(env_id):
    # An arm's turn branches factor its ladder (closed-form branch × turn windows): the
    # least travel taken over the factors is the least over every pair, bit for bit.
    from ikbranch_gym.envs.observations import (
        _travel_summaries,
        _turn_tables,
        _turned_travel_summaries,
    )

    env = gym.make(env_id, n_waypoints=4)
    base = env.unwrapped
    arm = base.arm
    turned = np.array([joint for joint, _ in arm.turn_windows], dtype=np.int64)
    factors = (np.ascontiguousarray(arm.branch_closed_form, dtype=np.int64), turned,
               np.ascontiguousarray(arm.branch_turns, dtype=np.int64), arm.n_closed_form,
               max(len(windows) for _, windows in arm.turn_windows))
    for seed in range(6):
        env.reset(seed=seed)
        ladder = base.ladder
        n, k = ladder.valid.shape
        scale, weights = float(base.pricer.travel_scale), ladder.pricer.cost.weights
        expected, factored = [np.empty((n, k)), np.empty((n, k))], [np.empty((n, k)),
                                                                    np.empty((n, k))]
        _travel_summaries(ladder.candidates, ladder.valid,
                          ladder.valid & ~ladder.endpoint_collision, weights, scale,
                          ladder.inside, ladder.configuration, float(ladder.limit),
                          ladder.revolute, *expected)
        tables = _turn_tables(ladder.candidates, ladder.valid, ladder.endpoint_collision,
                              *factors)
        assert tables[0]  # the ladder is the product of its factors
        _turned_travel_summaries(ladder.valid, tables, factors[0], turned, factors[2], weights,
                                 scale, *factored)
        np.testing.assert_array_equal(factored[0], expected[0])
        np.testing.assert_array_equal(factored[1], expected[1])
    # A ladder that is not a product (a turn copy moved) is recognised: the general kernel.
    closed = arm.branch_closed_form
    waypoint, copy = next((i, b) for i in range(n) for b in range(k) if ladder.valid[i, b]
                          and (ladder.valid[i] & (closed == closed[b])).sum() > 1)
    joint = next(j for j in range(arm.dof) if j not in turned)
    candidates = ladder.candidates.copy()
    candidates[waypoint, copy, joint] += 1e-9
    assert not _turn_tables(candidates, ladder.valid, ladder.endpoint_collision, *factors)[0]


def test_an_arm_with_hundreds_of_branches_sums_its_factors():
    from ikbranch_gym.envs.observations import FACTORED_BRANCHES

    assert gym.make("IKBranch/UR5e-v0").unwrapped._observations._turns is not None
    assert gym.make("IKBranch/KukaKR6-v0").unwrapped.arm.n_branches < FACTORED_BRANCHES
    assert gym.make("IKBranch/KukaKR6-v0").unwrapped._observations._turns is None


def _numpy_compact_templates(builder, ladder, leaving, arriving):
    """The compact templates assembled slice by slice with NumPy, as the module docstring
    lays them out: the reference of the compiled assembly."""
    n, k, dof = ladder.n_waypoints, builder.arm.n_branches, builder.arm.dof
    valid = ladder.valid
    candidates = np.where(valid[..., None], ladder.candidates, builder._centre)
    common = np.concatenate([np.ones((n, 1)), builder.normalise(candidates).reshape(n, k * dof),
                             valid, ladder.endpoint_collision], axis=1)
    templates = np.zeros((n + 1, builder.size))
    templates[:, slice(*builder.layout["progress"])] = np.arange(n + 1)[:, None] / n
    for h in range(min(builder.lookahead, n - 1) + 1):
        start = builder.layout[f"slot{h}/present"][0]
        templates[: n - h, start : start + common.shape[1]] = common[h:]
        templates[: n - h, slice(*builder.layout[f"slot{h}/travel_out"])] = leaving[h:]
        if h:
            templates[: n - h, slice(*builder.layout[f"slot{h}/travel_in"])] = arriving[h:]
    return np.clip(templates, -1.0, 1.0).astype(np.float32)


@pytest.mark.parametrize("env_id", ["IKBranch/UR5e-v3", "IKBranch/KukaKR6-v2",
                                    "IKBranch/Anthropomorphic-v4", "IKBranch/ToolTransfer-v2",
                                    "IKBranch/DualRRPRPP-v2"])
@pytest.mark.parametrize("lookahead", [0, 2, 5])
def test_compiled_compact_templates_are_the_numpy_assembly(env_id, lookahead):
    # Bit for bit, with lookaheads reaching past the task's end (n_waypoints=4).
    env = gym.make(env_id, lookahead=lookahead, n_waypoints=4)
    base = env.unwrapped
    builder = base._observations
    for seed in range(3):
        env.reset(seed=seed)
        ladder = base.ladder
        leaving, arriving = builder._travel_summaries(ladder)
        expected = _numpy_compact_templates(builder, ladder, leaving, arriving)
        assembled = builder._assemble(ladder)
        assert assembled.dtype == np.float32
        np.testing.assert_array_equal(assembled.view(np.uint32), expected.view(np.uint32))
        np.testing.assert_array_equal(base._episode.templates[0], assembled)


def test_the_ladder_layouts_travel_reads_a_move_a_segment_blocks_as_no_move():
    """Inside a deburring pass (``max_joint_step`` 30°) the ladder layout's K × K travel
    reads 1 for a move that changes the closed-form branch or steps a joint by more than
    the limit (here brute force), as for an invalid branch, and the priced travel for
    every other move between valid branches."""
    env = gym.make("IKBranch/KukaKR6Deburring-v1", observation="ladder", lookahead=1)
    base = env.unwrapped
    obs, _ = env.reset(seed=0)
    ladder, layout, k = base.ladder, base.observation_layout, base.arm.n_branches
    i = base.index + 1  # slot 1's waypoint: the move into it lies inside the pass
    assert ladder.inside[i]
    q0, q1 = ladder.candidates[i - 1], ladder.candidates[i]
    closed = np.asarray(base.arm.branch_closed_form)
    revolute = np.asarray(base.arm.revolute_mask)
    steps = np.abs(q1[None, :, :] - q0[:, None, :])[..., revolute].max(axis=-1)
    reconfigures = (closed[:, None] != closed[None, :]) | (steps > ladder.limit)
    both = ladder.valid[i - 1][:, None] & ladder.valid[i][None, :]
    assert reconfigures[both].any() and (~reconfigures)[both].any()
    travel = base.cost.travel(q0[:, None], q1[None]) / base.pricer.travel_scale
    expected = np.where(both & ~reconfigures, np.minimum(travel, 1.0), 1.0)
    np.testing.assert_allclose(obs[slice(*layout["slot1/travel"])].reshape(k, k),
                               expected.astype(np.float32), rtol=1e-6)


def test_templates_of_equal_arrays_under_other_continuity_are_not_shared():
    """The templates' cache key holds the process continuity too: the same arrays without
    a segment (every move allowed) read other travel summaries than the deburring pass's,
    and take their own templates, not the pass's from the cache."""
    env = gym.make("IKBranch/KukaKR6Deburring-v1")
    base = env.unwrapped
    env.reset(seed=0)
    ladder, builder = base.ladder, base._observations
    assert ladder.inside.any()
    restricted = builder.templates(ladder)
    assert builder.templates(ladder) is restricted  # met twice: in the cache
    free = TaskMoves(base.pricer, ladder.task, ladder.candidates, ladder.valid,
                     ladder.endpoint_collision, None)
    assert free.fingerprint == ladder.fingerprint
    unrestricted = builder.templates(free)
    np.testing.assert_array_equal(unrestricted, builder._assemble(free))
    assert not np.array_equal(unrestricted, restricted)
