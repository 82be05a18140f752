"""A tiny sweep on embedded Ray: two trials and the baselines, then the same command again
resumes (skips) them; the aggregation on synthetic scores with known IQM and intervals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from ikbranch_gym.agents.evaluation import iqm, iqm_rows
from ikbranch_gym.train import aggregate, publish, sweep

TINY = ['--hyperparams', '{"n_steps": 32, "batch_size": 32, "n_epochs": 1, '
        '"eval_freq": 64, "n_eval_episodes": 2, "checkpoint_freq": 64}']


def test_a_record_counts_only_at_the_trials_budget(tmp_path):
    root, store = tmp_path / "root", tmp_path / "archive"
    spec = sweep.trials(["IKBranch/ToolTransfer-v1"], ["maskable_ppo"], [0], root, 3, 128,
                        {}, store)[1]
    archived = sweep.done_path(spec, store)
    archived.parent.mkdir(parents=True)
    archived.write_text(json.dumps({"timesteps": 128}))
    assert sweep.finished(spec) == archived
    longer = {**spec, "timesteps": 256}
    assert sweep.budget(longer) == 256 and sweep.finished(longer) is None
    overridden = {**spec, "timesteps": None, "hyperparams": {"n_timesteps": 64}}
    assert sweep.budget(overridden) == 64 and sweep.finished(overridden) is None
    # A model of another budget in the trial's run directory: an error naming both.
    directory = sweep.run_dir(root, "IKBranch/ToolTransfer-v1", "maskable_ppo", 0)
    directory.mkdir(parents=True)
    (directory / "model.zip").write_bytes(b"")
    (directory / "config.yml").write_text("hyperparams:\n  n_timesteps: 128\n")
    with pytest.raises(ValueError, match="trained for 128 steps, where this trial's budget "
                                         "is 256"):
        sweep.run_trial(longer)


def test_tiny_sweep_writes_run_directories_and_resumes(tmp_path):
    import ray

    store = tmp_path / "archive"
    argv = ["--env", "IKBranch/ToolTransfer-v1", "--algo", "maskable_ppo", "--seeds", "0-1",
            "--timesteps", "128", "--episodes", "3", "--root", str(tmp_path),
            "--archive", str(store), *TINY]
    try:
        assert sweep.main(argv) == 0
        models = {seed: sweep.run_dir(tmp_path, "IKBranch/ToolTransfer-v1", "maskable_ppo",
                                      seed) for seed in (0, 1)}
        for seed, directory in models.items():
            for name in ("config.yml", "command.txt", "versions.yml", "model.zip",
                         "evaluations.npz", "evaluation.json"):
                assert (directory / name).exists(), name
            record = json.loads((directory / "evaluation.json").read_text())
            assert record["seed"] == seed and len(record["policy"]["returns"]) == 3
            assert record["timesteps"] == 128
        baselines = json.loads(sweep.baselines_path(tmp_path, "IKBranch/ToolTransfer-v1")
                               .read_text())
        assert {"dp_oracle", "paper_rule", "random"} <= set(baselines["policies"])
        stamps = {seed: (d / "model.zip").stat().st_mtime_ns for seed, d in models.items()}
        assert sweep.main(argv) == 0  # resumed: finished trials are skipped, not retrained
        assert stamps == {seed: (d / "model.zip").stat().st_mtime_ns
                          for seed, d in models.items()}
        # Archived, the records alone aggregate to the same numbers, and a later sweep
        # (another root: another machine or run) skips the archived trials.

        records = aggregate.aggregate(tmp_path)
        archived = publish.archive(tmp_path, store)
        assert not any(p.name in ("model.zip", "latest.zip") for p in archived)
        # (compared as JSON: NaN, e.g. a CI bound over identical scores, equals itself)
        assert json.dumps(aggregate.aggregate(store)) == json.dumps(records)
        row = records["IKBranch/ToolTransfer-v1"]["policies"]["maskable_ppo"]
        assert row["runs"] == 2 and row["timesteps"] == [128]
        elsewhere = tmp_path / "elsewhere"
        again = [arg if arg != str(tmp_path) else str(elsewhere) for arg in argv]
        assert sweep.main(again) == 0 and not (elsewhere / "runs").exists()
        # Publishing copies the representative seed's model and record, and renders them.
        out, models = tmp_path / "published", tmp_path / "repo" / "models"
        publish.publish(tmp_path, records, out=out, models=models, store=store)
        # From a root without the models: fine where they are published already, an error
        # (before any file is written) where they are not.
        publish.publish(elsewhere, records, out=out, models=models, store=store)
        with pytest.raises(FileNotFoundError, match="representative seed"):
            publish.publish(elsewhere, records, out=tmp_path / "other",
                            models=tmp_path / "other_models", store=store)
        assert not (tmp_path / "other").exists() and not (tmp_path / "other_models").exists()
        chosen = models / "ToolTransfer-v1" / "maskable_ppo.zip"
        source = sweep.run_dir(tmp_path, "IKBranch/ToolTransfer-v1", "maskable_ppo",
                               row["representative_seed"]) / "model.zip"
        assert chosen.read_bytes() == source.read_bytes()
        published = json.loads((out / "ToolTransfer-v1" / "maskable_ppo.json").read_text())
        assert published["seed"] == row["representative_seed"]
        assert published["command"].startswith("python -m train --algo maskable_ppo")
        seed = row["representative_seed"]
        assert published["command"].endswith(
            f"--run-dir runs/sweep/runs/ToolTransfer-v1/maskable_ppo/seed{seed}")
        text = "\n".join(publish.render_sweep(out / "aggregate.json"))
        assert "### IKBranch/ToolTransfer-v1" in text
        assert "| maskable_ppo | 2 | 128 |" in text
        # The README's table is rewritten between its markers, the rest kept.
        readme = tmp_path / "README.md"
        readme.write_text(f"# title\n{publish.README_BEGIN}\nold\n{publish.README_END}\nend\n")
        publish.write_readme(records, readme)
        lines = readme.read_text().split("\n")
        assert lines[:2] == ["# title", publish.README_BEGIN] and "old" not in lines
        assert lines[-3:] == [publish.README_END, "end", ""]
        assert "| ToolTransfer-v1 | maskable_ppo | 2 × 128 |" in lines[4]
    finally:
        ray.shutdown()


def _policy(returns, successes=None) -> dict:
    """A policy's record of an evaluation: every task a success unless ``successes``."""
    return {"returns": [float(r) for r in returns],
            "successes": [True] * len(returns) if successes is None else list(successes),
            "decision_ms": 1.0}


