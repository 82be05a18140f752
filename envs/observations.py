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
    ``path_collision`` (K, along the path there; with ``checked_moves`` n only the paths
    of least travel until n are free are checked, and the others read 1) and
    ``free_travel_out`` (K: per branch, the least travel onward to the waypoint after
    along a path that is collision-free, checked; 1 where none is, at the last waypoint,
    and for branches whose own path from the current configuration collides); with
    ``onward_moves`` n ≥ 2 slot 0 also
    ``free_travel_onward`` (K: per branch, the least travel of the next n moves — fewer
    where the task ends sooner — along paths checked collision-free, each ending in a free
    configuration, over n × the scale; 1 where none is, at the last waypoint, and for
    branches whose own path collides: a branch from which every way on is blocked within n
    moves reads 1); slots h ≥ 1 also ``travel_in`` (K: per branch, the least travel from a
    free branch of the waypoint before). Travel of and to invalid branches is 1.
``"ladder"`` (size O(K²): the v0/v1 ids)
    As compact without ``travel_out`` and ``travel_in``; instead slots h ≥ 1 carry
    ``travel`` (K × K) from every candidate of the waypoint before (1 for invalid
    branches and for moves a process segment blocks, as no move).

Everything a task fixes is assembled once per task (:meth:`ObservationBuilder.templates`);
each step fills in the configuration and slot 0's travel, path collisions and (compact)
onward free travel, for a batch of episodes at once (``envs.episodes``). The paths behind
``path_collision``, ``free_travel_out`` and ``free_travel_onward`` are checked by the env,
so a policy's decision time does not include them; a planner's (``receding_dp``)
includes the checks it makes itself.
"""

from __future__ import annotations

import numpy as np

from ikbranch_gym.envs.jit import njit
from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.moves import TEMPLATE_CACHE_BYTES, TEMPLATE_SIGHTINGS, TaskMoves
from ikbranch_gym.envs.process import blocked, move_blocked

#: The observation layouts (module docstring).
OBSERVATIONS = ("compact", "ladder")
#: Arms with at least this many branches (and turn windows) sum up their travel from the
#: ladder's factors (closed-form branch × turn windows), the others over every pair of
#: branches: both give the same values; docs/models.md has the measurements.
FACTORED_BRANCHES = 128

#: :func:`_turn_tables`' answer: factored (bool), fixed, turned_value, window_ok, free.
_TurnTables = tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@njit
def _travel_summaries(candidates: np.ndarray, valid: np.ndarray, free: np.ndarray,
                      weights: np.ndarray, scale: float, inside: np.ndarray,
                      configuration: np.ndarray, limit: float, revolute: np.ndarray,
                      leaving: np.ndarray, arriving: np.ndarray) -> None:
    """Per waypoint i < N − 1 and branch a, the least weighted travel Σ_j w_j|Δq_j| from
    valid branch a to any *free* branch of waypoint i + 1 (``leaving[i, a]``), and per
    branch b of waypoint i + 1 the least from any free branch of waypoint i
    (``arriving[i + 1, b]``), over ``scale`` and capped at 1 (1 where nothing qualifies,
    for invalid branches, at the ends). A move into a waypoint ``inside`` a process
    segment that reconfigures the arm (``envs.process.move_blocked`` with ``limit``) is
    no move. One pass over each pair of waypoints."""
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
                if inside[i + 1] and move_blocked(candidates[i, a], configuration[a],
                                                  candidates[i + 1, b], configuration[b],
                                                  limit, revolute):
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


@njit
def _turn_tables(candidates: np.ndarray, valid: np.ndarray, endpoint: np.ndarray,
                 closed: np.ndarray, turned: np.ndarray, turns: np.ndarray, n_closed: int,
                 windows: int) -> _TurnTables:
    """The ladder of an arm with turn branches as its factors, per waypoint i and
    closed-form branch c: the values of the joints without turns ``fixed[i, c]`` (dof),
    of each turned joint in each window ``turned_value[i, c, t, w]``, which windows exist
    ``window_ok[i, c, t, w]``, and whether c exists with a free configuration
    ``free[i, c]``. Returns False where the ladder is not such a product (a value that
    differs between turn copies, validity that is not the product of the windows', an
    endpoint verdict that differs between copies): the caller then takes the general
    kernel. (One loop, no helper: numba takes a reference on each array passed to one,
    which cost more than the work.)"""
    n, k, dof = candidates.shape
    jt = len(turned)
    fixed = np.zeros((n, n_closed, dof))
    turned_value = np.zeros((n, n_closed, jt, windows))
    window_ok = np.zeros((n, n_closed, jt, windows), dtype=np.bool_)
    exists = np.zeros((n, n_closed), dtype=np.bool_)
    free = np.zeros((n, n_closed), dtype=np.bool_)
    is_turned = np.zeros(dof, dtype=np.bool_)
    is_turned[turned] = True
    factored = True
    for i in range(n):
        for b in range(k):
            if not valid[i, b]:
                continue
            # Enter valid branch b (closed form c, windows turns[b]) into the factors of
            # waypoint i; a contradiction with what its turn copies entered ends the product.
            c, hit = closed[b], endpoint[i, b]
            first = not exists[i, c]
            if first:
                exists[i, c], free[i, c] = True, not hit
            elif free[i, c] == hit:
                factored = False
            for j in range(dof):
                if not is_turned[j]:
                    if first:
                        fixed[i, c, j] = candidates[i, b, j]
                    elif fixed[i, c, j] != candidates[i, b, j]:
                        factored = False
            for t in range(jt):
                w = turns[b, t]
                value = candidates[i, b, turned[t]]
                if window_ok[i, c, t, w] and turned_value[i, c, t, w] != value:
                    factored = False
                turned_value[i, c, t, w], window_ok[i, c, t, w] = value, True
        factored = factored and _validity_is_product(valid[i], exists[i], window_ok[i],
                                                     closed, turns)
    return factored, fixed, turned_value, window_ok, free


@njit
def _validity_is_product(valid: np.ndarray, exists: np.ndarray, window_ok: np.ndarray,
                         closed: np.ndarray, turns: np.ndarray) -> bool:
    """A waypoint's branches are valid exactly where their closed form exists and each of
    their turned joints' windows does (one waypoint of :func:`_turn_tables`)."""
    for b in range(len(valid)):
        product = exists[closed[b]]
        for t in range(turns.shape[1]):
            product = product and window_ok[closed[b], t, turns[b, t]]
        if product != valid[b]:
            return False
    return True


