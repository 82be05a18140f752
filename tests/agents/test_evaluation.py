"""``agents.evaluation``: any policy (callables, factories, SB3 model objects), env
factories and wrappers, masks taken through the wrappers, and the two gaps."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy.stats import trim_mean

import ikbranch_gym.envs  # noqa: F401
from ikbranch_gym.agents import make_baseline
from ikbranch_gym.agents.base import action_mask
from ikbranch_gym.agents.evaluation import as_policy, evaluate, gaps, iqm, with_gaps

ENV = "IKBranch/RodMechanism-v1"  # 4 branches, about half of them masked at a waypoint
KWARGS = {"n_waypoints": 5}
EPISODES, SEED = 3, 7


def without_timing(results: dict) -> dict:
    return {name: {k: v for k, v in m.items() if k != "decision_ms"}
            for name, m in results["policies"].items()}


def first_valid(obs, mask):
    return int(np.flatnonzero(mask)[0])


def hand_played_first_valid(seed: int) -> float:
    """The return of 'the first allowed branch' on task ``seed``, played without
    ``agents.evaluation``: the env's own info["action_mask"]."""
    env = gym.make(ENV, **KWARGS)
    _, info = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        _, reward, done, _, info = env.step(int(np.flatnonzero(info["action_mask"])[0]))
        total += reward
    return total


# ----------------------------------------------------------------------------- gaps
def test_the_gaps_of_hand_computed_returns():
    oracle = [-10.0, -20.0, 0.0, -5.0, -8.0]
    policy = [-11.0, -20.0, -1.0, -10.0, -8.0]
    measured = gaps(policy, oracle)
    # mean gap: oracle mean −8.6, policy mean −10: 1.4 / 8.6.
    assert measured["mean_gap"] == pytest.approx(1.4 / 8.6)
    # IQM gap: task 3 (oracle 0) left out; per task 0.1, 0, 1.0, 0 -> sorted 0, 0, 0.1, 1.0,
    # the lowest and highest quarter (one each) dropped: mean of 0 and 0.1.
    assert measured["iqm_gap"] == pytest.approx(0.05)
    assert measured["iqm_gap_skipped"] == 1


def test_gaps_without_a_scale_are_none_or_zero():
    assert gaps([0.0, 0.0], [0.0, 0.0]) == {"mean_gap": 0.0, "iqm_gap": None,
                                             "iqm_gap_skipped": 2}
    # Oracle mean 0 (one task above, one below) and a policy that differs: no mean gap,
    # but both tasks have a scale of their own.
    measured = gaps([-2.0, 1.0], [-1.0, 1.0])
    assert measured["mean_gap"] is None
    assert measured["iqm_gap"] == pytest.approx(0.5)  # per task 1.0 and 0.0, none trimmed
    with pytest.raises(ValueError, match="same tasks"):
        gaps([1.0, 2.0], [1.0])


@pytest.mark.parametrize("shape", [(1,), (2,), (3,), (4,), (5,), (7,), (8,), (13,), (50,),
                                   (3, 20), (5, 200), (10, 1)])
def test_iqm_is_rliables_to_the_bit(shape):
    from rliable import metrics

    rng = np.random.default_rng(sum(shape))
    values = rng.normal(size=shape) ** 3  # skewed: the trim matters
    values[rng.random(shape) < 0.2] = 1.0  # ties at the cuts
    assert iqm(values) == trim_mean(values.ravel(), 0.25) == metrics.aggregate_iqm(values)
    with pytest.raises(ValueError, match="no values"):
        iqm(np.empty((0, 3)))


def test_old_results_gain_both_gaps():
    old = {"episodes": 4, "policies": {
        "dp_oracle": {"optimality_gap": 0.0, "returns": [-10.0, -4.0, -2.0, -1.0]},
        "mine": {"optimality_gap": 0.1234, "returns": [-10.0, -6.0, -2.0, -3.0]},
        "no_returns": {"optimality_gap": 0.5},
    }}
    new = with_gaps(old)
    assert new["policies"]["mine"]["mean_gap"] == 0.1234  # the old key's value, unchanged
    # per task 0, 0.5, 0, 2 -> sorted 0, 0, 0.5, 2 -> IQM of 0 and 0.5
    assert new["policies"]["mine"]["iqm_gap"] == pytest.approx(0.25)
    assert new["policies"]["no_returns"]["iqm_gap"] is None
    assert "mean_gap" not in old["policies"]["mine"]  # the input is left alone


