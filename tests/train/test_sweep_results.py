"""The multi-seed results of docs/results.md (``train/publish.py``): each row's committed
model (its representative seed) plays its published held-out episodes again, and the
published intervals follow from the stored per-episode numbers."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

from ikbranch_gym.agents.sb3 import SB3Policy
from ikbranch_gym.train.publish import (
    MODELS,
    README,
    README_BEGIN,
    README_END,
    RESULTS_MD,
    SWEEP_RESULTS,
    readme_summary,
    render,
)
from tests.train.test_results import judged_episode

AGGREGATE = SWEEP_RESULTS / "aggregate.json"
#: Episodes replayed per model (of the 200 published): the first ones, in order.
REPLAYED = 12


def published_rows() -> list:
    records = json.loads(AGGREGATE.read_text()) if AGGREGATE.exists() else {}
    return [pytest.param(env_id, algo, id=f"{env_id}-{algo}")
            for env_id, record in records.items()
            for algo, row in record["policies"].items() if row.get("representative_seed")
            is not None]


def _trial(env_id: str, algo: str) -> dict:
    return json.loads((SWEEP_RESULTS / env_id.split("/")[-1] / f"{algo}.json").read_text())


def test_the_sweep_is_published_with_its_models():
    records = json.loads(AGGREGATE.read_text())
    assert records, "no published sweep"
    for env_id, algo in ((p.values[0], p.values[1]) for p in published_rows()):
        trial = _trial(env_id, algo)
        assert (MODELS.parent / trial["model"]).exists()
        row = records[env_id]["policies"][algo]
        assert trial["seed"] in row["seeds"] and trial["seed"] == row["representative_seed"]
        # The stored episodes give the stored summary (not computed from other episodes).
        policy = trial["policy"]
        assert len(policy["returns"]) == len(policy["successes"]) == records[env_id]["episodes"]
        assert policy["success_rate"] == pytest.approx(np.mean(policy["successes"]), abs=1e-12)
        assert policy["mean_return"] == pytest.approx(np.mean(policy["returns"]), abs=1e-9)
        assert np.all(np.array(policy["returns"]) <= np.array(trial["oracle"]["returns"]) + 1e-9)
        # The row's command is the one command that trains it, as a reader types it.
        command = trial["command"]
        assert command.startswith(f"python -m train --algo {algo} --env {env_id} ")
        assert command.count("-m train") == 1, command


def test_the_published_mean_gaps_follow_from_the_archived_returns():
    # The mean gap of every row, from the per-task returns the archive holds (the
    # learned rows' every seed, the baselines' one run) against the oracle's.
    from ikbranch_gym.train.aggregate import load
    from ikbranch_gym.train.sweep import ARCHIVE

    archive = load(ARCHIVE)
    for env_id, record in json.loads(AGGREGATE.read_text()).items():
        baselines = archive[env_id]["baselines"]["policies"]
        oracle = np.array(baselines["dp_oracle"]["returns"])
        for name, row in record["policies"].items():
            runs = ([trial["policy"]["returns"] for trial in archive[env_id]["trials"][name]]
                    if row.get("seeds") else [baselines[name]["returns"]])
            expected = (oracle.mean() - np.mean(runs)) / abs(oracle.mean())
            assert row["mean_gap"] == pytest.approx(expected, rel=1e-12, abs=1e-15), (
                env_id, name)


def test_docs_results_md_is_rendered_from_the_published_records():
    assert RESULTS_MD.read_text() == render()


def test_the_readme_shows_the_published_aggregate():
    lines = README.read_text().split("\n")
    table = lines[lines.index(README_BEGIN) + 1:lines.index(README_END)]
    assert table == readme_summary(json.loads(AGGREGATE.read_text()))


@pytest.mark.regression
@pytest.mark.parametrize(("env_id", "algo"), published_rows())
def test_a_published_model_replays_its_first_episodes_and_their_successes_hold(
        env_id, algo, monkeypatch):
    # The returns are a snapshot (the stored returns came from this code): a change in
    # what the env, the checker or the model loader computes shows up here. To rounding,
    # not bit for bit: the returns were stored when batches went through numpy IK solvers,
    # whose arctan2 and arccos differ from the C library's (what the one compiled IK calls
    # since) in the last bit; replayed returns moved by at most 9.3e-14. A changed
    # decision moves a return by a whole move's price.
    # The successes are judged from the same episodes' moves by a collision checker of its
    # own (the loop backend, not the env's compiled one): the published per-episode
    # successes must hold up.
    monkeypatch.chdir(MODELS.parent)
    trial = _trial(env_id, algo)
    env = gym.make(env_id, **trial["env_kwargs"])
    policy = SB3Policy.load(trial["model"], env)
    for e in range(REPLAYED):
        episode, judged = judged_episode(env, policy, trial["task_seed"] + e, "loop")
        assert episode.reward == pytest.approx(trial["policy"]["returns"][e], rel=0,
                                               abs=1e-9), e
        assert judged == trial["policy"]["successes"][e], e