@njit
def _joint_terms(src_fixed: np.ndarray, src_value: np.ndarray, src_ok: np.ndarray,
                 dst_fixed: np.ndarray, dst_value: np.ndarray, dst_ok: np.ndarray,
                 slot: np.ndarray, weights: np.ndarray, term: np.ndarray) -> None:
    """``term[c, d, j, w]``: joint j's weighted travel w_j|Δq_j| between closed-form
    branch c of one waypoint (in its window w of j, where j has turns) and the nearest
    turn copy of closed-form branch d of another (given as :func:`_turn_tables`' factors,
    ``src_*`` and ``dst_*``; ``slot[j]``: j's index among the turned joints, −1 for a
    joint without turns). Each term as the general kernel computes it:
    ``abs(later − earlier) * w`` (|x − y| and |y − x| are the same number)."""
    kc, dof = src_fixed.shape
    windows = src_value.shape[2]
    for c in range(kc):
        for d in range(kc):
            for j in range(dof):
                t = slot[j]
                if t < 0:
                    term[c, d, j, 0] = abs(dst_fixed[d, j] - src_fixed[c, j]) * weights[j]
                    continue
                for w in range(windows):
                    least = np.inf
                    if src_ok[c, t, w]:
                        for v in range(windows):
                            if dst_ok[d, t, v]:
                                step = abs(dst_value[d, t, v] - src_value[c, t, w]) * weights[j]
                                least = min(least, step)
                    term[c, d, j, w] = least


@njit(inline="always")
def _window_sums(term: np.ndarray, c: int, d: int, slot: np.ndarray, windows: int,
                 sums: np.ndarray) -> int:
    """``sums[leaf]``: the travel from closed-form branch ``c`` of one waypoint to ``d`` of
    another for every choice of windows of the turned joints (``leaf``: those windows as
    the digits of a base-``windows`` number, in joint order), each summed from
    :func:`_joint_terms` in joint order, as the general kernel sums it. The choices share
    their sums up to each joint: a sum is extended once per window of the next turned
    joint, not recomputed per branch. Returns the number of leaves."""
    sums[0] = 0.0
    size = 1
    for j in range(term.shape[2]):
        t = slot[j]
        if t < 0:
            step = term[c, d, j, 0]
            for p in range(size):
                sums[p] += step
            continue
        for p in range(size - 1, -1, -1):  # from the top: p · windows + w ≥ p
            base = sums[p]
            for w in range(windows):
                sums[p * windows + w] = base + term[c, d, j, w]
        size *= windows
    return size


