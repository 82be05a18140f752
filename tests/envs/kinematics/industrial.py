"""Shared checks for the industrial arms (OPW family, Universal Robots): independent
elementary transforms, exact round trips and a numerical multi-start solver.

Nothing here calls the package's rotation helpers: the transforms are written out again so
a sign slip in ``envs.kinematics`` cannot cancel against itself.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

FK_TOL = 1e-9
#: A sampled configuration counts as returned when one valid branch has every joint within
#: this of it, in absolute joint values (no modulo 2π: turns count).
SAME_Q = 1e-9


def rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    out = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    out[i, i], out[i, j], out[j, i], out[j, j] = c, -s, s, c
    return out


def trans(x: float, y: float, z: float) -> np.ndarray:
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


def chain(*factors: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    for factor in factors:
        out = out @ factor
    return out


def sample(arm, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (n, arm.dof))


def assert_round_trip(arm, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """FK -> IK -> FK at FK_TOL for every valid branch, and q itself among them exactly."""
    pose = arm.fk(q)
    solutions, valid = arm.ik(pose)
    assert solutions.shape == (*q.shape[:-1], arm.n_branches, arm.dof)
    assert np.all(np.isnan(solutions[~valid])) and np.all(np.isfinite(solutions[valid]))
    assert np.all(arm.within_limits(solutions[valid]))
    reposed = arm.fk(np.where(valid[..., None], solutions, arm.home))
    error = np.abs(reposed - pose[..., None, :, :]).max(axis=(-1, -2))
    assert error[valid].max() < FK_TOL, error[valid].max()
    gap = np.abs(solutions - q[..., None, :]).max(axis=-1)
    nearest = np.where(valid, gap, np.inf).min(axis=-1)
    assert np.all(nearest < SAME_Q), (nearest.max(), q[np.argmax(nearest)])
    return solutions, valid


def numerical_solutions(arm, pose: np.ndarray, starts: int, rng) -> np.ndarray:
    """Converged least-squares solutions of fk(q) = pose from random starts inside the
    limits (bounded: the real limits, turns included)."""
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]

    def residual(x):
        return (arm.fk(x) - pose)[:3].ravel()

    found = []
    for start in rng.uniform(lower, upper, size=(starts, arm.dof)):
        fit = least_squares(residual, start, bounds=(lower, upper), xtol=1e-15, ftol=1e-15,
                            gtol=1e-15, max_nfev=400)
        if np.abs(fit.fun).max() < 1e-10:
            found.append(fit.x)
    return np.array(found).reshape(-1, arm.dof)


def assert_complete(arm, n_poses: int, starts: int, seed: int) -> tuple[int, int, int]:
    """Every numerical solution is one of the returned branches (absolute joint values).

    Returns (solutions found, distinct branches they matched, branches returned)."""
    rng = np.random.default_rng(seed)
    found, matched, returned = 0, set(), 0
    for index, q in enumerate(sample(arm, n_poses, seed + 1)):
        pose = arm.fk(q)
        solutions, valid = arm.ik(pose)
        returned += int(valid.sum())
        for x in numerical_solutions(arm, pose, starts, rng):
            found += 1
            gap = np.where(valid, np.abs(solutions - x).max(axis=-1), np.inf)
            assert gap.min() < 1e-6, f"missed {x} (nearest branch {gap.min():.2e} away)"
            matched.add((index, int(np.argmin(gap))))
    return found, len(matched), returned
