"""The committed models reproduce the numbers published in docs/results.md."""

from __future__ import annotations

import json

import pytest

from agents.evaluation import evaluate
from train.results import EVAL_EPISODES, EVAL_SEED, RESULTS, ROOT, model_path

RECORDS = sorted(RESULTS.glob("*.json"))


def published_models():
    for path in RECORDS:
        record = json.loads(path.read_text())
        for algo in record["training"]:
            yield pytest.param(record, algo, id=f"{record['env']}-{algo}")


def test_every_published_record_has_its_models():
    assert RECORDS, "no published results"
    for path in RECORDS:
        record = json.loads(path.read_text())
        for algo in record["training"]:
            assert model_path(record["env"], algo).exists()


@pytest.mark.parametrize(("record", "algo"), published_models())
def test_committed_model_reproduces_its_published_row(record, algo, monkeypatch):
    monkeypatch.chdir(ROOT)  # the records name models by repository path
    name = str(model_path(record["env"], algo).relative_to(ROOT))
    assert record["episodes"] == EVAL_EPISODES and record["eval_seed"] == EVAL_SEED
    again = evaluate(record["env"], [name], EVAL_EPISODES, EVAL_SEED)["policies"]
    published = record["policies"]
    for policy in (name, "dp_oracle"):
        for metric in ("success_rate", "mean_return", "mean_travel", "mean_time",
                       "collision_rate", "invalid_rate", "optimality_gap"):
            assert again[policy][metric] == pytest.approx(published[policy][metric], abs=1e-9), (
                policy, metric)
