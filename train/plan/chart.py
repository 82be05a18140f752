"""The plan's map: waypoints × branches, each cell coloured by what the branch is there,
the chosen planner's line drawn through it (``--map map.png``; after Robotmaster's map of
turn and configuration: why a line was chosen, and where no other could go).

With a free tool axis (``--tool-axis``, ``--tool-tilt``) the rows are the tool's
orientations (spin, and tilt) instead, as on Robotmaster's map of the tool-axis angle:
each cell is the best state any branch of the configuration the plan holds at that
waypoint reaches there at that orientation (:func:`axis_states`), and the line is the
orientation the plan chose."""

from __future__ import annotations

import io
import itertools
from typing import Any

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


def axis_states(plan: Plan, run: PlanRun, states: np.ndarray) -> np.ndarray:
    """(N, S) int for a free tool axis of S orientations: at each waypoint the plan
    reached, the best state (``STATES``' last is best) of every rung at each orientation
    whose closed-form branch is the configuration the plan holds there; a waypoint the plan
    did not reach keeps the configuration before it (the first reached one's before)."""
    arm = plan.arm
    count = len(arm.angles)
    closed = np.asarray(arm.branch_closed_form)
    held = np.full(states.shape[0], -1)
    for step in run.reached:
        held[step.waypoint] = closed[step.branch]
    known = np.flatnonzero(held >= 0)
    if len(known):
        for w in range(len(held)):
            if held[w] < 0:
                before = known[known < w]
                held[w] = held[before[-1] if len(before) else known[0]]
    out = np.full((states.shape[0], count), OUT_OF_REACH, dtype=np.int64)
    for w, configuration in enumerate(held):
        mine = np.flatnonzero(closed == configuration)
        for rung in mine:
            sample = rung % count
            out[w, sample] = max(out[w, sample], states[w, rung])
    return out


def _sample_labels(arm: Any) -> list[str]:
    labels = []
    for angle, tilt, azimuth in zip(arm.angles, arm.tilts, arm.azimuths, strict=True):
        label = f"tool {np.degrees(angle):+g}°"
        if tilt > 0.0:
            label += f", tilt {np.degrees(tilt):g}° @ {np.degrees(azimuth):g}°"
        labels.append(label)
    return labels


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
    free_axis = hasattr(plan.arm, "branch_angles")
    rows = (lambda branch: branch % len(plan.arm.angles)) if free_axis else (lambda b: b)
    if free_axis:
        states = axis_states(plan, run, states)
    n, k = states.shape
    labels = _sample_labels(plan.arm) if free_axis else plan.arm.branch_labels
    height = min(2.0 + 0.22 * k, 40.0)
    figure, axes = plt.subplots(figsize=(min(4.0 + 0.18 * n, 40.0), height))
    axes.imshow(states.T, cmap=ListedColormap([colour for _, colour in STATES]),
                vmin=0, vmax=len(STATES) - 1, aspect="auto", interpolation="nearest",
                origin="lower")
    steps = run.reached
    moves = plan.moves(run)
    for (a, b), move in zip(itertools.pairwise(steps), moves[1:], strict=True):
        axes.plot([a.waypoint, b.waypoint], [rows(a.branch), rows(b.branch)], color="black",
                  lw=1.6, ls="--" if move.reconfiguration else "-")
    axes.plot([s.waypoint for s in steps], [rows(s.branch) for s in steps], "o",
              color="black", ms=3)
    for boundary in np.flatnonzero(np.diff(plan.segments)) + 0.5:
        axes.axvline(boundary, color="#1f4e99", lw=1.2, ls=":")
    axes.set_xlabel("waypoint (segments split by dotted lines)")
    axes.set_yticks(range(k))
    axes.set_yticklabels(labels if k <= 64 else [""] * k, fontsize=6)
    what = "tool orientation (in the configuration held)" if free_axis else "branch"
    axes.set_ylabel(what if k <= 64 else f"{what} (0 … {k - 1})")
    axes.set_title(f"{plan.arm.name}: {run.name}, {len(steps)} of {n} waypoints")
    axes.legend(handles=[Patch(color=colour, label=text) for text, colour in STATES],
                loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    return buffer.getvalue()