# ------------------------------------------------------------------- any kind of policy
def test_a_callable_plays_the_tasks_as_a_hand_played_loop():
    results = evaluate(ENV, [first_valid], EPISODES, SEED, KWARGS)
    assert list(results["policies"]) == ["dp_oracle", "first_valid"]
    returns = results["policies"]["first_valid"]["returns"]
    assert returns == [hand_played_first_valid(SEED + e) for e in range(EPISODES)]
    oracle = np.array(results["policies"]["dp_oracle"]["returns"])
    metrics = results["policies"]["first_valid"]
    assert metrics["mean_gap"] == pytest.approx(
        (oracle.mean() - np.mean(returns)) / abs(oracle.mean()))
    assert metrics["iqm_gap"] == pytest.approx(trim_mean((oracle - returns) / abs(oracle), 0.25))


class FirstValid:
    """A class: a factory of policies (instantiated with no argument)."""

    made = 0

    def __init__(self) -> None:
        FirstValid.made += 1

    def __call__(self, obs, mask):
        return np.int64(first_valid(obs, mask))  # any scalar np.asarray(...).item() takes


def make_first_valid():
    return first_valid


def test_factories_classes_and_names():
    FirstValid.made = 0
    results = evaluate(ENV, {"by_class": FirstValid, "by_function": make_first_valid,
                             "named": first_valid, "oracle_again": "dp_oracle"},
                       EPISODES, SEED, KWARGS)
    assert list(results["policies"]) == ["dp_oracle", "by_class", "by_function", "named",
                                         "oracle_again"]
    assert FirstValid.made == 1  # once for its env
    plays = without_timing(results)
    assert plays["by_class"] == plays["by_function"] == plays["named"]
    assert plays["oracle_again"] == plays["dp_oracle"]
    pair = evaluate(ENV, [("mine", first_valid), first_valid, first_valid], 1, SEED, KWARGS)
    assert list(pair["policies"]) == ["dp_oracle", "mine", "first_valid", "first_valid#2"]


def test_policies_that_do_not_fit_are_refused():
    env = gym.make(ENV, **KWARGS)
    with pytest.raises(ValueError, match="by its name"):
        as_policy(make_baseline("paper_rule", env), env)
    with pytest.raises(ValueError, match="not a policy"):
        as_policy(3, env, "three")
    with pytest.raises(ValueError, match="another factory"):
        as_policy(lambda: make_first_valid, env, "twice")
    with pytest.raises(ValueError, match="env factory sets its own"):
        evaluate(lambda: gym.make(ENV), [first_valid], 1, SEED, KWARGS)
    with pytest.raises(ValueError, match="2 actions"):
        evaluate(ENV, [lambda obs, mask: [0, 1]], 1, SEED, KWARGS)


@pytest.fixture(scope="module")
def maskable_model():
    from sb3_contrib import MaskablePPO

    return MaskablePPO("MlpPolicy", gym.make(ENV, **KWARGS), n_steps=16, batch_size=16, seed=0)


def test_an_sb3_model_object_plays_as_its_saved_zip(maskable_model, tmp_path):
    path = tmp_path / "model.zip"
    maskable_model.save(path)
    by_object = evaluate(ENV, [maskable_model], EPISODES, SEED, KWARGS)
    by_file = evaluate(ENV, [str(path)], EPISODES, SEED, KWARGS)
    assert list(by_object["policies"]) == ["dp_oracle", "MaskablePPO"]
    assert (without_timing(by_object)["MaskablePPO"]
            == without_timing(by_file)[str(path.with_suffix(""))])
    assert by_object["policies"]["MaskablePPO"]["invalid_rate"] == 0.0  # the masks reached it
    with pytest.raises(ValueError, match="observations of shape"):
        evaluate(ENV, [maskable_model], 1, SEED, {**KWARGS, "lookahead": 0})


def test_an_env_factory_plays_what_the_id_plays():
    by_id = evaluate(ENV, ["paper_rule"], EPISODES, SEED, KWARGS)
    by_factory = evaluate(lambda: gym.make(ENV, **KWARGS), ["paper_rule"], EPISODES, SEED)
    assert without_timing(by_factory) == without_timing(by_id)
    assert by_factory["env"] == ENV and by_factory["env_kwargs"] == {}


# ------------------------------------------------------------------------ wrappers
class Ban(gym.Wrapper):
    """Forbids branch ``banned`` wherever another branch is allowed, through
    ``action_masks()``, ``info["action_mask"]`` or both (``where``), and logs every step's
    offered branches and action."""

    def __init__(self, env, banned: int | None, log: list, where: str) -> None:
        super().__init__(env)
        self.banned, self.log, self.where = banned, log, where
        self.offered = None

    def narrowed(self, mask):
        mask = np.array(mask, dtype=bool)
        if self.banned is not None and mask[self.banned] and mask.sum() > 1:
            mask[self.banned] = False
        return mask

    def action_masks(self):
        mask = self.env.get_wrapper_attr("action_masks")()
        return self.narrowed(mask) if self.where in ("method", "both") else mask

    def _seen(self, info):
        self.offered = self.narrowed(info["action_mask"])
        if self.where in ("info", "both"):
            info = {**info, "action_mask": self.offered}
        return info

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return obs, self._seen(info)

    def step(self, action):
        self.log.append((self.offered.copy(), int(action)))
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, self._seen(info)


