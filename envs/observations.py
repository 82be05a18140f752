"""Observation assembly: the flat ``Box(-1, 1)`` vector of ``IKBranchEnv`` and its layout.

Two layouts (``observation=``), both with joint values normalised to [−1, 1] over their
limits and travel to [0, 1] by the largest possible travel:

``"compact"`` (size O(K): arms with hundreds of branches)
    ``q`` (dof), ``progress`` (waypoints done / N); for the next waypoint (slot 0) and
    each of ``lookahead`` later ones (slots 1…H): ``present`` (1: within the task),
    ``candidates`` (K × dof, 0 where invalid), ``valid`` (K), ``endpoint_collision`` (K),
    ``travel_out`` (K: per branch, the least travel to a *free* branch of the waypoint
    after, i.e. valid and its configuration collision-free; 1 at the task's last
    waypoint); slot 0 also ``travel`` (K, from the current configuration),
    ``path_collision`` (K, along the path there) and ``free_travel_out`` (K: per branch,
    the least travel onward to the waypoint after along a path that is collision-free,
    checked; 1 where none is, at the last waypoint, and for branches whose own path from
    the current configuration collides); slots h ≥ 1 also ``travel_in`` (K: per branch,
    the least travel from a free branch of the waypoint before). Travel of and to invalid
    branches is 1.
``"ladder"`` (size O(K²): the v0/v1 ids)
    As compact without ``travel_out`` and ``travel_in``; instead slots h ≥ 1 carry
    ``travel`` (K × K) from every candidate of the waypoint before.

Everything a task fixes is assembled once per task (:meth:`ObservationBuilder.templates`);
each step fills in the configuration and slot 0's travel, path collisions and (compact)
onward free travel, for a batch of episodes at once (``envs.episodes``). The paths behind
``path_collision`` and ``free_travel_out`` are checked by the env, so a policy's decision
time does not include them; a planner's (``receding_dp``) includes the checks it makes
itself.
"""

from __future__ import annotations

import numpy as np

from envs.jit import njit
from envs.kinematics import Arm
from envs.moves import TEMPLATE_CACHE_BYTES, TEMPLATE_SIGHTINGS, TaskMoves

#: The observation layouts (module docstring).
OBSERVATIONS = ("compact", "ladder")


@njit
def _travel_summaries(candidates, valid, free, weights, scale, leaving, arriving):
    """Per waypoint i < N − 1 and branch a, the least weighted travel Σ_j w_j|Δq_j| from
    valid branch a to any *free* branch of waypoint i + 1 (``leaving[i, a]``), and per
    branch b of waypoint i + 1 the least from any free branch of waypoint i
    (``arriving[i + 1, b]``), over ``scale`` and capped at 1 (1 where nothing qualifies,
    for invalid branches, at the ends). One pass over each pair of waypoints."""
    n, k, dof = candidates.shape
    leaving[:] = 1.0
    arriving[:] = 1.0
    out_from, out_to = np.empty(k), np.empty(k)
    for i in range(n - 1):
        out_from[:] = np.inf
        out_to[:] = np.inf
        for a in range(k):
            if not valid[i, a]:
                continue
            for b in range(k):
                if not valid[i + 1, b]:
                    continue
                travel = 0.0
                for j in range(dof):
                    travel += abs(candidates[i + 1, b, j] - candidates[i, a, j]) * weights[j]
                if free[i + 1, b]:
                    out_from[a] = min(out_from[a], travel)
                if free[i, a]:
                    out_to[b] = min(out_to[b], travel)
        for a in range(k):
            leaving[i, a] = min(out_from[a] / scale, 1.0)
            arriving[i + 1, a] = min(out_to[a] / scale, 1.0)


