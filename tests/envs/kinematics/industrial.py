"""Shared checks for the industrial arms (OPW family, Universal Robots): independent
elementary transforms, exact round trips and numerical multi-start solvers.

Nothing here calls the package's rotation helpers: the transforms are written out again so
a sign slip in ``envs.kinematics`` cannot cancel against itself.
"""

from __future__ import annotations

import numpy as np

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


# ---------------------------------------------------------------- batched multi-start IK
# scipy's least_squares costs ~50 ms a start on these arms (numpy overhead per call); the
# completeness tests need thousands of starts per pose (UR5e: 256 branches), so they run
# one bounded Levenberg–Marquardt over every start at once, on the chain below (the arm's
# documented kinematics, not its code) with its exact Jacobian.


def joint_chain(arm) -> list[tuple]:
    """The arm's forward kinematics as steps: ("joint", axis, index, sign, offset), a
    turn by θ = q[index]·sign − offset about the current frame's axis, or ("fixed", T).

    OPW (opw_kinematics' convention, joint = (θ + offset)·sign): Rz(θ1)·T(a1, b, c1)·
    Ry(θ2)·T(0, 0, c2)·Ry(θ3)·T(a2, 0, c3)·Rz(θ4)·Ry(θ5)·Rz(θ6)·T(0, 0, c4). UR: UR's DH
    chain, Rz(θi)·Tz(di)·Tx(ai)·Rx(αi) with α = (π/2, 0, 0, π/2, −π/2, 0)."""
    from ikbranch_gym.envs.kinematics import OpwArm, UrArm

    if isinstance(arm, OpwArm):
        sign, offset = arm.sign_corrections, arm.offsets

        def joint(i, axis):
            return ("joint", axis, i, float(sign[i]), float(offset[i]))

        return [
            joint(0, "z"), ("fixed", trans(arm.a1, arm.b, arm.c1)),
            joint(1, "y"), ("fixed", trans(0, 0, arm.c2)),
            joint(2, "y"), ("fixed", trans(arm.a2, 0, arm.c3)),
            joint(3, "z"), joint(4, "y"), joint(5, "z"), ("fixed", trans(0, 0, arm.c4)),
        ]
    if isinstance(arm, UrArm):
        d = (arm.d1, 0.0, 0.0, arm.d4, arm.d5, arm.d6)
        a = (0.0, arm.a2, arm.a3, 0.0, 0.0, 0.0)
        alpha = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)
        steps = []
        for i in range(6):
            steps += [("joint", "z", i, 1.0, 0.0),
                      ("fixed", chain(trans(0, 0, d[i]), trans(a[i], 0, 0), rot("x", alpha[i])))]
        return steps
    raise TypeError(f"no chain for {arm.name}")


_PLANE = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}
_COLUMN = {"x": 0, "y": 1, "z": 2}


