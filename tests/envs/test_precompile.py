"""``ikbranch warm-up`` (``envs.precompile``): every kernel compiled or loaded ahead of time."""

from __future__ import annotations

import pytest

from ikbranch_gym.agents import dp
from ikbranch_gym.envs import jit, precompile
from ikbranch_gym.envs.kinematics import compiled
from ikbranch_gym.train import cli


def test_warm_up_readies_the_kernels_and_names_their_caches(capsys):
    assert cli.main(["warm-up", "--processes", "1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("kernels ready in ")
    for directory in (jit.cache_directory(), compiled.cache_directory(), dp.cache_directory()):
        assert str(directory) in out


def test_warm_up_takes_one_or_two_processes(capsys):
    with pytest.raises(SystemExit) as exit_info:
        precompile.main(["--processes", "3"])
    assert exit_info.value.code == 2
    assert "invalid choice: 3" in capsys.readouterr().err
