"""docs/other_libraries.md: its Python blocks run, and what it says about masks around an
autoreset holds."""

from __future__ import annotations

import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym  # noqa: F401

PAGE = Path(__file__).resolve().parents[2] / "docs" / "other_libraries.md"
ENV = "IKBranch/RodMechanism-v2"


def test_the_pages_python_blocks_run_and_the_ban_holds():
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(), re.S)
    assert len(blocks) == 4
    namespace: dict = {}
    exec(compile("\n".join(blocks), str(PAGE), "exec"), namespace)
    np.testing.assert_array_equal(namespace["same"], namespace["mask"])
    assert namespace["masks"].shape == (16, 4)
    results = namespace["results"]
    assert list(results["policies"]) == ["dp_oracle", "mine", "rule"]
    # As the page says: under NoBranch2 every row is the same, below the unrestricted optimum.
    returns = {name: m["mean_return"] for name, m in results["policies"].items()}
    assert len(set(returns.values())) == 1
    assert returns["dp_oracle"] == pytest.approx(-22.40, abs=0.005)
    from ikbranch_gym.agents.evaluation import evaluate
    from ikbranch_gym.envs.seeds import TEST_SEED

    free = evaluate(ENV, [], 50, TEST_SEED)["policies"]["dp_oracle"]["mean_return"]
    assert free == pytest.approx(-15.79, abs=0.005)


def ends(mode: str):
    """Random masked play of 2 sub-envs until one episode ends; the infos around it."""
    envs = gym.make_vec(ENV, num_envs=2, vectorization_mode="vector_entry_point",
                        autoreset_mode=mode)
    _, info = envs.reset(seed=0)
    rng = np.random.default_rng(0)
    while True:
        actions = np.array([rng.choice(np.flatnonzero(row)) for row in info["action_mask"]])
        _, reward, terminated, _, info = envs.step(actions)
        if terminated.any():
            return envs, terminated, reward, info


def test_next_step_autoreset_masks():
    envs, ended, _, info = ends("next_step")
    assert info["action_mask"][ended].all()  # the episode is over: any action
    _, reward, terminated, _, info = envs.step(np.zeros(2, dtype=np.int64))
    assert np.all(reward[ended] == 0) and not terminated[ended].any()  # the action ignored
    assert np.all(info["waypoint"][ended] == 0)  # the reset's info, its new mask
    assert not info["action_mask"][ended].all()


def test_same_step_autoreset_masks():
    _, ended, _, info = ends("same_step")
    assert np.array_equal(info["_final_obs"], ended)
    assert np.all(info["waypoint"][ended] == 0)  # already the next episode ...
    assert not info["action_mask"][ended].all()  # ... and its mask
    assert info["final_info"]["action_mask"][ended].all()  # the finished one's: all True