def _synthetic_root(tmp_path, scores: np.ndarray, rival: np.ndarray,
                    oracle: np.ndarray | None = None):
    """A sweep root whose seeds of ``ppo`` score ``scores`` (seeds, T) per task: oracle
    return ``oracle`` (default 0), random 10 less, so R = oracle + 10·(score − 1);
    ``paper_rule`` scores ``rival``."""
    env = "IKBranch/ToolTransfer-v1"
    oracle = np.zeros(scores.shape[1]) if oracle is None else oracle
    baselines = {"dp_oracle": _policy(oracle), "random": _policy(oracle - 10.0),
                 "paper_rule": _policy(oracle + 10 * (rival - 1)), "receding_dp": _policy(oracle)}
    record = {"env": env, "task_seed": 0, "env_kwargs": {}, "policies": baselines}
    path = sweep.baselines_path(tmp_path, env)
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps(record))
    for seed, row in enumerate(scores):
        _synthetic_trial(tmp_path, env, seed, row, oracle)
    return env


def _synthetic_trial(root, env: str, seed: int, scores: np.ndarray, oracle: np.ndarray,
                     steps: int = 1000) -> Path:
    """A finished ``ppo`` trial of ``steps`` under ``root`` scoring ``scores`` per task
    (returns as :func:`_synthetic_root`'s), its config saying its budget; its directory."""
    trial = {"env": env, "algo": "ppo", "seed": seed, "timesteps": steps,
             "train_minutes": 1.0 + seed, "oracle": _policy(oracle),
             "policy": _policy(oracle + 10 * (scores - 1), [bool(s > 0.5) for s in scores])}
    directory = sweep.run_dir(root, env, "ppo", seed)
    directory.mkdir(parents=True)
    (directory / "config.yml").write_text(f"hyperparams:\n  n_timesteps: {steps}\n")
    (directory / "command.txt").write_text(f"python -m train --algo ppo --seed {seed}\n")
    (directory / "evaluation.json").write_text(json.dumps(trial))
    return directory


def _trials(root, env: str, trials: dict[int, tuple[float, int]]) -> Path:
    """``ppo`` trials under ``root``: seed -> (score on every task, steps), each with a
    model naming them; returns ``root``."""
    for seed, (score, steps) in trials.items():
        directory = _synthetic_trial(root, env, seed, np.full(20, score), np.zeros(20), steps)
        (directory / "model.zip").write_bytes(f"seed {seed} at {steps}".encode())
    return root


