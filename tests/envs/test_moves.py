"""The pricing of moves (``envs/moves.py``): one definition, whatever the batch shape."""

from __future__ import annotations

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics.singularities import singularity_margins
from ikbranch_gym.envs.moves import REWARD_TERMS, TaskMoves
from ikbranch_gym.envs.process import UNKNOWN, blocked
from tests.envs.env_cases import IDS, make


def _ladder(env_id: str, seed: int = 0, **kwargs) -> TaskMoves:
    env = make(env_id, time_weight=0.4, n_waypoints=4, **kwargs)
    env.reset(seed=seed)
    return env.unwrapped.ladder


@pytest.mark.parametrize("env_id", IDS)
def test_stacked_prices_equal_each_waypoints_edges(env_id):
    # The lazy planner prices all waypoints in one call; step and edge_rewards one
    # waypoint at a time. Same moves, same bits.
    ladder = _ladder(env_id)
    n, k = ladder.valid.shape
    origins, usable = ladder.stacked_origins()
    collision = np.zeros((n, k, k), dtype=bool)
    for w in range(n):
        rows, exists = ladder.origins(w)
        collision[w, : len(rows)][exists] = ladder.collisions(rows[exists], w)
    stacked = ladder.terms(origins, np.arange(n), collision=collision)
    for w in range(n):
        reward, terminal = ladder.edges(w)
        rows = usable[w] if w else usable[0, :1]
        np.testing.assert_array_equal(stacked["reward"][w][: len(reward)][rows], reward[rows])
        np.testing.assert_array_equal(stacked["terminal"][w][: len(reward)][rows],
                                      terminal[rows])


@pytest.mark.parametrize("env_id", IDS)
def test_onward_travel_is_the_priced_travel(env_id):
    # least_free_travel ranks onward moves by a travel-only kernel: bit for bit the
    # travel that step pays, inf off the targets in the rows asked for, and the rows not
    # asked for left as they were (nothing reads them).
    from ikbranch_gym.envs.moves import _onward_travel

    ladder = _ladder(env_id, seed=2)
    k = ladder.valid.shape[1]
    rng = np.random.default_rng(3)
    for w in range(ladder.n_waypoints - 1):
        here = ladder.candidates[w]
        priced, _ = ladder.motion(here, w + 1)
        rows = ladder.valid[w] & (rng.random(k) < 0.7)
        targets = ladder.valid[w + 1] & (rng.random(k) < 0.7)
        out, asked = np.full((1, k, k), -1.0), rows[None].copy()
        _onward_travel(here[None], ladder.candidates[w + 1][None], asked, targets[None],
                       ladder.pricer.cost.weights, out)
        # A move reconfiguring the arm inside a process segment is priced as an invalid
        # branch (no motion); the searches leave it out apart (_block_moves_from).
        moves = ~ladder.terms(here, w + 1, collision=np.zeros((k, k), dtype=bool))["invalid"]
        both = rows[:, None] & targets[None] & moves
        np.testing.assert_array_equal(out[0][both], priced[both])
        assert np.isposinf(out[0][rows[:, None] & ~targets[None]]).all()
        assert (out[0][~rows] == -1.0).all()
        np.testing.assert_array_equal(asked[0], rows & targets.any())


@pytest.mark.parametrize("env_id", IDS)
def test_reward_is_the_sum_of_its_terms_and_travel_is_the_cost_models(env_id):
    ladder = _ladder(env_id, seed=1)
    rng = np.random.default_rng(0)
    arm = ladder.pricer.arm
    origins = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(5, arm.dof))
    for w in range(ladder.n_waypoints):
        collision = rng.random((5, arm.n_branches)) < 0.3
        terms = ladder.terms(origins, w, collision=collision)
        total = np.zeros_like(terms["reward"])
        for name in REWARD_TERMS:
            total = total + terms[name]
        np.testing.assert_array_equal(terms["reward"], total)
        valid = ladder.valid[w]
        # Invalid: the branch, or a move reconfiguring the arm inside a process segment
        # (from a configuration of unknown branch only the step limit applies), which
        # does not move and so collides with nothing.
        reconfigures = (blocked(origins, np.full(len(origins), UNKNOWN), ladder.candidates[w],
                                ladder.configuration, ladder.limit, ladder.revolute)
                        if ladder.inside[w] else np.zeros(total.shape, dtype=bool))
        np.testing.assert_array_equal(terms["collision"], collision & ~reconfigures)
        np.testing.assert_array_equal(terms["invalid"], ~valid[None] | reconfigures)
        cost = ladder.pricer.cost
        if w == 0 and ladder.task.free_start:
            assert (terms["travel"] == 0).all() and (terms["time"] == 0).all()
        else:
            # TransitionCost (numpy) and the kernel agree to the last bit.
            moves = valid[None] & ~reconfigures
            expected = np.broadcast_to(ladder.candidates[w][None], (*moves.shape, arm.dof))
            origin = np.broadcast_to(origins[:, None], expected.shape)
            np.testing.assert_array_equal(terms["travel"][moves],
                                          cost.travel(origin[moves], expected[moves]))
            np.testing.assert_array_equal(terms["time"][moves],
                                          cost.time(origin[moves], expected[moves]))
            assert (terms["travel"][~moves] == 0).all()


