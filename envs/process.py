"""Process continuity: inside a process segment the arm keeps its configuration.

A job's waypoints fall into **segments** (a weld seam, a deburring pass): consecutive
waypoints the tool must follow without the arm changing how it holds it. Between segments
the arm moves through the air and may reconfigure. A move into waypoint w lies *inside* a
segment when waypoint w − 1 belongs to the same segment.

Inside a segment a move **reconfigures** the arm, and is not allowed, when

- its configuration changes: the closed-form branch (shoulder, elbow, wrist;
  ``Arm.branch_closed_form``) of the configuration it ends in differs from the one it
  starts in. Between two close poses that is a wrist (or elbow, or shoulder) flip, or a
  pass through the singularity between the two (a controller refuses a linear move that
  changes its status bits); or
- a revolute joint steps by more than the **step limit** (rad): an unwind of a joint
  whose range exceeds a revolution, a near-singular whip. The limit must lie below π, so
  a turn change (a joint moving to another turn of the same pose, a step of 2π less the
  other way's) is always one. Prismatic joints are not limited.

Without a given limit it is **derived from the job**: per segment, the least step limit
under which some branch sequence follows it keeping one configuration (a minimax dynamic
programme over the ladder, :func:`least_limits`), and the job's limit is twice the
largest of those, at least ``MIN_DERIVED_LIMIT`` and at most ``MAX_LIMIT``: room for the
travel-optimal sequence beside the smoothest one, far below any flip or unwind.

Branches from which the rest of their segment cannot be followed (:func:`followable`)
are taken out of the ladder: every state the arm reaches through allowed moves then has an
allowed move onward, so an action mask is never empty for that reason. A segment that no
branch sequence follows is an error naming where it breaks.

Pure numpy and numba; no I/O, no RNG.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ikbranch_gym.envs.jit import njit
from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.compiled import writable

#: The derived limit's least value and factor over the job's hardest segment.
MIN_DERIVED_LIMIT = math.radians(10.0)
DERIVED_FACTOR = 2.0
#: Every limit lies in (0, MAX_LIMIT]: below half a revolution, so no turn change fits.
MAX_LIMIT = math.radians(179.0)
#: ``configuration`` of a state whose closed-form branch is unknown (the task's start).
UNKNOWN = -1


def segment_index(n_waypoints: int, starts: Sequence[int]) -> np.ndarray:
    """(N,) int64: the segment of each waypoint, segments beginning at the 0-based
    waypoints ``starts`` (0 implied); ``ValueError`` unless they increase strictly inside
    [0, N)."""
    values = [int(s) for s in starts]
    if any(not 0 <= s < n_waypoints for s in values):
        raise ValueError(f"segment starts must be waypoints in [0, {n_waypoints}), got {values}")
    if any(b <= a for a, b in itertools.pairwise(values)):
        raise ValueError(f"segment starts must increase strictly, got {values}")
    first = np.zeros(n_waypoints, dtype=np.int64)
    first[[s for s in values if s > 0]] = 1
    return np.cumsum(first)


def inside_moves(segments: np.ndarray) -> np.ndarray:
    """(N,) bool: the move into waypoint w lies inside a segment (w ≥ 1, same segment as
    w − 1)."""
    segments = np.asarray(segments)
    inside = np.zeros(len(segments), dtype=bool)
    inside[1:] = segments[1:] == segments[:-1]
    return inside


def check_limit(value: object, name: str = "max_joint_step") -> float:
    """``value`` (rad) as a float, ``ValueError`` outside (0, MAX_LIMIT]."""
    try:
        limit = float(value)  # type: ignore[arg-type]  # any object: the error says what
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number of radians, 'auto' or None, got "
                         f"{value!r}") from None
    if not (math.isfinite(limit) and 0.0 < limit <= MAX_LIMIT):
        raise ValueError(f"{name} must lie in (0, {MAX_LIMIT!r}] rad (0–179°: a step of "
                         f"half a revolution or more is a turn change), got {value!r}")
    return limit


def largest_steps(q0: np.ndarray, q1: np.ndarray, revolute: np.ndarray) -> np.ndarray:
    """(…,) the largest |Δq_j| over revolute joints j of q0 → q1 (…, dof) (0 for an arm
    without revolute joints; NaN rows give NaN)."""
    delta = np.abs(np.asarray(q1) - np.asarray(q0))[..., revolute]
    if delta.shape[-1] == 0:
        return np.zeros(delta.shape[:-1])
    return delta.max(axis=-1)


def blocked(q0: np.ndarray, config0: np.ndarray, q1: np.ndarray, config1: np.ndarray,
            limit: float, revolute: np.ndarray) -> np.ndarray:
    """(R, K) bool: the move from ``q0[r]`` (configuration ``config0[r]``, ``UNKNOWN``:
    no configuration check) to ``q1[k]`` (``config1[k]``) reconfigures the arm (module
    docstring); rows or columns with NaN are not blocked (they are no moves)."""
    out = np.empty((len(q0), len(q1)), dtype=np.bool_)
    _blocked(writable(np.ascontiguousarray(q0, dtype=np.float64)),
             writable(np.asarray(config0, dtype=np.int64)),
             writable(np.ascontiguousarray(q1, dtype=np.float64)),
             writable(np.asarray(config1, dtype=np.int64)), float(limit),
             writable(np.asarray(revolute, dtype=np.bool_)), out)
    return out


@njit
def _blocked(q0: np.ndarray, config0: np.ndarray, q1: np.ndarray, config1: np.ndarray,
             limit: float, revolute: np.ndarray, out: np.ndarray) -> None:
    """:func:`blocked` into ``out`` (R, K)."""
    for r in range(q0.shape[0]):
        for k in range(q1.shape[0]):
            out[r, k] = move_blocked(q0[r], config0[r], q1[k], config1[k], limit, revolute)


@njit(inline="always")
def move_blocked(q0: np.ndarray, config0: int, q1: np.ndarray, config1: int, limit: float,
                 revolute: np.ndarray) -> bool:
    """One move of :func:`blocked`."""
    if config0 != UNKNOWN and config0 != config1:
        return True
    for j in range(len(q0)):
        if revolute[j] and abs(q1[j] - q0[j]) > limit:  # NaN compares False: no move
            return True
    return False


def least_limits(candidates: np.ndarray, valid: np.ndarray, inside: np.ndarray,
                 configuration: np.ndarray, revolute: np.ndarray) -> np.ndarray:
    """(N,) per waypoint w: the least step limit under which some branch sequence leads
    from its segment's first waypoint to w keeping one configuration, valid branches only
    (+inf where none does at any limit: a configuration the segment cannot keep). The
    value at a segment's last waypoint is the least limit that follows the segment."""
    need = np.empty(len(candidates))
    _least_limits(writable(np.ascontiguousarray(candidates, dtype=np.float64)),
                  writable(np.asarray(valid, dtype=np.bool_)),
                  writable(np.asarray(inside, dtype=np.bool_)),
                  writable(np.asarray(configuration, dtype=np.int64)),
                  writable(np.asarray(revolute, dtype=np.bool_)), need)
    return need