def test_a_raised_budget_waits_staged_until_its_seeds_cover_the_row(tmp_path):
    # A sweep of a raised budget spread over runs, two seeds a run: its trials neither
    # replace nor mix with the row of the budget before until they cover all its seeds;
    # then they replace it, and a representative trained in a run whose root is gone is
    # published from the model its staged trial left.
    store = tmp_path / "archive"
    env = _synthetic_root(tmp_path / "first", np.full((3, 20), 0.5), rival=np.full(20, 0.2))
    publish.archive(tmp_path / "first", store)
    before = json.dumps(aggregate.aggregate(store))
    second = _trials(tmp_path / "second", env, {0: (0.8, 2000), 1: (0.9, 2000)})
    publish.archive(second, store)
    assert json.dumps(aggregate.aggregate(store)) == before
    staged = sweep.staged_root(store, 2000)
    spec = sweep.trials([env], ["ppo"], [0], tmp_path / "elsewhere", 20, 2000, {}, store)[1]
    assert sweep.finished(spec) == sweep.done_path(spec, staged)
    assert sweep.finished({**spec, "seed": 2}) is None
    assert sweep.finished({**spec, "timesteps": 1000}) == sweep.done_path(spec, store)
    # The row of the budget before is published from a root holding the raised budget's
    # models: those are other trials, not its representative's.
    with pytest.raises(FileNotFoundError, match="representative seed 0"):
        publish.publish(second, json.loads(before), out=tmp_path / "out",
                        models=tmp_path / "models", store=store)
    # Seed 1 trained again at the raised budget: its new record joins the row, not the
    # staged one.
    third = _trials(tmp_path / "third", env, {1: (0.85, 2000), 2: (0.7, 2000)})
    publish.archive(third, store)
    records = aggregate.aggregate(store)
    row = records[env]["policies"]["ppo"]
    assert row["seeds"] == [0, 1, 2] and row["timesteps"] == [2000]
    assert row["representative_seed"] == 0  # IQM 0.79 of 0.7, 0.8, 0.85
    assert sweep.finished(spec) == sweep.done_path(spec, store)
    assert not list(staged.glob("runs/*/*/seed*/evaluation.json"))
    assert json.loads(sweep.done_path({**spec, "seed": 1}, store).read_text()) == json.loads(
        sweep.done_path({**spec, "seed": 1}, third).read_text())
    publish.publish(third, records, out=tmp_path / "out", models=tmp_path / "models",
                    store=store)
    assert (tmp_path / "models" / "ToolTransfer-v1" / "ppo.zip").read_bytes() == (
        b"seed 0 at 2000")
    removed = publish.prune_staged(store)
    assert [p.name for p in removed] == ["seed0", "seed1", "seed2", "2000"]
    assert not sweep.staged_root(store).exists() or not any(
        sweep.staged_root(store).iterdir())


def test_a_row_takes_one_budget_and_never_goes_back(tmp_path):
    store, left_out = tmp_path / "archive", []
    env = _synthetic_root(tmp_path / "first", np.full((3, 20), 0.5), rival=np.full(20, 0.2))
    publish.archive(tmp_path / "first", store)
    # One root with seeds of the row's budget and of a raised one: the first join the
    # row, the others wait; the row never holds two budgets.
    mixed = _trials(tmp_path / "mixed", env, {0: (0.8, 2000), 3: (0.6, 1000)})
    publish.archive(mixed, store, left_out=left_out)
    row = aggregate.aggregate(store)[env]["policies"]["ppo"]
    assert row["seeds"] == [0, 1, 2, 3] and row["timesteps"] == [1000] and not left_out
    waiting = sweep.run_dir(sweep.staged_root(store, 2000), env, "ppo", 0)
    assert (waiting / "model.zip").read_bytes() == b"seed 0 at 2000"
    # A smaller budget than the row's is left out, named; it touches no staged trial of
    # the same seed, nor does a larger budget of that seed, which waits apart.
    _trials(tmp_path / "short", env, {0: (0.1, 50)})
    _trials(tmp_path / "long", env, {0: (0.9, 3000)})
    publish.archive(tmp_path / "short", store, left_out=left_out)
    publish.archive(tmp_path / "long", store, left_out=left_out)
    assert [(path.name, steps, row_steps) for path, steps, row_steps in left_out] == [
        ("seed0", 50, 1000)]
    assert (waiting / "model.zip").read_bytes() == b"seed 0 at 2000"
    assert sweep.run_dir(sweep.staged_root(store, 3000), env, "ppo", 0).exists()
    assert aggregate.aggregate(store)[env]["policies"]["ppo"]["timesteps"] == [1000]
    # A published row holds seeds the archive lost: the raised budget must cover those
    # too before it replaces the row (else the row would shrink, and be carried over).
    published = aggregate.aggregate(store)
    published[env]["policies"]["ppo"]["seeds"] = [0, 1, 2, 3, 4]
    publish.archive(_trials(tmp_path / "rest", env, {1: (0.8, 2000), 2: (0.8, 2000),
                                                     3: (0.8, 2000)}), store, published)
    assert aggregate.aggregate(store)[env]["policies"]["ppo"]["timesteps"] == [1000]
    publish.archive(_trials(tmp_path / "last", env, {4: (0.8, 2000)}), store, published)
    row = aggregate.aggregate(store)[env]["policies"]["ppo"]
    assert row["seeds"] == [0, 1, 2, 3, 4] and row["timesteps"] == [2000]
    # The larger budget still waits; an old root of the budget before is left out.
    assert sweep.run_dir(sweep.staged_root(store, 3000), env, "ppo", 0).exists()
    publish.archive(tmp_path / "first", store, left_out=left_out)
    assert aggregate.aggregate(store)[env]["policies"]["ppo"]["timesteps"] == [2000]
    assert len(left_out) == 4
    # A new row with nothing archived takes its root's largest budget.
    fresh = tmp_path / "fresh_archive"
    publish.archive(mixed, fresh, left_out=left_out)
    assert aggregate.load(fresh)[env]["trials"]["ppo"][0]["timesteps"] == 2000
    assert left_out[-1][1:] == (1000, 2000)