def test_caches_answer_as_the_checker_and_keep_their_bounds():
    env = make("IKBranch/Anthropomorphic-v1")
    env.reset(seed=0)
    pricer = env.unwrapped.pricer
    arm = pricer.arm
    rng = np.random.default_rng(1)
    q0, q1 = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(2, 60, arm.dof))
    expected = pricer.checker.paths_collide(q0, q1)
    np.testing.assert_array_equal(pricer.paths_collide(q0, q1), expected)
    np.testing.assert_array_equal(pricer.paths_collide(q0, q1), expected)  # cached now
    np.testing.assert_array_equal(pricer.is_path_free(q0, q1), ~expected)
    np.testing.assert_array_equal(pricer.paths_collide(q0[0], q1),
                                  pricer.checker.paths_collide(q0[0], q1))
    np.testing.assert_array_equal(pricer.configurations_collide(q0),
                                  pricer.checker.collides(q0))
    # The generators' sampling: the first ``need`` free rows, later ones False unchecked.
    free = ~pricer.checker.collides(q1)
    for need in (1, 3, int(free.sum())):
        mask = pricer.is_free(q1 + 0.5 * np.sign(-q1), need=need)  # fresh rows: misses
        expected_rows = np.flatnonzero(~pricer.checker.collides(q1 + 0.5 * np.sign(-q1)))[:need]
        np.testing.assert_array_equal(np.flatnonzero(mask), expected_rows)
    np.testing.assert_array_equal(pricer.is_free(q1, need=2),  # some cached, some not
                                  np.isin(np.arange(len(q1)), np.flatnonzero(free)[:2]))
    pricer.configurations_collide(q1[:5])
    np.testing.assert_array_equal(pricer.is_free(q1, need=2),
                                  np.isin(np.arange(len(q1)), np.flatnonzero(free)[:2]))
    pricer.paths.bound = 10
    pricer.paths_collide(q0[:8] + 0.01, q1[:8])
    assert len(pricer.paths) == 8  # full: cleared, then this call's misses stored
    with pytest.raises(ValueError, match="finite"):
        pricer.paths_collide(q0[0], np.full((2, arm.dof), np.nan))
    with pytest.raises(ValueError, match="finite"):
        pricer.is_free(np.full((1, arm.dof), np.inf))


def test_generators_build_on_configurations_free_and_outside_the_margins():
    """``is_workable``, the predicate the generators get: without margins the pricer's
    ``is_free`` itself; with them, free rows whose wrist and elbow lie at least the margin
    from singular (computed here from ``singularity_margins``), ``need`` counted among
    those."""
    margin = np.radians(40.0)
    pricer = make("IKBranch/KukaKR6Deburring-v1", singularity_margin=margin).unwrapped.pricer
    arm = pricer.arm
    rng = np.random.default_rng(7)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(400, arm.dof))
    margins = singularity_margins(arm, q)
    free = ~pricer.checker.collides(q)
    plain = make("IKBranch/KukaKR6Deburring-v1").unwrapped.pricer
    np.testing.assert_array_equal(plain.is_workable(q, need=5),
                                  np.isin(np.arange(len(q)), np.flatnonzero(free)[:5]))
    np.testing.assert_array_equal(plain.is_workable(q), free)
    expected = free & (margins.wrist >= margin) & (margins.elbow >= margin)
    assert 0 < expected.sum() < free.sum()  # the margins leave free rows out
    for need in (1, 5, int(expected.sum())):
        fresh = make("IKBranch/KukaKR6Deburring-v1",
                     singularity_margin=margin).unwrapped.pricer
        np.testing.assert_array_equal(np.flatnonzero(fresh.is_workable(q, need=need)),
                                      np.flatnonzero(expected)[:need])
    np.testing.assert_array_equal(pricer.is_workable(q), expected)
    with pytest.raises(ValueError, match="finite"):
        pricer.is_workable(np.full((1, arm.dof), np.nan))


