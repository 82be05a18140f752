"""Rule baselines: the paper's minimum-travel rules, random and fixed branches.

None of them looks at obstacles: the paper's rule (Klyuiko 1986) ranks branches by joint
travel alone, and the naive controllers ignore even that.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from .base import Baseline, first_within


class PaperRule(Baseline):
    """The paper's exhaustive rule at each transition: of every valid branch of the next
    waypoint take the one of least travel Σ w_j|Δq_j| (the env's travel, so prismatic
    joints count with its ``prismatic_scale``); ties go to the lower branch index.

    Myopic like the paper: it ignores obstacles, time and every later waypoint. At a free
    start (the arm already stands at waypoint 0) all branches cost nothing: branch order
    decides.
    """

    name = "paper_rule"

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        return first_within(np.where(mask, self.move_travel(waypoint), np.inf))


class PaperPairRule(Baseline):
    """The paper's full form, a transfer between two positions: of all K×K branch pairs
    (a at the next waypoint, b at the one after) take the pair of least total travel, and
    move to a. In the worked example these are the 16 variants (64 with the back-shoulder
    family) and the move to position 1 is free; in a longer task the move from where the
    arm stands to a counts too, so the rule stays a two-position transfer re-decided at
    every step. On the last waypoint it is :class:`PaperRule`. Obstacles are ignored.
    """

    name = "paper_pair_rule"

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        env = self.env
        # Set by reset; ``predict`` refuses to act before one.
        assert env.task is not None and env.ladder is not None
        assert env.candidates is not None and env.valid is not None
        move = np.where(mask, self.move_travel(waypoint), np.inf)
        if waypoint + 1 >= env.task.n_waypoints:
            return first_within(move)
        # (K, K): from every candidate of this waypoint to every one of the next.
        transfer, _ = env.ladder.motion(env.candidates[waypoint], waypoint + 1)
        allowed = (mask[:, None] & env.valid[waypoint + 1][None, :]
                   & ~env.ladder.blocked(env.candidates[waypoint], waypoint + 1))
        total = np.where(allowed, move[:, None] + transfer, np.inf)
        # Row-major flat index: ties go to the lower a, then the lower b.
        return first_within(total) // env.arm.n_branches


class RandomBranch(Baseline):
    """Uniform over the valid branches, from its own generator (``seed``)."""

    name = "random"

    def __init__(self, env: gym.Env, seed: int | None = None) -> None:
        super().__init__(env)
        self.rng = np.random.default_rng(seed)

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        return int(self.rng.choice(np.flatnonzero(mask)))


class FixedBranch(Baseline):
    """Always the same branch, as a controller with a fixed configuration flag would.

    ``branch`` is an index or a label of ``arm.branch_labels``. Where it is invalid the
    nearest valid branch is taken: fewest differing label parts (``front/elbow-up/wrist+``
    has three), then the nearest index: a naive controller flips as few flags as it can.
    """

    name = "fixed"

    def __init__(self, env: gym.Env, branch: int | str = 0) -> None:
        super().__init__(env)
        labels = self.env.arm.branch_labels
        if isinstance(branch, str) and branch in labels:
            branch = labels.index(branch)
        elif isinstance(branch, str) and branch.lstrip("-").isdigit():
            branch = int(branch)
        if isinstance(branch, str) or not 0 <= int(branch) < len(labels):
            raise ValueError(
                f"branch must be an index in [0, {len(labels)}) or one of {', '.join(labels)};"
                f" got {branch!r}"
            )
        self.branch = int(branch)
        parts = [label.split("/") for label in labels]
        mine = parts[self.branch]
        differing = np.array([sum(a != b for a, b in zip(mine, p, strict=False)) for p in parts])
        distance = np.abs(np.arange(len(labels)) - self.branch)
        #: Branches in order of preference (the fixed one first).
        self.preference = np.lexsort((np.arange(len(labels)), distance, differing))

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        return int(next(b for b in self.preference if mask[b]))
