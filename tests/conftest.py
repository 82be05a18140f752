"""Settings every test folder shares."""

from __future__ import annotations

import pytest

#: Tests that take minutes on their own (a fresh venv compiles every kernel) run first:
#: with ``-n 2`` one worker starts on them while the other takes the rest, instead of
#: the whole run waiting on them at its end.
FIRST = frozenset({
    "tests/test_package.py::test_the_wheel_installs_into_a_fresh_venv_with_core_extras_then_trains",
})


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    items.sort(key=lambda item: item.nodeid not in FIRST)  # stable: the rest keep their order
