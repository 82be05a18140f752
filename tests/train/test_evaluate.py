"""``python -m train.evaluate``: metrics, determinism, SB3 models, outputs."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs  # noqa: F401
from ikbranch_gym.agents.evaluation import evaluate
from ikbranch_gym.train.evaluate import main

ENV = "IKBranch/RodMechanism-v1"
KWARGS = {"n_waypoints": 5}
REQUIRED = {"success_rate", "mean_return", "mean_travel", "mean_time", "collision_rate",
            "invalid_rate", "optimality_gap", "decision_ms"}


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
    assert oracle["optimality_gap"] == 0.0
    for metrics in results["policies"].values():
        assert REQUIRED <= set(metrics)
        assert metrics["mean_return"] <= oracle["mean_return"] + 1e-9
        assert metrics["optimality_gap"] >= -1e-12
        assert metrics["invalid_rate"] == 0.0  # baselines respect the mask
        expected = (oracle["mean_return"] - metrics["mean_return"]) / abs(oracle["mean_return"])
        assert metrics["optimality_gap"] == pytest.approx(expected)
    assert figure.stat().st_size > 0
    printed = capsys.readouterr().out
    assert "travel deg" in printed and "dp_oracle" in printed


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
    with pytest.raises(SystemExit, match="unknown baseline"):
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