class ObservationBuilder:
    """The layout and assembly of one env's observations (arm, lookahead, travel scale,
    ``kind``: one of ``OBSERVATIONS``)."""

    def __init__(self, arm: Arm, lookahead: int, travel_scale: float,
                 kind: str = "compact") -> None:
        if kind not in OBSERVATIONS:
            raise ValueError(f"observation must be one of {', '.join(OBSERVATIONS)}, got {kind!r}")
        self.arm, self.lookahead, self.travel_scale, self.kind = arm, lookahead, travel_scale, kind
        lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
        self._centre, self._half_range = (upper + lower) / 2, (upper - lower) / 2
        #: name -> (start, stop) of each slice of the observation vector.
        self.layout = self._layout()
        self.size = max(stop for _, stop in self.layout.values())
        self._q = slice(*self.layout["q"])
        self._travel0 = slice(*self.layout["slot0/travel"])
        self._path0 = slice(*self.layout["slot0/path_collision"])
        onward = self.layout.get("slot0/free_travel_out")
        self._onward0 = None if onward is None else slice(*onward)
        #: (candidates, valid, endpoint_collision) bytes of a task -> its templates
        #: (read-only), cleared when it would grow past ``TEMPLATE_CACHE_BYTES``; only
        #: tasks seen before (``_sighted``: hashes of keys) are kept, so that tasks which
        #: never repeat (random waypoints) fill no memory.
        self._cache: dict[tuple[bytes, bytes, bytes], np.ndarray] = {}
        self._cached_bytes = 0
        self._sighted: set[int] = set()

    def _layout(self) -> dict[str, tuple[int, int]]:
        dof, k = self.arm.dof, self.arm.n_branches
        sizes = [("q", dof), ("progress", 1)]
        for h in range(self.lookahead + 1):
            sizes += [(f"slot{h}/present", 1), (f"slot{h}/candidates", k * dof),
                      (f"slot{h}/valid", k), (f"slot{h}/endpoint_collision", k)]
            if self.kind == "compact":
                sizes += [(f"slot{h}/travel_out", k)]
                sizes += [("slot0/travel", k), ("slot0/path_collision", k),
                          ("slot0/free_travel_out", k)] if h == 0 else [
                    (f"slot{h}/travel_in", k)]
                continue
            sizes += [("slot0/travel", k), ("slot0/path_collision", k)] if h == 0 else [
                (f"slot{h}/travel", k * k)]
        layout, start = {}, 0
        for name, size in sizes:
            layout[name] = (start, start + size)
            start += size
        return layout

    def normalise(self, q: np.ndarray) -> np.ndarray:
        return (q - self._centre) / self._half_range

    def templates(self, ladder: TaskMoves) -> np.ndarray:
        """Everything of the observation a task fixes, (N + 1, size) read-only: row i is
        the observation at ``index == i`` (i = 0 … N) but for ``q`` and slot 0's
        ``travel``, ``path_collision`` and ``free_travel_out``, which :meth:`observe_rows`
        and :meth:`fill_slot0` fill in. They depend on the task's candidates, their
        validity and endpoint hits only, so a task met again (a finite pose set) takes
        them from the cache."""
        key = (ladder.candidates.tobytes(), ladder.valid.tobytes(),
               ladder.endpoint_collision.tobytes())
        templates = self._cache.get(key)
        if templates is None:
            templates = self._assemble(ladder)
            templates.flags.writeable = False
            sighting = hash(key)
            if sighting in self._sighted:  # a task seen before: this env's tasks repeat
                if self._cached_bytes + templates.nbytes > TEMPLATE_CACHE_BYTES:
                    self._cache.clear()
                    self._cached_bytes = 0
                self._cache[key] = templates
                self._cached_bytes += templates.nbytes
            else:
                if len(self._sighted) >= TEMPLATE_SIGHTINGS:
                    self._sighted.clear()
                self._sighted.add(sighting)
        return templates

    def _assemble(self, ladder: TaskMoves) -> np.ndarray:
        """The templates of :meth:`templates`, (N + 1, size) float32."""
        n, k, dof = ladder.n_waypoints, self.arm.n_branches, self.arm.dof
        valid = ladder.valid
        # Per waypoint: present, candidates (invalid ones at the centre: 0), valid, endpoint.
        candidates = np.where(valid[..., None], ladder.candidates, self._centre)
        common = np.concatenate(
            [np.ones((n, 1)), self.normalise(candidates).reshape(n, k * dof), valid,
             ladder.endpoint_collision], axis=1,
        )
        width = common.shape[1]
        templates = np.zeros((n + 1, self.size))
        templates[:, slice(*self.layout["progress"])] = np.arange(n + 1)[:, None] / n
        if self.kind == "compact":
            self._prepare_compact(ladder, common, templates)
        else:
            self._prepare_ladder(ladder, common, templates, width)
        # Values sit inside [−1, 1] by construction; the clip only absorbs the 1e-9 slack
        # with which a branch may lie on a joint limit.
        return np.clip(templates, -1.0, 1.0).astype(np.float32)

    def _prepare_ladder(self, ladder, common, templates, width) -> None:
        n, k = ladder.n_waypoints, self.arm.n_branches
        valid = ladder.valid
        if self.lookahead and n > 1:
            # travel[i - 1]: (K, K) from every candidate of waypoint i − 1 to every one of i.
            both = valid[:-1, :, None] & valid[1:, None, :]
            travel = np.ones((n - 1, k, k))
            travel[both] = ladder.pricer.cost.travel(
                ladder.candidates[:-1, :, None, :], ladder.candidates[1:, None, :, :]
            )[both] / self.travel_scale
            travel = travel.reshape(n - 1, k * k)
        for h in range(min(self.lookahead, n - 1) + 1):
            start = self.layout[f"slot{h}/present"][0]
            rows = n - h  # indices 0 … n − h − 1 see waypoint index + h inside the task
            templates[:rows, start : start + width] = common[h:]
            if h:
                templates[:rows, start + width : start + width + k * k] = travel[h - 1 :]

    def _prepare_compact(self, ladder, common, templates) -> None:
        n, k = ladder.n_waypoints, self.arm.n_branches
        # leaving[i] (K): from waypoint i onwards, to the free branches after; arriving[i]
        # (K): into waypoint i, from the free branches before.
        leaving, arriving = np.empty((n, k)), np.empty((n, k))
        _travel_summaries(ladder.candidates, ladder.valid,
                          ladder.valid & ~ladder.endpoint_collision, ladder.pricer.cost.weights,
                          float(self.travel_scale), leaving, arriving)
        for h in range(min(self.lookahead, n - 1) + 1):
            rows = n - h  # indices 0 … n − h − 1 see waypoint index + h inside the task
            start = self.layout[f"slot{h}/present"][0]
            templates[:rows, start : start + common.shape[1]] = common[h:]
            templates[:rows, slice(*self.layout[f"slot{h}/travel_out"])] = leaving[h:]
            if h:
                templates[:rows, slice(*self.layout[f"slot{h}/travel_in"])] = arriving[h:]

    @property
    def wants_onward(self) -> bool:
        """The layout has ``slot0/free_travel_out`` (the caller computes it per step)."""
        return self._onward0 is not None

    def observe_rows(self, templates: np.ndarray, index: np.ndarray,
                     q: np.ndarray) -> np.ndarray:
        """(B, size) float32: per row b its task's template at ``index[b]`` with the
        configuration ``q[b]``: the whole observation once an episode is over; otherwise
        :meth:`fill_slot0` completes it. ``templates`` (B, N + 1, size)."""
        obs = templates[np.arange(len(index)), index]
        # np.clip's values, without its dispatch.
        obs[:, self._q] = np.minimum(np.maximum(self.normalise(q), -1.0), 1.0)
        return obs

    def fill_slot0(self, obs: np.ndarray, rows: np.ndarray, valid: np.ndarray,
                   travel: np.ndarray, collision: np.ndarray,
                   onward: np.ndarray | None) -> None:
        """Slot 0 of ``obs[rows]``: per branch of the next waypoint (``valid`` (R, K)) the
        travel of the move there (``travel``, what ``step`` pays), whether its path
        collides, and (compact layout) ``onward``, the least travel onward along a free
        path (``envs.moves.least_free_travel``; inf where none)."""
        scaled = travel / self.travel_scale  # invalid branches: 0
        obs[rows, self._travel0] = np.where(valid, np.minimum(scaled, 1.0), 1.0)
        obs[rows, self._path0] = collision
        if self._onward0 is not None:
            if onward is None:
                raise ValueError("the compact observation needs the onward free travel")
            obs[rows, self._onward0] = np.minimum(onward / self.travel_scale, 1.0)