def test_a_cloned_rows_oracle_episodes_are_published_beside_its_steps(tmp_path):
    scores = np.random.default_rng(1).uniform(0.5, 1.0, size=(2, 40))
    env = _synthetic_root(tmp_path, scores, rival=np.full(40, 0.2))
    for seed in range(2):  # as a bc_maskable_ppo trial records them (train.sweep)
        path = sweep.run_dir(tmp_path, env, "ppo", seed) / "evaluation.json"
        path.write_text(json.dumps({**json.loads(path.read_text()), "imitation_episodes": 200}))
    records = aggregate.aggregate(tmp_path)
    assert records[env]["policies"]["ppo"]["imitation_episodes"] == [200]
    (tmp_path / "aggregate.json").write_text(json.dumps(records))
    lines = publish.render_sweep(tmp_path / "aggregate.json")
    assert any(line.startswith("| ppo | 2 | 1,000 after 200 oracle episodes |")
               for line in lines)
    summary = publish.readme_summary(records)
    assert any("| ppo | 2 × 1,000 after 200 oracle episodes |" in line for line in summary)


def test_a_resumed_run_publishes_the_command_that_started_it(tmp_path):
    record = tmp_path / "command.txt"
    started = f"/venv/bin/python -m train --algo ppo --run-dir {tmp_path}/runs/x/seed2"
    record.write_text(f"{started}\n{started} --resume\n")
    assert publish._portable(publish._started_by(record), tmp_path) == (
        "python -m train --algo ppo --run-dir runs/sweep/runs/x/seed2")
    # A trial staged from another machine's root: its run directory from runs/<EnvName>.
    elsewhere = ("/venv/bin/python -m train --algo ppo --env IKBranch/UR5e-v3 --seed 2 "
                 "--run-dir /work/sweep/runs/ur5e/runs/UR5e-v3/ppo/seed2")
    assert publish._portable(elsewhere, tmp_path) == (
        "python -m train --algo ppo --env IKBranch/UR5e-v3 --seed 2 "
        "--run-dir runs/sweep/runs/UR5e-v3/ppo/seed2")


def test_aggregation_recovers_known_iqm_intervals_and_improvement(tmp_path):
    rng = np.random.default_rng(0)
    scores = rng.uniform(0.5, 1.0, size=(2, 200))
    env = _synthetic_root(tmp_path, scores, rival=np.full(200, 0.2))
    record = aggregate.aggregate(tmp_path)[env]
    learned = record["policies"]["ppo"]
    point, low, high = learned["score"]
    # The IQM is the 25 %-trimmed mean over all runs × tasks, computed independently.
    assert point == pytest.approx(stats.trim_mean(scores.ravel(), 0.25), abs=1e-12)
    assert low < point < high and high - low < 0.1
    assert record["policies"]["dp_oracle"]["score"][0] == pytest.approx(1.0)
    assert record["policies"]["random"]["score"][0] == pytest.approx(0.0)
    # Every learned score beats paper_rule's 0.2 on every task: improvement certain.
    assert learned["improvement"]["paper_rule"] == pytest.approx((1.0, 1.0, 1.0))
    # ... and never beats receding_dp's 1.0.
    assert learned["improvement"]["receding_dp"][0] == pytest.approx(0.0)
    assert learned["optimal"] == np.mean(scores >= 1.0) == 0.0
    assert record["policies"]["receding_dp"]["optimal"] == 1.0
    assert record["policies"]["paper_rule"]["optimal"] == 0.0
    success = (scores > 0.5).mean()
    assert learned["success"][1] <= success <= learned["success"][2]
    per_run = scores.mean(axis=1)
    assert learned["representative_seed"] == int(np.argmin(np.abs(per_run - point)))
    assert learned["timesteps"] == [1000] and learned["train_minutes"] == 1.5