@njit
def _least_limits(candidates: np.ndarray, valid: np.ndarray, inside: np.ndarray,
                  configuration: np.ndarray, revolute: np.ndarray, need: np.ndarray) -> None:
    """:func:`least_limits` into ``need``: per waypoint, each branch's least limit ``best``
    (0 at a segment's first waypoint, +inf where invalid), then over every move of one
    configuration between valid branches, the larger of the origin's and the move's
    largest revolute step, least over the origins."""
    n, k = valid.shape
    best, after = np.empty(k), np.empty(k)
    for w in range(n):
        if w == 0 or not inside[w]:
            for b in range(k):
                best[b] = 0.0 if valid[w, b] else np.inf
        else:
            for b in range(k):
                after[b] = np.inf
                if not valid[w, b]:
                    continue
                for a in range(k):
                    if not valid[w - 1, a] or configuration[a] != configuration[b]:
                        continue
                    via = max(best[a], _largest_step(candidates[w - 1, a], candidates[w, b],
                                                     revolute))
                    if via < after[b]:
                        after[b] = via
            best[:] = after
        least = np.inf
        for b in range(k):
            if best[b] < least:
                least = best[b]
        need[w] = least


@njit(inline="always")
def _largest_step(q0: np.ndarray, q1: np.ndarray, revolute: np.ndarray) -> float:
    """The largest |Δq_j| over revolute joints j of q0 → q1 (0 without any)."""
    step = 0.0
    for j in range(len(q0)):
        if revolute[j]:
            step = max(step, abs(q1[j] - q0[j]))
    return step


