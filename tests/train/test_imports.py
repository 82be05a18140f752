"""The train modules import each other in one direction: no cycle, and statistics,
publication and rendering of results layered as

    train.sweep      the sweep's trials and their layout on disk
        ↑
    train.publish    writes and renders (archive, models, plots, docs/results.md, README)
        ↑                     ↑
    train.aggregate           train.results
    (the statistics: rliable  (the earlier single-seed records)
     intervals; its --publish
     hands them to publish)

Every import counts: at the top of a module or inside a function, absolute
(``ikbranch_gym.train.x``, ``train.x``), relative, ``from ikbranch_gym.train import x``,
and a module named in a string (``importlib.import_module("ikbranch_gym.train.x")``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import ikbranch_gym.train as train

TRAIN = Path(train.__file__).resolve().parent
MODULES = sorted(path.stem for path in TRAIN.glob("*.py"))
#: A module may import only modules of a lower layer (of these four).
LAYERS = {"sweep": 0, "publish": 1, "aggregate": 2, "results": 2}
PREFIXES = ("ikbranch_gym.train", "train")


def _train_module(name: str | None) -> str | None:
    """The train module ``name`` (dotted, absolute) refers to, if it is one."""
    for prefix in PREFIXES:
        if name and name.startswith(prefix + "."):
            first = name[len(prefix) + 1:].split(".")[0]
            return first if first in MODULES else None
    return None


def imports(source: str) -> set[str]:
    """The train modules the module with this source imports, anywhere in it."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(filter(None, (_train_module(alias.name) for alias in node.names)))
        elif isinstance(node, ast.ImportFrom):
            if node.level == 1:  # from .x import y / from . import x
                names = [node.module] if node.module else [a.name for a in node.names]
                found.update(name.split(".")[0] for name in names
                             if name.split(".")[0] in MODULES)
            elif node.level == 0 and node.module in PREFIXES:  # from train import x
                found.update(a.name for a in node.names if a.name in MODULES)
            elif node.level == 0:
                module = _train_module(node.module)
                found.update([module] if module else [])
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            module = _train_module(node.value)
            found.update([module] if module and node.value.count(" ") == 0 else [])
    return found


def graph() -> dict[str, set[str]]:
    return {name: imports((TRAIN / f"{name}.py").read_text()) - {name} for name in MODULES}


def cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """A cycle of ``edges`` (its modules in order), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for target in sorted(edges.get(node, ())):
            if state.get(target) == 1:
                return [*path[path.index(target):], target]
            if target not in state and (found := visit(target)):
                return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(edges):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_the_train_modules_import_each_other_without_a_cycle():
    edges = graph()
    assert set(LAYERS) <= set(edges)
    assert cycle(edges) is None, " -> ".join(cycle(edges) or [])


def test_statistics_publication_and_rendering_import_in_one_direction():
    edges = graph()
    wrong = [(source, target) for source in LAYERS for target in edges[source] & set(LAYERS)
             if LAYERS[target] >= LAYERS[source]]
    assert not wrong, f"imports against the layers {LAYERS}: {wrong}"
    # The layering is used, not vacuous: these are the imports it orders.
    assert {"sweep", "publish"} <= edges["aggregate"]
    assert "sweep" in edges["publish"] and "publish" in edges["results"]


@pytest.mark.parametrize(("source", "expected"), [
    ("from ikbranch_gym.train.publish import render\n", {"publish"}),
    ("def f():\n    from ikbranch_gym.train import aggregate, sweep\n", {"aggregate", "sweep"}),
    ("import ikbranch_gym.train.results as r\n", {"results"}),
    ("from train.aggregate import main\n", {"aggregate"}),
    ("from . import publish\nfrom .sweep import ROOT\n", {"publish", "sweep"}),
    ("import importlib\nimportlib.import_module('ikbranch_gym.train.sweep')\n", {"sweep"}),
    ("from ikbranch_gym.envs import files\nimport train_other\n", set()),
])
def test_every_kind_of_import_is_seen(source, expected):
    assert imports(source) == expected


def test_a_cycle_is_found():
    assert cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None