def test_the_learning_curve_matches_the_seeds_evaluations_by_timestep(tmp_path):
    # A log that lacks early evaluations (or ends sooner) leaves those timesteps out; it
    # is never read as if its first evaluation were everyone's first.
    logs = {0: ([10, 20, 30, 40], [[-9.0, -7.0], [-6.0, -6.0], [-5.0, -3.0], [-2.0, -2.0]]),
            1: ([20, 30, 40], [[-8.0, -8.0], [-4.0, -4.0], [-1.0, -3.0]]),
            2: ([10, 20, 30], [[-9.0, -9.0], [-5.0, -7.0], [-3.0, -3.0]])}
    for seed, (timesteps, results) in logs.items():
        run = tmp_path / "runs" / "Env-v0" / "ppo" / f"seed{seed}"
        run.mkdir(parents=True)
        np.savez(run / "evaluations.npz", timesteps=timesteps, results=results,
                 ep_lengths=np.ones_like(results))
    curve = aggregate._curves(tmp_path, "IKBranch/Env-v0", "ppo", [0, 1, 2])
    assert curve["timesteps"] == [20, 30]
    assert curve["iqm"] == [pytest.approx(iqm(np.array([-6.0, -8.0, -6.0]))),
                            pytest.approx(iqm(np.array([-4.0, -4.0, -3.0])))]
    # Logs that share no timestep (seeds evaluated at other steps) make no curve.
    run = tmp_path / "runs" / "Env-v0" / "ppo" / "seed3"
    run.mkdir(parents=True)
    np.savez(run / "evaluations.npz", timesteps=[15, 25], results=[[-1.0], [-1.0]],
             ep_lengths=[[1], [1]])
    assert aggregate._curves(tmp_path, "IKBranch/Env-v0", "ppo", [0, 1, 2, 3]) is None


def test_the_iqm_gap_and_the_mean_gap_are_the_projects_two_gaps(tmp_path):
    # IQM gap: the IQM over runs × tasks of (R_oracle,i − R_i)/|R_oracle,i|; mean gap:
    # (mean R_oracle − mean R)/|mean R_oracle|; both computed independently here.
    rng = np.random.default_rng(3)
    scores = rng.uniform(0.0, 1.0, size=(3, 80)) ** 0.2
    oracle = -rng.uniform(5.0, 50.0, size=80)
    env = _synthetic_root(tmp_path, scores, rival=np.full(80, 0.2), oracle=oracle)
    record = aggregate.aggregate(tmp_path)[env]
    returns = oracle + 10 * (scores - 1)
    learned = record["policies"]["ppo"]
    per_task = (oracle - returns) / np.abs(oracle)
    assert learned["gap"][0] == pytest.approx(stats.trim_mean(per_task.ravel(), 0.25),
                                              rel=1e-12)
    assert learned["gap"][1] < learned["gap"][0] < learned["gap"][2]
    expected = (oracle.mean() - returns.mean()) / abs(oracle.mean())
    assert learned["mean_gap"] == pytest.approx(expected, rel=1e-12)
    assert learned["mean_gap"] != pytest.approx(learned["gap"][0], rel=1e-3)  # not one number
    rule = oracle + 10 * (0.2 - 1)
    assert record["policies"]["paper_rule"]["mean_gap"] == pytest.approx(
        (oracle.mean() - rule.mean()) / abs(oracle.mean()), rel=1e-12)
    assert record["policies"]["dp_oracle"]["mean_gap"] == 0.0
    # Rendered side by side, named as the legend names them.
    from ikbranch_gym.train import publish

    path = tmp_path / "aggregate.json"
    path.write_text(json.dumps({env: record}))
    lines = publish.render_sweep(path)
    text = "\n".join(lines)
    header = next(line for line in lines if line.startswith("| policy |"))
    assert "| score IQM | IQM gap | mean gap | success |" in header
    row = next(line for line in lines if line.startswith("| ppo |"))
    cells = [cell.strip() for cell in row.split("|")[1:-1]]
    titles = [cell.strip() for cell in header.split("|")[1:-1]]
    assert cells[titles.index("mean gap")] == f"{100 * learned['mean_gap']:.1f} %"
    gap = [100 * v for v in learned["gap"]]
    assert cells[titles.index("IQM gap")] == f"{gap[0]:.1f} % [{gap[1]:.1f}, {gap[2]:.1f}]"
    assert "**IQM gap**" in text and "**mean gap**" in text and "**gap**" not in text


def test_the_mean_gap_without_a_scale():
    assert aggregate.mean_gap(np.array([[-1.0, -3.0]]), np.array([-2.0, -2.0])) == 0.0
    assert aggregate.mean_gap(np.array([[-3.0, -3.0]]), np.array([-2.0, -2.0])) == 0.5
    assert aggregate.mean_gap(np.zeros((2, 3)), np.zeros(3)) == 0.0
    assert aggregate.mean_gap(np.full((2, 3), -1.0), np.zeros(3)) is None


def test_a_rival_optimal_on_some_tasks_caps_the_probability_of_improvement(tmp_path):
    # paper_rule attains the optimum on a quarter of the tasks, the learned policy on all:
    # it beats the rule on the other three quarters and ties on that quarter.
    rival = np.full(200, 0.2)
    rival[:50] = 1.0
    env = _synthetic_root(tmp_path, np.ones((2, 200)), rival=rival)
    records = aggregate.aggregate(tmp_path)
    policies = records[env]["policies"]
    assert policies["paper_rule"]["optimal"] == 0.25 and policies["ppo"]["optimal"] == 1.0
    assert policies["ppo"]["improvement"]["paper_rule"][0] == pytest.approx(1 - 0.25 / 2)
    from ikbranch_gym.train.publish import goal_lines

    line = next(line for line in goal_lines(records) if "P(improvement" in line)
    assert "attains the optimum on 25.0% of the tasks: P can be at most 0.875" in line