def test_a_task_met_again_takes_its_ladder_from_the_cache():
    """Tool changes repeat their poses: the second ladder of a pose sequence holds the
    first's arrays, equal to what a pricer that never met it solves; a new scene (or a
    full cache) forgets them; the env hands them out read-only."""
    env = make("IKBranch/ToolTransfer-v2").unwrapped
    fresh = make("IKBranch/ToolTransfer-v2").unwrapped
    fresh.reset(seed=0)
    met: dict[bytes, TaskMoves] = {}
    repeated = 0
    for seed in range(40):
        env.reset(seed=seed)
        ladder = env.ladder
        key = ladder.task.poses.tobytes()
        if key in met:
            repeated += 1
            assert ladder.candidates is met[key].candidates
            assert ladder.fingerprint is met[key].fingerprint
        met[key] = ladder
        fresh.pricer.clear_caches()
        solved = fresh.pricer.task(ladder.task)
        np.testing.assert_array_equal(ladder.candidates, solved.candidates)
        np.testing.assert_array_equal(ladder.valid, solved.valid)
        np.testing.assert_array_equal(ladder.endpoint_collision, solved.endpoint_collision)
        assert ladder.fingerprint == (solved.candidates.tobytes(), solved.valid.tobytes(),
                                      solved.endpoint_collision.tobytes())
    assert repeated > 10
    pricer = env.pricer
    assert pricer.ladders
    with pytest.raises(ValueError, match="read-only"):
        env.candidates[0, 0, 0] = 0.0
    pricer.clear_caches()
    assert not pricer.ladders
    again = pricer.task(env.task)
    assert again.candidates is not env.ladder.candidates
    np.testing.assert_array_equal(again.candidates, env.ladder.candidates)


def test_waypoints_outside_the_task_are_refused():
    ladder = _ladder("IKBranch/Cartesian-v1")
    with pytest.raises(ValueError, match="waypoint"):
        ladder.edges(ladder.n_waypoints)
    with pytest.raises(ValueError, match="waypoint"):
        ladder.terms(ladder.candidates[0], np.array([0, -1]))


def test_next_targets_follow_a_stable_sort_of_each_row():
    # The onward search takes targets cheapest first, ties by index: a scan per round
    # gives the order a stable argsort of the row gives.
    from ikbranch_gym.envs.moves import _next_targets

    rng = np.random.default_rng(4)
    travel = np.round(rng.uniform(0, 3, size=(2, 5, 9)), 1)  # many ties
    travel[travel > 2.6] = np.inf
    for line in range(2):
        for row in range(5):
            order = [int(b) for b in np.argsort(travel[line, row], kind="stable")
                     if np.isfinite(travel[line, row, b])]
            last = np.full((2, 5), -1, dtype=np.int64)
            seen = []
            while True:
                column = np.empty(1, dtype=np.int64)
                _next_targets(np.array([line]), np.array([row]), travel, last, column)
                if column[0] < 0:
                    break
                seen.append(int(column[0]))
                last[line, row] = column[0]
            assert seen == order


@pytest.mark.parametrize("env_id", ["IKBranch/UR5e-v0", "IKBranch/KukaKR6-v0",
                                    "IKBranch/IRB4600ToolTransfer-v0"])
def test_turn_copies_share_their_endpoint_checks_with_the_same_verdicts(env_id):
    # One check per closed-form branch (its turn copies place every link alike): the
    # verdict of every copy is the loop backend's, configuration by configuration.
    from ikbranch_gym.envs.models import CollisionChecker

    env = make(env_id, n_waypoints=4)
    base = env.unwrapped
    checked = 0
    for seed in range(4):
        env.reset(seed=seed)  # (a clutter laid: the reference copies the model after it)
        loop = CollisionChecker(base.checker.model, dof=base.arm.dof, backend="loop")
        ladder = base.ladder
        valid = ladder.valid
        expected = np.zeros(valid.shape, dtype=bool)
        expected[valid] = loop.collides(ladder.candidates[valid])
        np.testing.assert_array_equal(ladder.endpoint_collision, expected)
        checked += int(valid.sum())
    assert checked > 20
