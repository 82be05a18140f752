"""``python -m train.evaluate``: metrics, determinism, SB3 models, MODULE:ATTR policies
and wrappers, the table and its two gaps, outputs."""

from __future__ import annotations

import json
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs  # noqa: F401
from ikbranch_gym.agents.evaluation import evaluate
from ikbranch_gym.train.evaluate import main, table

ENV = "IKBranch/RodMechanism-v1"
KWARGS = {"n_waypoints": 5}
REQUIRED = {"success_rate", "mean_return", "mean_travel", "mean_time", "collision_rate",
            "invalid_rate", "mean_gap", "iqm_gap", "iqm_gap_skipped", "decision_ms"}


def without_timing(results: dict) -> dict:
    return {name: {k: v for k, v in m.items() if k != "decision_ms"}
            for name, m in results["policies"].items()}


def test_cli_writes_json_and_plot_and_always_runs_the_oracle(tmp_path, capsys):
    out, figure = tmp_path / "r.json", tmp_path / "r.png"
    main(["--env", ENV, "--env-kwargs", json.dumps(KWARGS), "--policy", "paper_rule",
          "--policy", "random", "--policy", "fixed:1", "--policy", "receding_dp:2",
          "--episodes", "3", "--seed", "5", "--json", str(out), "--plot", str(figure)])
    results = json.loads(out.read_text())
    assert {"env", "episodes", "seed", "policies"} <= set(results)
    assert (results["env"], results["episodes"], results["seed"]) == (ENV, 3, 5)
    assert list(results["policies"]) == [
        "dp_oracle", "paper_rule", "random", "fixed:1", "receding_dp:2"]
    oracle = results["policies"]["dp_oracle"]
    assert oracle["mean_gap"] == oracle["iqm_gap"] == 0.0
    best = np.array(oracle["returns"])
    for metrics in results["policies"].values():
        assert REQUIRED <= set(metrics)
        assert "optimality_gap" not in metrics  # one name per quantity
        assert metrics["mean_return"] <= oracle["mean_return"] + 1e-9
        assert metrics["mean_gap"] >= -1e-12 and metrics["iqm_gap"] >= -1e-12
        assert metrics["invalid_rate"] == 0.0  # baselines respect the mask
        expected = (oracle["mean_return"] - metrics["mean_return"]) / abs(oracle["mean_return"])
        assert metrics["mean_gap"] == pytest.approx(expected)
        per_task = (best - np.array(metrics["returns"])) / np.abs(best)
        assert metrics["iqm_gap"] == pytest.approx(np.mean(np.sort(per_task)))  # 3 tasks: no trim
        assert metrics["iqm_gap_skipped"] == 0
    assert figure.stat().st_size > 0
    printed = capsys.readouterr().out
    assert "travel deg" in printed and "dp_oracle" in printed
    header = printed.splitlines()[0]
    assert "mean gap" in header and "IQM gap" in header
    assert "gap" not in header.replace("mean gap", "").replace("IQM gap", "")


def test_evaluation_is_deterministic_under_a_seed():
    policies = ["paper_pair_rule", "random", "receding_dp"]
    first = evaluate(ENV, policies, episodes=3, seed=11, env_kwargs=KWARGS)
    second = evaluate(ENV, policies, episodes=3, seed=11, env_kwargs=KWARGS)
    assert without_timing(first) == without_timing(second)
    other = evaluate(ENV, policies, episodes=3, seed=12, env_kwargs=KWARGS)
    assert without_timing(other) != without_timing(first)


def test_success_and_travel_match_a_hand_played_episode():
    results = evaluate(ENV, ["paper_rule"], episodes=1, seed=3, env_kwargs=KWARGS)
    from ikbranch_gym.agents import make_baseline

    env = gym.make(ENV, **KWARGS)
    policy = make_baseline("paper_rule", env)
    obs, _ = env.reset(seed=3)
    travel, done = 0.0, False
    while not done:
        action, _ = policy.predict(obs)
        obs, _, done, _, info = env.step(action)
        travel += info["travel"]
    metrics = results["policies"]["paper_rule"]
    assert metrics["mean_travel"] == pytest.approx(travel)
    assert metrics["mean_travel_deg"] == pytest.approx(np.degrees(travel))
    assert metrics["success_rate"] == float(info["is_success"])