def test_each_headline_goal_is_checked_against_its_own_gap():
    # The same row meets UR5e-v2's goal (IQM gap ≤ 2 %) and misses Anthropomorphic-v4's
    # (≤ 1 %); success below 99 % misses either.
    from ikbranch_gym.train.publish import goal_lines

    def record(success, gap):
        row = {"success": [success, success, success], "gap": [gap, gap, gap],
               "improvement": {"paper_rule": [0.9, 0.8, 1.0]}, "decision_ms": 0.0}
        return {"policies": {"paper_rule": {}, "ppo": row}}

    def verdict(env_id, success, gap):
        lines = goal_lines({env_id: record(success, gap)})
        return next(line for line in lines if "IQM gap" in line)

    assert verdict("IKBranch/UR5e-v2", 0.995, 0.015).endswith("(≤ 2 %): met")
    assert verdict("IKBranch/Anthropomorphic-v4", 0.995, 0.015).endswith("(≤ 1 %): **not met**")
    assert verdict("IKBranch/Anthropomorphic-v4", 0.995, 0.005).endswith("(≤ 1 %): met")
    assert verdict("IKBranch/UR5e-v2", 0.985, 0.005).endswith("**not met**")
    assert not [line for line in goal_lines({"IKBranch/UR5e-v1": record(1.0, 0.0)})
                if "IQM gap" in line]


def test_probability_of_improvement_equals_rliables():
    # The vectorised count against rliable's per-task Mann-Whitney U, ties included
    # (scores on a coarse grid tie often; identical columns take rliable's 0.5 branch).
    from rliable import metrics

    from ikbranch_gym.train.aggregate import probability_of_improvement

    rng = np.random.default_rng(0)
    for runs_x, runs_y in ((5, 1), (3, 3), (1, 1), (5, 5)):
        x = np.round(rng.normal(size=(runs_x, 40)), 1)
        y = np.round(rng.normal(size=(runs_y, 40)), 1)
        y[:, :5] = x[:runs_y, :5] if runs_x == runs_y else y[:, :5]
        assert probability_of_improvement(x, y) == metrics.probability_of_improvement(x, y)
        z = rng.normal(size=(runs_x, 40))
        assert probability_of_improvement(z, y) == metrics.probability_of_improvement(z, y)
        # Equal to rounding is a tie here; rliable lets the last bit decide.
        one = x[:1]
        nudged = one + np.where(rng.random(one.shape) < 0.5, 1e-15, -1e-15)
        assert probability_of_improvement(one, nudged) == 0.5
        assert probability_of_improvement(one + 1e-6, one) == 1.0


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (5, 1), (3, 40), (5, 200), (1, 200)])
def test_intervals_are_rliables_to_the_bit(shape):
    # rliable's loop (arch's bootstrap iterator) against the batches: the same points and
    # interval ends, for every statistic the aggregate reports, ties included (scores on
    # a coarse grid, as successes and optimal moves are).
    import warnings

    from rliable import library, metrics

    rng = np.random.default_rng(sum(shape))
    fine = rng.normal(size=shape)
    coarse = np.round(rng.random(shape) * 4) / 4
    rival = rng.normal(size=(1, shape[1]))

    def rliables(scores, func):
        np.random.seed(0)  # noqa: NPY002 (what _estimate seeds, for rliable's draws)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            points, intervals = library.get_interval_estimates(
                {"x": scores}, lambda *x: np.array([func(*x)]), reps=aggregate.REPS,
                task_bootstrap=True, random_state=np.random.RandomState(0))
        return float(points["x"][0]), float(intervals["x"][0][0]), float(intervals["x"][1][0])

    for scores in (fine, coarse):
        assert aggregate._estimate(scores, iqm_rows) == rliables(scores, iqm)
        assert (aggregate._estimate(scores, aggregate.mean_of_task_means)
                == rliables(scores, metrics.aggregate_mean))
        assert (aggregate._estimate((scores, rival), aggregate.improvement_rows)
                == rliables((scores, rival), aggregate.probability_of_improvement))
        assert (aggregate._estimate((scores, coarse), aggregate.improvement_rows)
                == rliables((scores, coarse), aggregate.probability_of_improvement))


def test_intervals_refuse_scores_they_cannot_resample():
    for bad in (np.zeros((0, 3)), np.zeros(4), (np.zeros((2, 3)), np.zeros((2, 4)))):
        with pytest.raises(ValueError, match="bootstrap scores"):
            aggregate._estimate(bad, iqm_rows)