def followable(candidates: np.ndarray, valid: np.ndarray, inside: np.ndarray,
               configuration: np.ndarray, limit: float, revolute: np.ndarray) -> np.ndarray:
    """(N, K) bool: valid branches from which the rest of their segment can be followed
    without reconfiguring (every branch of a segment's last waypoint that is valid)."""
    n = len(candidates)
    alive = np.array(valid, dtype=bool)
    for w in range(n - 2, -1, -1):
        if not inside[w + 1]:
            continue
        moves = ~blocked(candidates[w], configuration, candidates[w + 1], configuration, limit,
                         revolute)
        alive[w] &= (moves & alive[w + 1][None, :]).any(axis=1)
    return alive


@dataclass(frozen=True, eq=False)
class Continuity:
    """A task's process continuity: ``inside`` (N,) which moves lie inside a segment,
    ``segments`` (N,) each waypoint's segment, ``limit`` the step limit (rad; derived or
    given), ``derived`` whether it was derived, ``needed`` (S,) per segment the least limit
    that follows it."""

    segments: np.ndarray
    inside: np.ndarray
    limit: float
    derived: bool
    needed: np.ndarray


def continuity(candidates: np.ndarray, valid: np.ndarray, segments: np.ndarray,
               configuration: np.ndarray, revolute: np.ndarray,
               max_joint_step: float | str, where: Sequence[str] | None = None
               ) -> tuple[Continuity, np.ndarray]:
    """The continuity of a task's ladder (``candidates`` (N, K, dof), ``valid`` (N, K),
    ``segments`` (N,)) with ``max_joint_step`` (rad, or ``"auto"``: derived) and its
    followable branches (N, K) (:func:`followable`). ``ValueError`` for a segment no
    branch sequence follows, naming it (``where[w]`` says where waypoint w came from)."""
    segments = np.asarray(segments, dtype=np.int64)
    inside = inside_moves(segments)
    need = least_limits(candidates, valid, inside, configuration, revolute)
    last = np.flatnonzero(np.append(segments[1:] != segments[:-1], True))
    needed = need[last]
    derived = isinstance(max_joint_step, str)
    if derived:
        if max_joint_step != "auto":
            raise ValueError(f"max_joint_step must be a number of radians, 'auto' or None, got "
                             f"{max_joint_step!r}")
        hardest = float(needed[np.isfinite(needed)].max(initial=0.0))
        limit = min(max(DERIVED_FACTOR * hardest, MIN_DERIVED_LIMIT), MAX_LIMIT)
    else:
        limit = check_limit(max_joint_step)
    broken = np.flatnonzero(need > limit)
    if len(broken):
        w = int(broken[0])
        segment = int(segments[w])
        members = np.flatnonzero(segments == segment)

        def name(i: int) -> str:
            return f"waypoint {i}" + (f" ({where[i]})" if where is not None else "")

        least = float(need[w])
        if least <= MAX_LIMIT:
            why = (f"it needs a step limit of {math.degrees(least):.2f}° there. Raise the "
                   f"step limit, start a new segment there, or check the path")
        else:
            why = ("no branch sequence gets there keeping one configuration with steps below "
                   "half a revolution (the arm must flip or unwind): start a new segment "
                   "there, or check the path")
        raise ValueError(
            f"process segment {segment} (waypoints {members[0]}–{members[-1]}) cannot be "
            f"followed without reconfiguring the arm at joint steps of at most "
            f"{math.degrees(limit):.2f}°: it breaks between {name(w - 1)} and {name(w)}; "
            f"{why}")
    alive = followable(candidates, valid, inside, configuration, limit, revolute)
    return Continuity(segments, inside, limit, derived, needed), alive