@njit(inline="always")
def _least_by_windows(term: np.ndarray, free: np.ndarray, other: int, slot: np.ndarray,
                      windows: int, sums: np.ndarray, least: np.ndarray) -> None:
    """``least[c, leaf]``: the least travel from closed-form branch c in the windows
    ``leaf`` (:func:`_window_sums`) to any free branch of waypoint ``other`` (``free[other]``:
    its free closed forms). Each free closed-form branch's best turn copy takes each turned
    joint's best window: addition is monotonic, so that sum is the least of its copies'
    sums exactly."""
    kc = term.shape[0]
    least[:] = np.inf
    for c in range(kc):
        for d in range(kc):
            if not free[other, d]:
                continue
            size = _window_sums(term, c, d, slot, windows, sums)
            for p in range(size):
                least[c, p] = min(least[c, p], sums[p])


@njit
def _turned_travel_summaries(valid: np.ndarray, tables: _TurnTables, closed: np.ndarray,
                             turned: np.ndarray, turns: np.ndarray, weights: np.ndarray,
                             scale: float, leaving: np.ndarray, arriving: np.ndarray) -> None:
    """:func:`_travel_summaries` (the same values, bit for bit) from the factors of a
    ladder with turn branches (:func:`_turn_tables`; ``closed``, ``turns``: each branch's
    closed form and windows): per pair of waypoints each joint's travel between closed
    forms and windows once, then per closed form the sums over its windows, sharing the
    joints they agree on, where the general kernel sums over every pair of branches."""
    _, fixed, turned_value, window_ok, free = tables
    n, kc, dof = fixed.shape
    windows = turned_value.shape[3]
    slot = np.full(dof, -1, dtype=np.int64)
    for t in range(len(turned)):
        slot[turned[t]] = t
    leaf = np.zeros(len(closed), dtype=np.int64)  # each branch's windows as a leaf
    for b in range(len(closed)):
        for j in range(dof):
            if slot[j] >= 0:
                leaf[b] = leaf[b] * windows + turns[b, slot[j]]
    term = np.empty((kc, kc, dof, windows))
    sums = np.empty(windows ** len(turned))
    least = np.empty((kc, len(sums)))
    leaving[:] = 1.0
    arriving[:] = 1.0
    for i in range(n - 1):
        _joint_terms(fixed[i], turned_value[i], window_ok[i], fixed[i + 1],
                     turned_value[i + 1], window_ok[i + 1], slot, weights, term)
        _least_by_windows(term, free, i + 1, slot, windows, sums, least)
        for a in range(len(closed)):
            if valid[i, a]:
                leaving[i, a] = min(least[closed[a], leaf[a]] / scale, 1.0)
        _joint_terms(fixed[i + 1], turned_value[i + 1], window_ok[i + 1], fixed[i],
                     turned_value[i], window_ok[i], slot, weights, term)
        _least_by_windows(term, free, i, slot, windows, sums, least)
        for b in range(len(closed)):
            if valid[i + 1, b]:
                arriving[i + 1, b] = min(least[closed[b], leaf[b]] / scale, 1.0)