def test_intervals_are_reproducible_whatever_numpys_global_state():
    # rliable resamples with numpy's global generator; the estimates must not depend on it.
    scores = np.random.default_rng(0).normal(size=(4, 30))
    np.random.seed(1)  # noqa: NPY002 (the global generator rliable uses)
    first = aggregate._estimate(scores, iqm_rows)
    np.random.seed(2)  # noqa: NPY002
    outer = np.random.get_state()  # noqa: NPY002
    second = aggregate._estimate(scores, iqm_rows)
    assert first == second
    after = np.random.get_state()  # noqa: NPY002
    assert all(np.array_equal(a, b) for a, b in zip(outer, after, strict=True))


@pytest.mark.parametrize("text", ["no markers\n",
                                  "<!-- /results -->\n<!-- results: written by python -m "
                                  "train.aggregate --publish; do not edit -->\n"])
def test_the_readme_table_needs_its_markers_in_order(tmp_path, text):
    from ikbranch_gym.train import publish

    readme = tmp_path / "README.md"
    readme.write_text(text)
    with pytest.raises(ValueError, match=r"README\.md"):
        publish.write_readme({}, readme)
    assert readme.read_text() == text


def test_publishing_keeps_the_learned_rows_whose_trials_the_archive_does_not_hold(tmp_path):
    # A sweep that adds one id (or an archive that lost trials) must not erase the rows
    # it did not re-run: they are carried over, marked, and their models left alone.
    from ikbranch_gym.train import publish

    env = _synthetic_root(tmp_path / "full", np.full((2, 20), 0.9), rival=np.full(20, 0.2))
    published = aggregate.aggregate(tmp_path / "full")
    baselines_only = tmp_path / "baselines_only"
    (baselines_only / "baselines").mkdir(parents=True)
    path = sweep.baselines_path(tmp_path / "full", env)
    (baselines_only / "baselines" / path.name).write_text(path.read_text())
    fresh = aggregate.aggregate(baselines_only)
    assert "ppo" not in fresh[env]["policies"]
    other = {"env": "IKBranch/Other-v0", "policies": {}}
    merged = publish.carry_over(fresh, {**published, other["env"]: other})
    assert merged["IKBranch/Other-v0"] == other
    row = dict(merged[env]["policies"]["ppo"])
    assert row.pop(publish.CARRIED_OVER) is True
    assert row == published[env]["policies"]["ppo"]
    assert merged[env]["policies"]["paper_rule"] == fresh[env]["policies"]["paper_rule"]
    # publish() copies no model for a carried-over row (there is none under the root).
    written = publish.publish(baselines_only, merged, out=tmp_path / "out",
                              models=tmp_path / "models", store=baselines_only)
    assert not (tmp_path / "models").exists()
    assert json.loads((tmp_path / "out" / "aggregate.json").read_text()) == json.loads(
        json.dumps(merged))
    assert tmp_path / "out" / "aggregate.json" in written
    # A fresh row replaces the published one; nothing is carried over where trials exist.
    assert publish.carry_over(published, published) == published


def test_a_sweep_still_rerunning_a_rows_seeds_does_not_shrink_it(tmp_path):
    import shutil

    from ikbranch_gym.train import publish

    env = _synthetic_root(tmp_path, np.array([np.full(20, 0.9), np.full(20, 0.5)]),
                          rival=np.full(20, 0.2))
    published = aggregate.aggregate(tmp_path)
    shutil.rmtree(sweep.run_dir(tmp_path, env, "ppo", 1))
    fresh = aggregate.aggregate(tmp_path)
    assert fresh[env]["policies"]["ppo"]["seeds"] == [0]
    merged = publish.carry_over(fresh, published)
    assert merged[env]["policies"]["ppo"] == {**published[env]["policies"]["ppo"],
                                              publish.CARRIED_OVER: True}
    assert list(merged[env]["policies"]) == list(published[env]["policies"])


def test_publishing_again_keeps_a_reproduced_representative_and_writes_nothing_half(tmp_path):
    from ikbranch_gym.train import publish

    root = tmp_path / "root"
    env = _synthetic_root(root, np.array([np.full(20, 0.9), np.full(20, 0.5)]),
                          rival=np.full(20, 0.2))
    records = aggregate.aggregate(root)
    seed = records[env]["policies"]["ppo"]["representative_seed"]
    trial = sweep.run_dir(root, env, "ppo", seed)
    out, models = tmp_path / "out", tmp_path / "models"
    # A representative whose model is missing: an error before any file is written.
    with pytest.raises(FileNotFoundError, match="representative seed"):
        publish.publish(root, records, out=out, models=models, store=root)
    assert not out.exists() and not models.exists()
    (trial / "model.zip").write_bytes(b"trained")
    publish.publish(root, records, out=out, models=models, store=root)
    model = models / "ToolTransfer-v1" / "ppo.zip"
    record = out / "ToolTransfer-v1" / "ppo.json"
    assert model.read_bytes() == b"trained"
    first = record.read_text()
    # The same seed re-run elsewhere (its model not under this root, its wall times new):
    # the committed model and record stay.
    (trial / "model.zip").unlink()
    evaluation = json.loads((trial / "evaluation.json").read_text())
    evaluation["train_minutes"] = 99.0
    (trial / "evaluation.json").write_text(json.dumps(evaluation))
    publish.publish(root, aggregate.aggregate(root), out=out, models=models, store=root)
    assert model.read_bytes() == b"trained" and record.read_text() == first
    # Another outcome of that seed is a new trial: its model is needed again.
    evaluation["policy"]["returns"][0] -= 1.0
    (trial / "evaluation.json").write_text(json.dumps(evaluation))
    with pytest.raises(FileNotFoundError):
        publish.publish(root, aggregate.aggregate(root), out=out, models=models, store=root)