@pytest.mark.parametrize("algorithm", ["PPO", "MaskablePPO"])
def test_sb3_models_are_recognised_and_masked(tmp_path, algorithm):
    import sb3_contrib
    import stable_baselines3

    cls = getattr(sb3_contrib if algorithm == "MaskablePPO" else stable_baselines3, algorithm)
    model = cls("MlpPolicy", gym.make(ENV, **KWARGS), n_steps=16, batch_size=16, seed=0)
    path = tmp_path / f"{algorithm}.zip"
    model.save(path)

    from ikbranch_gym.agents.sb3 import SB3Policy

    policy = SB3Policy.load(path, gym.make(ENV, **KWARGS))
    assert policy.maskable == (algorithm == "MaskablePPO")
    results = evaluate(ENV, [str(path)], episodes=4, seed=0, env_kwargs=KWARGS)
    metrics = results["policies"][str(path.with_suffix(""))]
    if algorithm == "MaskablePPO":
        assert metrics["invalid_rate"] == 0.0  # masks reached the policy
    with pytest.raises(SystemExit, match="observations of shape"):
        main(["--env", ENV, "--env-kwargs", '{"lookahead": 0}', "--policy", str(path)])


def test_bad_policies_fail_before_anything_runs(tmp_path):
    with pytest.raises(SystemExit, match="unknown policy 'genius'"):
        main(["--env", ENV, "--policy", "paper_rule", "--policy", "genius"])
    not_a_model = tmp_path / "x.zip"
    not_a_model.write_text("no")
    with pytest.raises(SystemExit, match="not an SB3 model"):
        main(["--env", ENV, "--policy", str(not_a_model)])
    with pytest.raises(SystemExit, match="takes no argument"):
        main(["--env", ENV, "--policy", "paper_rule:3"])


def test_cli_defaults_to_held_out_tasks_and_scenes(tmp_path):
    out = tmp_path / "r.json"
    main(["--env", "IKBranch/Cartesian-v2", "--env-kwargs", '{"n_waypoints": 3}',
          "--policy", "paper_rule", "--episodes", "2", "--json", str(out)])
    results = json.loads(out.read_text())
    from ikbranch_gym.envs.seeds import HELD_OUT_SCENES, TEST_SEED

    assert results["seed"] == TEST_SEED
    assert results["env_kwargs"]["scene_seeds"] == list(HELD_OUT_SCENES)


def test_baseline_specs_are_checked_without_an_env():
    from ikbranch_gym.agents.evaluation import parse_spec

    assert parse_spec("paper_rule") == ("paper_rule", {})
    assert parse_spec("receding_dp:4") == ("receding_dp", {"horizon": 4})
    assert parse_spec("random:7") == ("random", {"seed": 7})
    assert parse_spec("fixed:back/elbow-up/wrist+") == ("fixed", {"branch": "back/elbow-up/wrist+"})
    for spec, message in (("magic", "unknown baseline"), ("paper_rule:3", "takes no argument"),
                          ("dp_oracle:", "takes no argument"), ("receding_dp:0", "horizon"),
                          ("receding_dp:x", "horizon"), ("random:-1", "seed")):
        with pytest.raises(ValueError, match=message):
            parse_spec(spec)


# ------------------------------------------------------------------ the table's gaps
def test_the_table_shows_both_gaps_and_says_which_tasks_the_iqm_left_out():
    results = {"episodes": 5, "policies": {
        "dp_oracle": {"returns": [-10.0, -20.0, 0.0, -5.0, -8.0]},
        "mine": {"returns": [-11.0, -20.0, -1.0, -10.0, -8.0]},
    }}
    for metrics in results["policies"].values():
        returns = np.array(metrics["returns"])
        metrics.update(success_rate=1.0, mean_return=returns.mean(), std_return=returns.std(),
                       mean_travel=1.0, mean_travel_deg=57.3, mean_time=1.0,
                       collision_rate=0.0, invalid_rate=0.0, decision_ms=0.1)
    lines = table(results).splitlines()
    header = lines[0].split("  ")
    assert [cell.strip() for cell in header if cell.strip()][-3:] == [
        "mean gap", "IQM gap", "ms/step"]
    mine = lines[3]
    # Written by the old code (no gap keys): the mean gap 1.4 / 8.6, and the IQM gap of the
    # four tasks with a non-zero optimum (0.1, 0, 1.0, 0 -> mean of 0 and 0.1).
    assert "16.28%" in mine and "5.00%" in mine
    assert lines[-1].startswith("IQM gap: 1 of 5 tasks left out")