#: Samples of a joint-space move for :func:`line_deviation`: one per this much of its
#: largest revolute step (rad) or prismatic step (m), at least ``LINE_SAMPLES``.
LINE_ANGLE_STEP = math.radians(0.25)
LINE_LENGTH_STEP = 0.0005
LINE_SAMPLES = 16


def line_deviation(fk: Callable[[np.ndarray], np.ndarray], q0: np.ndarray, q1: np.ndarray,
                   revolute: np.ndarray, tcp: np.ndarray | None = None) -> tuple[float, float]:
    """How far the TCP leaves the straight line while the joints move linearly q0 → q1:
    the largest distance (m) of the TCP from the segment between its two end positions,
    and the largest angle (rad) between its orientation and the orientation a linear
    (LIN) move would have at the same point of the line (the slerp of the two end
    orientations at the TCP's projection onto the segment; for a move without
    translation, under 1 µm, at the same fraction of the joint move). Sampled (``LINE_ANGLE_STEP``,
    ``LINE_LENGTH_STEP``, ends included): a lower bound of the true maxima, tight to the
    sampling. ``fk`` maps (M, dof) to (M, 4, 4) poses; ``tcp`` (4, 4) the TCP in its frame."""
    q0, q1 = np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64)
    delta = np.abs(q1 - q0)
    angle = float(delta[revolute].max(initial=0.0))
    length = float(delta[~revolute].max(initial=0.0))
    count = max(LINE_SAMPLES, math.ceil(angle / LINE_ANGLE_STEP),
                math.ceil(length / LINE_LENGTH_STEP))
    t = np.linspace(0.0, 1.0, count + 1)
    poses = fk(q0 + t[:, None] * (q1 - q0))
    if tcp is not None:
        poses = poses @ tcp
    points, rotations = poses[:, :3, 3], poses[:, :3, :3]
    start, chord = points[0], points[-1] - points[0]
    span = float(chord @ chord)
    # A chord under a micrometre is a move without translation: the joint fraction then.
    along = np.clip((points - start) @ chord / span, 0.0, 1.0) if span > 1e-12 else t
    off = points - (start + along[:, None] * chord)
    distance = float(np.sqrt((off * off).sum(axis=1)).max())
    expected = _slerp(rotations[0], rotations[-1], along)
    relative = np.einsum("nji,njk->nik", expected, rotations)
    # The angle of each relative rotation as atan2(sin, cos): arccos of the trace alone
    # loses half the digits near zero (1e-8 rad from rounding).
    sine = 0.5 * np.linalg.norm(np.stack([relative[:, 2, 1] - relative[:, 1, 2],
                                          relative[:, 0, 2] - relative[:, 2, 0],
                                          relative[:, 1, 0] - relative[:, 0, 1]], -1), axis=-1)
    cosine = (np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0
    return distance, float(np.arctan2(sine, cosine).max())


def _slerp(r0: np.ndarray, r1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(len(s), 3, 3): the rotations from ``r0`` to ``r1`` about their fixed axis, the
    fraction ``s`` of the way (the shorter way)."""
    relative = r0.T @ r1
    cosine = np.clip((np.trace(relative) - 1.0) / 2.0, -1.0, 1.0)
    theta = math.acos(cosine)
    if theta < 1e-12:
        return np.broadcast_to(r0, (len(s), 3, 3)).copy()
    if math.pi - theta < 1e-6:  # a half turn, R = 2uuᵀ − I: u from (R + I)/2 = uuᵀ
        outer = (relative + relative.T) / 4.0 + np.eye(3) / 2.0
        k = int(np.argmax(np.diag(outer)))
        axis = outer[:, k] / math.sqrt(outer[k, k])
    else:
        axis = np.array([relative[2, 1] - relative[1, 2], relative[0, 2] - relative[2, 0],
                         relative[1, 0] - relative[0, 1]]) / (2.0 * math.sin(theta))
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                     [-axis[1], axis[0], 0.0]])
    angles = theta * np.asarray(s)
    turns = (np.eye(3) + np.sin(angles)[:, None, None] * skew
             + (1.0 - np.cos(angles))[:, None, None] * (skew @ skew))  # Rodrigues
    return r0 @ turns


#: A linear (LIN) move is followed by IK at most this far apart along the line.
LIN_LENGTH_STEP = 0.002
LIN_ANGLE_STEP = math.radians(1.0)


@dataclass(frozen=True)
class LinearPath:
    """A LIN move q0 → q1 solved by IK along the line: ``samples`` (M, dof) the
    configurations at M − 1 equal steps of the TCP's line and slerp, from q0 to q1, each in
    q0's closed-form branch and the turn nearest the sample before; ``problem`` None when
    the arm follows the whole line so, else what stops it (the samples then end there)."""

    samples: np.ndarray
    problem: str | None


def linear_path(arm: Arm, q0: np.ndarray, q1: np.ndarray, configuration: int,
                limit: float, tcp: np.ndarray | None = None) -> LinearPath:
    """The configurations a controller's LIN move from ``q0`` to ``q1`` passes through,
    sampled every ``LIN_LENGTH_STEP`` of the TCP's path and ``LIN_ANGLE_STEP`` of its
    turn (``tcp`` (4, 4) the TCP in the fk frame). The arm keeps q0's closed-form branch
    ``configuration`` (a controller's LIN keeps its status); a sample no configuration of
    that branch reaches, a revolute step beyond ``limit`` between samples (a pass near a
    singularity, where the joints whip) or an end in another turn than q1's is the
    ``problem``. ``arm`` is the kinematic arm (``envs.kinematics.Arm``)."""
    q0, q1 = np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64)
    tcp = np.eye(4) if tcp is None else np.asarray(tcp, dtype=np.float64)
    revolute = np.asarray(arm.revolute_mask)
    start, end = arm.fk(q0) @ tcp, arm.fk(q1) @ tcp
    length = float(np.linalg.norm(end[:3, 3] - start[:3, 3]))
    relative = start[:3, :3].T @ end[:3, :3]
    angle = math.acos(min(1.0, max(-1.0, (np.trace(relative) - 1.0) / 2.0)))
    count = max(1, math.ceil(length / LIN_LENGTH_STEP), math.ceil(angle / LIN_ANGLE_STEP))
    fractions = np.arange(1, count) / count
    rotations = _slerp(start[:3, :3], end[:3, :3], fractions)
    back = np.linalg.inv(tcp)
    ik_rows, ik_ok = arm.ik(np.array([_pose(start[:3, 3] + s * (end[:3, 3] - start[:3, 3]),
                                            r) @ back for s, r in zip(fractions, rotations,
                                                                      strict=True)])
                            if count > 1 else np.empty((0, 4, 4)))
    closed = np.asarray(arm.branch_closed_form)
    samples = [q0]
    for i, (rows, ok) in enumerate(zip(ik_rows, ik_ok, strict=True)):
        mine = ok & (closed == configuration)
        where = f"{100.0 * fractions[i]:.1f} % along the line"
        if not mine.any():
            return LinearPath(np.array(samples), f"out of reach in its configuration {where}")
        gaps = np.abs(rows[mine] - samples[-1])
        best = int(np.argmin(gaps.max(axis=1)))
        step = float(gaps[best][revolute].max(initial=0.0))
        if step > limit:
            return LinearPath(np.array(samples), f"a joint steps {math.degrees(step):.1f}° "
                              f"between two samples {where} (a singularity on the line)")
        samples.append(rows[mine][best])
    last = float(np.abs(q1 - samples[-1])[revolute].max(initial=0.0))
    if last > limit:
        return LinearPath(np.array(samples), "the line arrives in another turn or "
                          f"configuration than the waypoint's ({math.degrees(last):.1f}°)")
    samples.append(q1)
    return LinearPath(np.array(samples), None)


def _pose(position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = rotation, position
    return pose