def chain_fk(steps, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Poses (n, 4, 4) of ``joint_chain`` steps for q (n, 6), and the geometric Jacobian
    (n, 6, 6): rows linear velocity of the output origin, then angular velocity."""
    frames = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    axes, origins = [], []
    for step in steps:
        if step[0] == "fixed":
            frames = frames @ step[1]
            continue
        _, axis, index, sign, offset = step
        axes.append(frames[:, :3, _COLUMN[axis]] * sign)  # d/dq of a turn by q·sign
        origins.append(frames[:, :3, 3].copy())
        theta = q[:, index] * sign - offset
        c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
        i, j = _PLANE[axis]
        ci, cj = frames[:, :3, i].copy(), frames[:, :3, j].copy()
        frames[:, :3, i], frames[:, :3, j] = ci * c + cj * s, cj * c - ci * s
    w = np.stack(axes, axis=-1)  # (n, 3, 6)
    lever = frames[:, :3, 3, None] - np.stack(origins, axis=-1)
    return frames, np.concatenate([np.cross(w, lever, axis=1), w], axis=1)


def _hat(v: np.ndarray) -> np.ndarray:
    zero = np.zeros_like(v[..., 0])
    return np.stack([np.stack([zero, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], zero, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], zero], -1)], -2)


def pose_error(steps, q: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """6-D pose error e (n, 6) = (p − p*, log(R·R*ᵀ)) and its exact Jacobian (n, 6, 6)
    (the rotation rows through the inverse left Jacobian of SO(3))."""
    frames, jacobian = chain_fk(steps, q)
    m = frames[:, :3, :3] @ target[:3, :3].T
    cos = np.clip((np.trace(m, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    sin = np.sin(theta)
    small = theta < 1e-6
    safe_theta = np.where(small, 1.0, theta)
    safe_sin = np.where(small, 1.0, np.maximum(sin, 1e-300))
    vee = 0.5 * np.stack([m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0],
                          m[:, 1, 0] - m[:, 0, 1]], axis=-1)  # sin θ · axis
    phi = vee * np.where(small, 1.0 + theta * theta / 6.0, theta / safe_sin)[:, None]
    coef = np.where(small, 1.0 / 12.0, 1.0 / safe_theta**2
                    - (1.0 + cos) / (2.0 * safe_theta * safe_sin))
    hat = _hat(phi)
    inverse = np.eye(3) - 0.5 * hat + coef[:, None, None] * (hat @ hat)
    error = np.concatenate([frames[:, :3, 3] - target[:3, 3], phi], axis=1)
    return error, np.concatenate([jacobian[:, :3], inverse @ jacobian[:, 3:]], axis=1)


def multistart_solutions(arm, pose: np.ndarray, starts: np.ndarray,
                         iterations: int = 200) -> np.ndarray:
    """The converged ends of a bounded Levenberg–Marquardt run from every row of ``starts``
    (n, 6) on the 6-D pose error, all at once.

    Steps are clipped to the real joint limits (joints on a bound whose gradient points
    outward are held there), so every end lies inside the limits, turns included and
    nothing wrapped. Damping follows Nielsen (1999): it lets the near-singular poses, whose
    valleys are 1e3 times longer than wide, converge within ``iterations``. A start
    converges when ``arm.fk`` of its end is ``pose`` within 1e-12 (iterations go on to a
    squared error of 1e-30, so its joints are pinned to ~1e-15 times the Jacobian's
    condition number); the others (held on a bound, in a local minimum, too slow) are
    dropped."""
    steps = joint_chain(arm)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    x = np.clip(np.array(starts, dtype=np.float64), lower, upper)
    damping, growth = np.full(len(x), 1e-3), np.full(len(x), 2.0)
    error, jacobian = pose_error(steps, x, pose)
    cost = np.einsum("ni,ni->n", error, error)
    active = np.ones(len(x), dtype=bool)
    for _ in range(iterations):
        index = np.flatnonzero(active)
        if index.size == 0:
            break
        jac, at, now = jacobian[index], x[index], error[index]
        gradient = np.einsum("nki,nk->ni", jac, now)
        held = ((at <= lower) & (gradient > 0)) | ((at >= upper) & (gradient < 0))
        free_jac = np.where(held[:, None, :], 0.0, jac)
        normal = np.einsum("nki,nkj->nij", free_jac, free_jac)
        diagonal = damping[index, None] * (1.0 + np.einsum("nii->ni", normal)) + held
        step = np.linalg.solve(normal + np.eye(6) * diagonal[:, :, None],
                               -np.where(held, 0.0, gradient)[..., None])[..., 0]
        trial = np.clip(at + step, lower, upper)
        trial_error, trial_jacobian = pose_error(steps, trial, pose)
        trial_cost = np.einsum("ni,ni->n", trial_error, trial_error)
        # Gain ratio: actual over predicted decrease of the (clipped) step.
        model = now + np.einsum("nki,ni->nk", jac, trial - at)
        predicted = cost[index] - np.einsum("nk,nk->n", model, model)
        gain = np.clip((cost[index] - trial_cost) / np.maximum(predicted, 1e-300), -1.0, 2.0)
        better = trial_cost < cost[index]
        accepted, rejected = index[better], index[~better]
        x[accepted], cost[accepted] = trial[better], trial_cost[better]
        error[accepted], jacobian[accepted] = trial_error[better], trial_jacobian[better]
        shrink = np.maximum(1.0 / 3.0, 1.0 - (2.0 * gain[better] - 1.0) ** 3)
        damping[accepted] = np.maximum(damping[accepted] * shrink, 1e-15)
        growth[accepted] = 2.0
        damping[rejected] *= growth[rejected]
        growth[rejected] *= 2.0
        active = (cost > 1e-30) & (damping < 1e10)
    converged = np.abs(arm.fk(x) - pose).max(axis=(-1, -2)) < 1e-12
    return x[converged]