@njit
def _compact_templates(candidates: np.ndarray, valid: np.ndarray, endpoint: np.ndarray,
                       centre: np.ndarray, half_range: np.ndarray, leaving: np.ndarray,
                       arriving: np.ndarray, slots: np.ndarray, progress: int,
                       out: np.ndarray) -> None:
    """The compact layout's templates (``ObservationBuilder.templates``) into ``out`` (N + 1,
    size) float32: row i has ``progress`` i / N and per slot h whose waypoint w = i + h
    lies in the task (``slots[h]``: where its present, travel_out and travel_in start,
    −1 for none) present 1, the candidates normalised (0 where invalid), valid, endpoint
    collision, ``leaving[w]`` and ``arriving[w]``; 0 everywhere else. Each value is
    computed in float64 and clipped to [−1, 1] (the 1e-9 slack with which a branch may
    lie on a joint limit) before it is stored, as NumPy's ``clip`` and ``astype`` would."""
    n, k, dof = candidates.shape
    out[:] = 0.0
    for i in range(n + 1):
        out[i, progress] = i / n
    # Each waypoint's normalised candidates once, as stored; every slot showing it copies.
    shown = np.empty((n, k * dof), dtype=out.dtype)
    for w in range(n):
        for b in range(k):
            for j in range(dof):
                value = 0.0
                if valid[w, b]:
                    value = (candidates[w, b, j] - centre[j]) / half_range[j]
                shown[w, b * dof + j] = min(max(value, -1.0), 1.0)
    for h in range(len(slots)):
        present, travel_out, travel_in = slots[h]
        for i in range(n - h):
            w = i + h
            row = out[i]
            row[present] = 1.0
            at = present + 1
            row[at : at + k * dof] = shown[w]
            at += k * dof
            for b in range(k):
                row[at + b] = 1.0 if valid[w, b] else 0.0
                row[at + k + b] = 1.0 if endpoint[w, b] else 0.0
                row[travel_out + b] = leaving[w, b]
                if travel_in >= 0:
                    row[travel_in + b] = arriving[w, b]