def test_a_row_is_not_carried_over_onto_other_baselines(tmp_path):
    from ikbranch_gym.train import publish

    env = _synthetic_root(tmp_path, np.full((2, 20), 0.9), rival=np.full(20, 0.2))
    published = aggregate.aggregate(tmp_path)
    fresh = json.loads(json.dumps(published))
    del fresh[env]["policies"]["ppo"]
    fresh[env]["policies"]["paper_rule"]["mean_return"] += 1.0
    with pytest.raises(ValueError, match=r"paper_rule differs .* re-run their trials"):
        publish.carry_over(fresh, published)


def test_a_trials_record_is_written_whole(tmp_path, monkeypatch):
    # A record appears complete or not at all (a resumed sweep skips a trial whose record
    # exists): its folders made, JSON with a final newline, nothing left beside it.
    import os

    path = sweep.run_dir(tmp_path, "IKBranch/ToolTransfer-v1", "ppo", 0) / "evaluation.json"
    sweep._write_json(path, {"seed": 0, "returns": [-1.5]})
    assert path.read_text() == '{\n "seed": 0,\n "returns": [\n  -1.5\n ]\n}\n'
    assert [p.name for p in path.parent.iterdir()] == ["evaluation.json"]

    def interrupted(source, target):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        sweep._write_json(path, {"seed": 0, "returns": [-2.5]})
    assert json.loads(path.read_text())["returns"] == [-1.5]
    assert [p.name for p in path.parent.iterdir()] == ["evaluation.json"]


def test_the_trial_archive_is_committed_not_ignored():
    # A root-level "runs/" rule once matched docs/results/sweep/trials/runs: every archived
    # trial stayed out of git, and the next checkout could not re-aggregate them.
    import subprocess

    # A staged trial's model is committed too: the run that trained it may be gone.
    for probe in (sweep.run_dir(sweep.ARCHIVE, "IKBranch/ToolTransfer-v1", "ppo", 0)
                  / "evaluation.json",
                  sweep.run_dir(sweep.staged_root(sweep.ARCHIVE), "IKBranch/ToolTransfer-v1",
                                "ppo", 0) / sweep.MODEL):
        result = subprocess.run(["git", "check-ignore", "--no-index", "-q", str(probe)],
                                cwd=sweep.ROOT, check=False)
        assert result.returncode == 1, f"{probe} is ignored by .gitignore"


def test_a_sweeps_runs_land_under_the_working_directory_by_default():
    # Not inside the package: an installed package's directory is no place for runs.
    from ikbranch_gym.train import sweep

    args = sweep.parser().parse_args(["--env", "IKBranch/ToolTransfer-v1"])
    assert args.root == Path("runs") / "sweep" and not args.root.is_absolute()


def test_learning_beats_planning_only_counts_industrial_arms_and_the_lower_bound():
    # ToolTransfer's arm is one of the papers': its row never meets the goal, however high.
    # On the IRB 2600 a point above 0.5 whose interval reaches below it does not either.
    from ikbranch_gym.train.publish import goal_lines

    def record(improvement):
        row = {"success": [1.0] * 3, "gap": [0.0] * 3, "decision_ms": 0.0,
               "improvement": {"paper_rule": [0.9, 0.8, 1.0], "receding_dp": improvement}}
        return {"policies": {"paper_rule": {}, "receding_dp": {}, "bc_maskable_ppo": row}}

    def verdict(records):
        return next(line for line in goal_lines(records) if "beats receding_dp" in line)

    papers = {"IKBranch/ToolTransfer-v1": record([0.9, 0.85, 0.95])}
    assert "beats receding_dp" not in " ".join(goal_lines(papers))
    below = {**papers, "IKBranch/IRB2600Screwing-v1": record([0.55, 0.49, 0.6])}
    assert verdict(below).endswith(
        "**not met** (best: IRB2600Screwing-v1 bc_maskable_ppo 0.550 [0.490, 0.600])")
    above = {**below, "IKBranch/KukaKR6-v1": record([0.6, 0.51, 0.7])}
    assert verdict(above).endswith(": met (KukaKR6-v1 bc_maskable_ppo 0.600 [0.510, 0.700])")
