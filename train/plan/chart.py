"""The plan's map: waypoints × branches, each cell coloured by what the branch is there,
the chosen planner's line drawn through it (``--map map.png``; after Robotmaster's map of
turn and configuration: why a line was chosen, and where no other could go)."""

from __future__ import annotations

import io
import itertools

import numpy as np

from .playing import Plan, PlanRun

#: The states of a cell, in the order they are decided (the first that holds), with
#: their legend text and colour.
STATES: tuple[tuple[str, str], ...] = (
    ("out of reach", "#4d4d4d"),
    ("outside the joint limits", "#bdbdbd"),
    ("left out (continuity, singularity margins)", "#b8a9d9"),
    ("configuration collides", "#e06666"),
    ("near a singularity", "#f2d15c"),
    ("free", "#b6e3b0"),
)
OUT_OF_REACH, OUTSIDE_LIMITS, LEFT_OUT, COLLIDES, NEAR_SINGULAR, FREE = range(len(STATES))


def cell_states(plan: Plan) -> np.ndarray:
    """(N, K) int: each branch's state at each waypoint (``STATES`` order), from the IK
    of the waypoints (their poses in the fk frame), the ladder every planner chose from
    and the plan's singularity margins."""
    from ikbranch_gym.envs.kinematics.singularities import (
        has_singularity_rules,
        singularity_margins,
    )

    arm = plan.arm
    candidates, exists = arm.ik(plan.targets)
    reaches = arm.reaches(plan.targets)
    states = np.full(exists.shape, FREE, dtype=np.int64)
    if has_singularity_rules(arm):
        margins = singularity_margins(arm, candidates)
        with np.errstate(invalid="ignore"):
            near = ((margins.wrist < plan.singularity_margin)
                    | (margins.elbow < plan.singularity_margin)
                    | (margins.shoulder < plan.shoulder_margin))
        states[near] = NEAR_SINGULAR
    states[plan.ladder_valid & plan.ladder_endpoint] = COLLIDES
    states[exists & ~plan.ladder_valid] = LEFT_OUT
    states[~exists] = OUTSIDE_LIMITS
    states[~reaches] = OUT_OF_REACH
    return states


def map_png(plan: Plan, run: PlanRun | None = None) -> bytes:
    """The map as PNG bytes: a row per branch (its label), a column per waypoint, the
    run's branches (default the chosen planner's) joined by a line; a move that
    reconfigures the arm is drawn dashed."""
    import matplotlib

    matplotlib.use("Agg")  # files only: no display needed
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    run = plan.chosen_run if run is None else run
    states = cell_states(plan)
    n, k = states.shape
    labels = plan.arm.branch_labels
    height = min(2.0 + 0.22 * k, 40.0)
    figure, axes = plt.subplots(figsize=(min(4.0 + 0.18 * n, 40.0), height))
    axes.imshow(states.T, cmap=ListedColormap([colour for _, colour in STATES]),
                vmin=0, vmax=len(STATES) - 1, aspect="auto", interpolation="nearest",
                origin="lower")
    steps = run.reached
    moves = plan.moves(run)
    for (a, b), move in zip(itertools.pairwise(steps), moves[1:], strict=True):
        axes.plot([a.waypoint, b.waypoint], [a.branch, b.branch], color="black", lw=1.6,
                  ls="--" if move.reconfiguration else "-")
    axes.plot([s.waypoint for s in steps], [s.branch for s in steps], "o", color="black",
              ms=3)
    for boundary in np.flatnonzero(np.diff(plan.segments)) + 0.5:
        axes.axvline(boundary, color="#1f4e99", lw=1.2, ls=":")
    axes.set_xlabel("waypoint (segments split by dotted lines)")
    axes.set_yticks(range(k))
    axes.set_yticklabels(labels if k <= 64 else [""] * k, fontsize=6)
    axes.set_ylabel("branch" if k <= 64 else f"branch (0 … {k - 1})")
    axes.set_title(f"{plan.arm.name}: {run.name}, {len(steps)} of {n} waypoints")
    axes.legend(handles=[Patch(color=colour, label=text) for text, colour in STATES],
                loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    return buffer.getvalue()