class ObservationBuilder:
    """The layout and assembly of one env's observations (arm, lookahead, travel scale,
    ``kind``: one of ``OBSERVATIONS``)."""

    def __init__(self, arm: Arm, lookahead: int, travel_scale: float,
                 kind: str = "compact", onward_moves: int = 1,
                 checked_moves: int | None = None) -> None:
        if kind not in OBSERVATIONS:
            raise ValueError(f"observation must be one of {', '.join(OBSERVATIONS)}, got {kind!r}")
        if onward_moves > 1 and kind != "compact":
            raise ValueError(f"onward_moves={onward_moves} needs observation='compact' (the "
                             f"{kind} layout shows no onward free travel)")
        self.arm, self.lookahead, self.travel_scale, self.kind = arm, lookahead, travel_scale, kind
        #: Moves the onward free travel of slot 0 covers (``free_travel_onward`` from 2).
        self.onward_moves = onward_moves
        #: Moves into slot 0 whose paths are checked, in order of least travel, until so
        #: many are free (None: every move); the others read as colliding.
        self.checked_moves = checked_moves
        lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
        self._centre, self._half_range = (upper + lower) / 2, (upper - lower) / 2
        #: An arm with turn branches: its branch factors (closed-form index per branch,
        #: turned joints, window per branch and turned joint, counts), else None.
        self._turns = None
        if arm.turn_windows and arm.n_branches >= FACTORED_BRANCHES:
            turned = np.array([joint for joint, _ in arm.turn_windows], dtype=np.int64)
            self._turns = (np.ascontiguousarray(arm.branch_closed_form, dtype=np.int64), turned,
                           np.ascontiguousarray(arm.branch_turns, dtype=np.int64),
                           arm.n_closed_form,
                           max(len(windows) for _, windows in arm.turn_windows))
        #: name -> (start, stop) of each slice of the observation vector.
        self.layout = self._layout()
        self.size = max(stop for _, stop in self.layout.values())
        #: Per slot h (compact): where its present, travel_out and travel_in (−1: slot 0
        #: has none) start.
        self._slot_starts = np.array(
            [[self.layout[f"slot{h}/present"][0], self.layout[f"slot{h}/travel_out"][0],
              self.layout.get(f"slot{h}/travel_in", (-1, -1))[0]]
             for h in range(self.lookahead + 1)] if kind == "compact" else [[0, 0, 0]],
            dtype=np.int64)
        #: (candidates, valid, endpoint_collision, inside) bytes and the step limit of a
        #: task -> its templates (read-only), cleared when it would grow past
        #: ``TEMPLATE_CACHE_BYTES``; only tasks seen before (``_sighted``: hashes of keys)
        #: are kept, so that tasks which never repeat (random waypoints) fill no memory.
        self._cache: dict[tuple[bytes, bytes, bytes, bytes, float], np.ndarray] = {}
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
                if h == 0 and self.onward_moves > 1:
                    sizes += [("slot0/free_travel_onward", k)]
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
        ``travel``, ``path_collision`` and onward free travel, which each step fills in
        (``envs.stepping``). They depend on the task's candidates, their validity and
        endpoint hits, and on which moves a process segment holds to which step limit
        only, so a task met again (a finite pose set) takes them from the cache."""
        key = (*ladder.fingerprint, ladder.inside.tobytes(), float(ladder.limit))
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
        if self.kind == "compact":
            assembled = np.empty((ladder.n_waypoints + 1, self.size), dtype=np.float32)
            leaving, arriving = self._travel_summaries(ladder)
            _compact_templates(ladder.candidates, ladder.valid, ladder.endpoint_collision,
                               self._centre, self._half_range, leaving, arriving,
                               self._slot_starts, self.layout["progress"][0], assembled)
            return assembled
        n, k, dof = ladder.n_waypoints, self.arm.n_branches, self.arm.dof
        valid = ladder.valid
        # Per waypoint: present, candidates (invalid ones at the centre: 0), valid, endpoint.
        candidates = np.where(valid[..., None], ladder.candidates, self._centre)
        common = np.concatenate(
            [np.ones((n, 1)), self.normalise(candidates).reshape(n, k * dof), valid,
             ladder.endpoint_collision], axis=1,
        )
        templates = np.zeros((n + 1, self.size))
        templates[:, slice(*self.layout["progress"])] = np.arange(n + 1)[:, None] / n
        self._prepare_ladder(ladder, common, templates, common.shape[1])
        # Values sit inside [−1, 1] by construction; the clip only absorbs the 1e-9 slack
        # with which a branch may lie on a joint limit.
        return np.clip(templates, -1.0, 1.0).astype(np.float32)

    def _prepare_ladder(self, ladder: TaskMoves, common: np.ndarray, templates: np.ndarray,
                        width: int) -> None:
        n, k = ladder.n_waypoints, self.arm.n_branches
        valid = ladder.valid
        if self.lookahead and n > 1:
            # travel[i - 1]: (K, K) from every candidate of waypoint i − 1 to every one of i.
            both = valid[:-1, :, None] & valid[1:, None, :]
            travel: np.ndarray = np.ones((n - 1, k, k))
            travel[both] = ladder.pricer.cost.travel(
                ladder.candidates[:-1, :, None, :], ladder.candidates[1:, None, :, :]
            )[both] / self.travel_scale
            for i in np.flatnonzero(ladder.inside[1:]):  # moves into waypoint i + 1
                travel[i][blocked(ladder.candidates[i], ladder.configuration,
                                  ladder.candidates[i + 1], ladder.configuration,
                                  ladder.limit, ladder.revolute)] = 1.0
            travel = travel.reshape(n - 1, k * k)
        for h in range(min(self.lookahead, n - 1) + 1):
            start = self.layout[f"slot{h}/present"][0]
            rows = n - h  # indices 0 … n − h − 1 see waypoint index + h inside the task
            templates[:rows, start : start + width] = common[h:]
            if h:
                templates[:rows, start + width : start + width + k * k] = travel[h - 1 :]

    def _travel_summaries(self, ladder: TaskMoves) -> tuple[np.ndarray, np.ndarray]:
        """The compact layout's travel summaries (N, K) of ``ladder``: ``leaving[i]`` from
        waypoint i onwards, to the free branches after; ``arriving[i]`` into waypoint i,
        from the free branches before."""
        n, k = ladder.n_waypoints, self.arm.n_branches
        leaving, arriving = np.empty((n, k)), np.empty((n, k))
        weights, scale = ladder.pricer.cost.weights, float(self.travel_scale)
        tables = None
        if self._turns is not None:  # many turn branches: the ladder's factors, where it is one
            closed, turned, turns, n_closed, windows = self._turns
            tables = _turn_tables(ladder.candidates, ladder.valid, ladder.endpoint_collision,
                                  closed, turned, turns, n_closed, windows)
        # A process segment's blocked moves are not factors of the ladder: the general
        # kernel leaves them out.
        if tables is not None and tables[0] and not ladder.inside.any():
            assert self._turns is not None  # tables are made from the turn factors only
            _turned_travel_summaries(ladder.valid, tables, closed, turned, turns, weights,
                                     scale, leaving, arriving)
        else:
            _travel_summaries(ladder.candidates, ladder.valid,
                              ladder.valid & ~ladder.endpoint_collision, weights, scale,
                              ladder.inside, ladder.configuration, float(ladder.limit),
                              ladder.revolute, leaving, arriving)
        return leaving, arriving
