"""The worked example of Klyuiko (1986): a tool moved from a rack into a milling spindle.

Data exactly as printed (mm, degrees); ``example_poses()`` converts to SI at the boundary.
"""

from __future__ import annotations

import numpy as np

from .frames import pose_from_points

#: Tool points in the gripper frame: a = c = 50 mm, b = 350 mm (the tool axis is y3).
TOOL_ABC_MM = (50.0, 350.0, 50.0)

#: The four points O, (a,0,0), (0,b,0), (0,0,c) of each position, world frame, mm.
POSITION_POINTS_MM = {
    1: ((525, 1272, 800), (525, 1272, 750), (875, 1272, 800), (525, 1222, 800)),
    2: ((-1475, 1290, 1100), (-1475, 1340, 1100), (-1475, 1290, 1450), (-1425, 1290, 1100)),
}

#: The paper's table as printed (degrees), rows 1.1–1.4 and 2.1–2.4 (φ1 … φ6).
PRINTED_TABLE_DEG = {
    "1.1": (-22.43, 22.97, -85.88, 69.82, 80.0, 64.70),
    "1.2": (-22.43, 22.97, -85.88, -110.18, -80.0, -115.30),
    "1.3": (-22.43, -62.91, 85.88, 99.15, 69.44, -24.64),
    "1.4": (-22.43, -62.91, 85.88, -80.85, -69.44, -155.37),
    "2.1": (48.83, 4.16, -19.98, 0.0, 105.81, 41.17),
    "2.2": (48.83, 4.16, -19.98, -180.0, -105.81, -138.83),
    "2.3": (48.83, -15.81, 19.98, 0.0, 85.84, 41.17),
    "2.4": (48.83, -15.81, 19.98, -180.0, -85.84, -138.83),
}

#: Printed entries that no configuration of the arm reproduces, (row, joint index) ->
#: the value forward kinematics confirms. Evidence in docs/kinematics.md.
TABLE_MISPRINTS_DEG = {("1.4", 5): 155.36}

#: The minimum total travel Σ|Δφ| the paper reports (1.1 → 2.1 and 1.2 → 2.2), degrees.
PRINTED_MIN_TRAVEL_DEG = 275.15

#: Branch index of each printed row in ``AnthropomorphicArm.branch_labels`` (front shoulder,
#: elbow up for rows .1/.2, wrist + for the odd rows).
ROW_BRANCH = {"1": 0, "2": 1, "3": 2, "4": 3}


def example_poses() -> np.ndarray:
    """The two target poses (2, 4, 4) in metres."""
    a, b, c = (value / 1000.0 for value in TOOL_ABC_MM)
    points = np.array([POSITION_POINTS_MM[1], POSITION_POINTS_MM[2]], dtype=np.float64) / 1000.0
    return pose_from_points(points, a, b, c)


def corrected_table_deg() -> dict[str, np.ndarray]:
    """The printed table with the documented misprints replaced."""
    table = {row: np.array(values) for row, values in PRINTED_TABLE_DEG.items()}
    for (row, joint), value in TABLE_MISPRINTS_DEG.items():
        table[row][joint] = value
    return table


#: The tool rack of the milling cell (an extension of the worked example, which shows one
#: slot): slot k holds a tool at position 1 shifted along Y0 by this much (m). Slot 0 is the
#: paper's position 1; the others continue the rack away from the machine.
RACK_SLOT_OFFSETS_Y = (0.0, -0.22, -0.44)


def rack_slot_poses() -> np.ndarray:
    """Gripper poses (S, 4, 4) at the rack's slots, in metres (slot 0 = position 1)."""
    position1 = example_poses()[0]
    slots = np.repeat(position1[None], len(RACK_SLOT_OFFSETS_Y), axis=0)
    slots[:, 1, 3] += RACK_SLOT_OFFSETS_Y
    return slots
