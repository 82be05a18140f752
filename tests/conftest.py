"""Settings every test folder shares."""

from __future__ import annotations

import pytest

#: The longest tests (a fresh venv and its installs; a Ray cluster and its trials; a
#: training run that resumes; the demo) run first: with ``-n 2`` the workers start on them
#: while the rest wait, instead of the whole run waiting on one of them at its end.
FIRST = frozenset({
    "tests/test_package.py::test_the_wheel_installs_into_a_fresh_venv_with_core_extras_then_trains",
    "tests/train/test_sweep.py::test_tiny_sweep_writes_run_directories_and_resumes",
    "tests/train/test_train.py::test_training_run_writes_a_complete_run_directory_and_resumes",
    "tests/train/test_cli.py::test_the_demo_runs_end_to_end_on_a_tiny_budget",
})


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    items.sort(key=lambda item: item.nodeid not in FIRST)  # stable: the rest keep their order