POLICIES = ["dp_oracle", "paper_rule", "paper_pair_rule", "receding_dp", "random", "fixed:0"]


def logged(wrapper, policies, episodes=6) -> list:
    log: list = []
    evaluate(ENV, policies, episodes, SEED, KWARGS, wrappers=[lambda env: wrapper(env, log)])
    return log


@pytest.mark.parametrize("where", ["method", "info", "both"])
def test_a_wrapper_that_bans_a_branch_is_obeyed_by_every_policy(where, maskable_model):
    choices = [first_valid, maskable_model, *POLICIES]
    # Without a ban the policies choose the banned branch (the most chosen one) on some
    # steps where another was allowed, so the ban is a real constraint.
    free = logged(lambda env, log: Ban(env, None, log, "none"), choices)
    chosen = np.bincount([action for offered, action in free if offered.sum() > 1],
                         minlength=4)
    banned = int(np.argmax(chosen))
    assert chosen[banned] > 0
    log = logged(lambda env, log: Ban(env, banned, log, where), choices)
    assert all(offered[action] for offered, action in log)
    assert all(offered.sum() == 1 for offered, action in log if action == banned)


def test_masks_come_through_the_wrappers():
    env = gym.make(ENV, **KWARGS)
    _, info = env.reset(seed=SEED)
    np.testing.assert_array_equal(action_mask(env, info), info["action_mask"])
    np.testing.assert_array_equal(action_mask(env), env.unwrapped.action_masks())
    log: list = []
    wrapped = Ban(env, int(np.flatnonzero(info["action_mask"])[0]), log, "method")
    _, info = wrapped.reset(seed=SEED)
    allowed = np.flatnonzero(info["action_mask"])
    assert len(allowed) > 1  # the ban bites on this task
    expected = info["action_mask"].copy()
    expected[allowed[0]] = False
    np.testing.assert_array_equal(action_mask(wrapped), expected)
    np.testing.assert_array_equal(action_mask(wrapped, info), expected)
    # An env with neither: None; an info of its own: that.
    plain = gym.make("CartPole-v1")
    assert action_mask(plain) is None
    np.testing.assert_array_equal(action_mask(plain, {"action_mask": [True, False]}),
                                  [True, False])
    with pytest.raises(ValueError, match="shape"):
        action_mask(env, {"action_mask": np.ones(3, dtype=bool)})


def test_reward_and_observation_wrappers_apply_to_every_row():
    plain = evaluate(ENV, ["paper_rule", first_valid], EPISODES, SEED, KWARGS)
    doubled = evaluate(ENV, ["paper_rule", first_valid], EPISODES, SEED, KWARGS,
                       wrappers=[lambda env: gym.wrappers.TransformReward(env, lambda r: 2 * r)])
    for name, metrics in plain["policies"].items():
        assert doubled["policies"][name]["returns"] == [2 * r for r in metrics["returns"]]
        assert doubled["policies"][name]["mean_gap"] == pytest.approx(metrics["mean_gap"])
    # Stacked observations (2, size): the baselines read the shape of the wrapped env.
    stacked = evaluate(ENV, ["paper_rule"], EPISODES, SEED, KWARGS,
                       wrappers=[gym.wrappers.RecordEpisodeStatistics,
                                 lambda env: gym.wrappers.FrameStackObservation(env, 2)])
    assert without_timing(stacked)["paper_rule"] == without_timing(plain)["paper_rule"]
    assert stacked["wrappers"][0] == "RecordEpisodeStatistics"
    with pytest.raises(ValueError, match="not an env"):
        evaluate(ENV, ["paper_rule"], 1, SEED, KWARGS, wrappers=[lambda env: 3])


@pytest.mark.parametrize("name", ["paper_rule", "dp_oracle", "receding_dp"])
def test_a_baseline_made_with_a_wrapped_env_obeys_its_ban_unasked(name):
    # No mask passed to predict: the baseline asks the wrapper it was made with.
    free_env = gym.make(ENV, **KWARGS)
    free = make_baseline(name, free_env)
    obs, _ = free_env.reset(seed=SEED)
    favourite = int(free.predict(obs)[0])  # what it picks at the first waypoint unbanned
    log: list = []
    env = Ban(gym.make(ENV, **KWARGS), favourite, log, "method")
    policy = make_baseline(name, env)
    obs, info = env.reset(seed=SEED)
    assert info["action_mask"].sum() > 1  # so the ban bites at this waypoint
    assert int(policy.predict(obs)[0]) != favourite
