"""Reproduce the paper's worked example: ``python -m envs.worked_example``.

Solves both positions of Klyuiko (1986) with the anthropomorphic arm's closed-form IK,
prints all eight branches per position beside the paper's table, and ranks the 16 transfers
of the paper (plus the 48 involving the φ1 + 180° family) by total joint travel Σ|Δφ|.
"""

from __future__ import annotations

import numpy as np

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.paper_example import (
    PRINTED_MIN_TRAVEL_DEG,
    PRINTED_TABLE_DEG,
    example_poses,
)


def main() -> None:
    arm = make_arm("anthropomorphic")
    solutions, valid = arm.ik(example_poses())
    degrees = np.degrees(solutions)
    header = "  ".join(f"{name:>8}" for name in arm.joint_names)
    for position in (0, 1):
        print(f"\nPosition {position + 1}: all {valid[position].sum()} valid branches (degrees)")
        print(f"{'branch':<26}{header}   paper")
        for k, label in enumerate(arm.branch_labels):
            row = f"{position + 1}.{k + 1}"
            values = "  ".join(f"{v:8.2f}" for v in degrees[position, k])
            printed = PRINTED_TABLE_DEG.get(row)
            paper = f"   {row}: " + " ".join(f"{v:.2f}" for v in printed) if printed else ""
            print(f"{label:<26}{values}{paper}")

    travel = np.abs(degrees[0][:, None, :] - degrees[1][None, :, :]).sum(axis=-1)
    paper_pairs = travel[:4, :4]
    best = np.argwhere(np.isclose(paper_pairs, paper_pairs.min(), atol=1e-9))
    print("\nTotal travel Σ|Δφ| (degrees) for the paper's 16 transfers, rows 1.k → cols 2.k:")
    for i in range(4):
        print(f"  1.{i + 1}: " + "  ".join(f"{v:8.2f}" for v in paper_pairs[i]))
    pairs = ", ".join(f"1.{i + 1} -> 2.{j + 1}" for i, j in best)
    print(f"Minimum {paper_pairs.min():.2f}° ({pairs}); printed: {PRINTED_MIN_TRAVEL_DEG}°.")
    print(f"Over all 64 transfers incl. the φ1 + 180° family the minimum is {travel.min():.2f}°.")


if __name__ == "__main__":
    main()