def test_a_file_with_the_old_gap_key_still_renders():
    results = {"episodes": 2, "policies": {name: {
        "success_rate": 1.0, "mean_return": -1.0, "std_return": 0.0, "mean_travel": 1.0,
        "mean_travel_deg": 57.3, "mean_time": 1.0, "collision_rate": 0.0,
        "invalid_rate": 0.0, "optimality_gap": gap, "decision_ms": 0.1,
    } for name, gap in (("dp_oracle", 0.0), ("old", 0.4321))}}
    lines = table(results).splitlines()
    assert "43.21%" in lines[3] and lines[3].rstrip().endswith("n/a    0.100")


# ------------------------------------------------- MODULE:ATTR policies and wrappers
POLICIES_MODULE = """
import gymnasium as gym
import numpy as np


def first_valid(obs, mask):
    return int(np.flatnonzero(mask)[0])


def make_first_valid():
    return first_valid


def make_factory():
    return make_first_valid


def doubled(env):
    return gym.wrappers.TransformReward(env, lambda r: 2 * r)


NOT_A_POLICY = 3
"""


@pytest.fixture
def policies_module(tmp_path, monkeypatch):
    """A module of policies and wrappers in the working directory, not on sys.path."""
    name = "ikbranch_test_policies"
    (tmp_path / f"{name}.py").write_text(textwrap.dedent(POLICIES_MODULE))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(tmp_path))])
    monkeypatch.delitem(sys.modules, name, raising=False)
    yield name
    sys.modules.pop(name, None)


def test_module_attr_policies_and_files(policies_module, tmp_path):
    out = tmp_path / "r.json"
    main(["--env", ENV, "--env-kwargs", json.dumps(KWARGS), "--episodes", "3", "--seed", "5",
          "--policy", f"{policies_module}:first_valid",
          "--policy", f"{policies_module}:make_first_valid",
          "--policy", f"{tmp_path / (policies_module + '.py')}:first_valid",
          "--json", str(out)])
    results = json.loads(out.read_text())
    names = list(results["policies"])
    assert names[:3] == ["dp_oracle", f"{policies_module}:first_valid",
                         f"{policies_module}:make_first_valid"]
    env = gym.make(ENV, **KWARGS)  # the first allowed branch, played by hand
    expected = []
    for e in range(3):
        _, info = env.reset(seed=5 + e)
        total, done = 0.0, False
        while not done:
            _, reward, done, _, info = env.step(int(np.flatnonzero(info["action_mask"])[0]))
            total += reward
        expected.append(total)
    for name in names[1:]:
        assert results["policies"][name]["returns"] == expected


def test_wrappers_on_the_command_line(policies_module, tmp_path):
    runs = {}
    for label, extra in (("plain", []), ("class", ["--wrapper",
                         "gymnasium.wrappers:RecordEpisodeStatistics"]),
                         ("doubled", ["--wrapper", f"{policies_module}:doubled"])):
        out = tmp_path / f"{label}.json"
        main(["--env", ENV, "--env-kwargs", json.dumps(KWARGS), "--episodes", "3",
              "--policy", "paper_rule", "--json", str(out), *extra])
        runs[label] = json.loads(out.read_text())
    assert runs["class"]["wrappers"] == ["gymnasium.wrappers:RecordEpisodeStatistics"]
    assert without_timing(runs["class"]) == without_timing(runs["plain"])
    for name, metrics in runs["plain"]["policies"].items():
        doubled = runs["doubled"]["policies"][name]
        assert doubled["returns"] == [2 * r for r in metrics["returns"]]
        assert doubled["mean_gap"] == pytest.approx(metrics["mean_gap"])


@pytest.mark.parametrize(("args", "message"), [
    (["--policy", "x.pt"], "unknown policy 'x.pt': a policy is a baseline name .* SB3 "
                           "model zip .* MODULE:ATTR .* saved in another format"),
    (["--policy", "no_such_module_anywhere:f"], "no module 'no_such_module_anywhere'"),
    (["--policy", "{module}:missing"], "has no attribute 'missing'"),
    (["--policy", "{module}:NOT_A_POLICY"], "not a policy"),
    (["--policy", "{module}:make_factory"], "returned another factory"),
    (["--policy", "paper_rule", "--wrapper", "{module}:NOT_A_POLICY"], "no wrapper"),
])
def test_what_is_not_a_policy_or_wrapper_is_named(policies_module, args, message):
    args = [arg.format(module=policies_module) for arg in args]
    with pytest.raises(SystemExit, match=message):
        main(["--env", ENV, "--env-kwargs", json.dumps(KWARGS), "--episodes", "1", *args])
