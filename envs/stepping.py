"""The compiled stages of a batch of episodes (``envs.episodes``): survey and advance.

One call per stage for every row given, with no Python between the parts of a stage:

- :func:`survey` — for rows in a new state, the moves into their next waypoint: every
  path from where the arm stands (looked up in the path memo, the rest checked in one
  call of the collision filter's kernel, each path in its row's scene; where the batch
  checks ``CHECKED_MOVES`` = n ≥ 1 moves, the moves in order of least travel until n are
  free, a round of kernel calls for every row's next ones), every price
  (``envs.moves._price``), the least travel onward along a free path (cheapest first,
  one kernel call per round, as ``envs.moves.least_free_travel`` defines it), where the
  layout asks for it the least travel of several onward moves along free paths (the same
  search, layer by layer from the farthest waypoint back, each target carrying the least
  travel onward from it; the branches of the waypoint after the next costed only when
  the search reaches them) and the observation (the template of the task with the
  configuration and slot 0 filled in, as ``envs.observations.ObservationBuilder``
  defines it);
- :func:`advance` — rows take their actions: what :func:`survey` priced is paid (a move
  it left unchecked is checked now and, if its path collides, priced again), the arm
  moves.

The path memo is an open-addressing hash table of verdicts, keyed by the exact bits of a
path's two ends and the scene they were checked in (a token that changes whenever a
scene is laid anew): a move met again — the onward path a step checked, taken by the
next step; a finite pose set's moves, episode after episode — is not checked again. It
holds ``MEMO_SLOTS`` entries and starts afresh when half full. On an arm with turn
branches a second memo, of turn copies, serves paths whose ends differ by the same whole
turns of revolute joints: they place every link alike, so a verdict the filter's proofs
reached for one (no sample decided by MuJoCo) is the verdict of every copy
(:func:`_copy_verdicts`); a reset's onward search from every branch of the first
waypoint asks many of them.

Everything lives in one :class:`Episodes` object (a numba StructRef: one argument to
unbox, where its ~30 arrays would cost several µs a call).

A helper with one call site is inlined into it (``inline="always"``): compiled on its own,
each would be a library of its own holding re-optimised copies of everything it calls
(docs/models.md, "Compile time"). :func:`_onward` is not: the tests call it to read the
onward travel before it is rounded.
"""

from __future__ import annotations

import numpy as np
from numba.core import types
from numba.experimental import structref

from ikbranch_gym.envs.jit import njit
from ikbranch_gym.envs.models.filter.kernels import bound_paths, path_steps
from ikbranch_gym.envs.moves import (
    _by_joint,
    _next_targets,
    _onward_travel,
    _price,
    _take_or_try_next,
    _travel_to_all,
)
from ikbranch_gym.envs.process import UNKNOWN, move_blocked

#: The flags the filter's kernels take, as run-time booleans: every caller then shares one
#: compiled version of them (a literal ``False`` would be typed, and compiled, apart).
_FLAGS = np.array([False, True])
#: A search round of at most half this many branches asks two targets of each.
SPECULATE = 16
#: Slots of the path memo (a power of two); it starts afresh when half are taken.
MEMO_SLOTS = 2**16
#: Slots of the turn-copy memo (a power of two); it starts afresh when half are taken.
COPY_SLOTS = 2**14
#: The turn-copy memo keys a path by its ends rounded to 1 / ``COPY_GRID`` (rad, m).
COPY_GRID = 1e9
#: States of a turn-copy memo slot: empty, a verdict proved free or colliding, a path of
#: this call being checked (``copy_owner``), and a path MuJoCo helped decide.
COPY_EMPTY, COPY_FREE, COPY_HIT, COPY_PENDING, COPY_UNPROVED = -1, 0, 1, 2, 3
#: Indices into ``Episodes.numbers``.
TRAVEL_WEIGHT, TIME_WEIGHT, COLLISION_PENALTY, INVALID_PENALTY, TERMINATE, MAX_COST = range(6)
TRAVEL_SCALE, RESOLUTION, ONWARD_MOVES, CHECKED_MOVES, TURN_COPIES = 6, 7, 8, 9, 10
#: Indices into ``Episodes.layout``: start and stop of the observation's slices (q, slot
#: 0's travel, path collisions, onward free travel and free travel of ``ONWARD_MOVES``
#: moves; −1 where the layout has none).
Q0, Q1, TRAVEL0, TRAVEL1, PATH0, PATH1, ONWARD0, ONWARD1, AHEAD0, AHEAD1 = range(10)

FIELDS = ("q", "index", "collided", "invalid", "candidates", "valid", "endpoint",
          "free_start", "lengths", "templates", "values", "flags", "observation", "weights",
          "speeds", "numbers", "layout", "centre", "half_range", "lever", "scenes", "tokens",
          "memo_keys", "memo_tokens", "memo_verdicts", "memo_count", "inside", "limits",
          "configuration", "revolute", "branch", "checked", "copy_keys", "copy_tokens",
          "copy_verdicts", "copy_owner", "copy_count")


@structref.register
class _EpisodesType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(kind)) for name, kind in fields)


class Episodes(structref.StructRefProxy):
    """The arrays of a batch of episodes (``FIELDS``; ``envs.episodes.EpisodeBatch``
    makes and owns it)."""

    def __new__(cls, *arrays):
        return structref.StructRefProxy.__new__(cls, *arrays)


structref.define_proxy(Episodes, _EpisodesType, list(FIELDS))


@njit
def make_episodes(q, index, collided, invalid, candidates, valid, endpoint, free_start,
                  lengths, templates, values, flags, observation, weights, speeds, numbers,
                  layout, centre, half_range, lever, scenes, tokens, memo_keys, memo_tokens,
                  memo_verdicts, memo_count, inside, limits, configuration, revolute, branch,
                  checked, copy_keys, copy_tokens, copy_verdicts, copy_owner, copy_count):
    """An :class:`Episodes` of these arrays (``FIELDS`` order), made in compiled code:
    numba caches this on disk, where the proxy's own constructor is compiled again in
    every process."""
    return Episodes(q, index, collided, invalid, candidates, valid, endpoint, free_start,
                    lengths, templates, values, flags, observation, weights, speeds, numbers,
                    layout, centre, half_range, lever, scenes, tokens, memo_keys, memo_tokens,
                    memo_verdicts, memo_count, inside, limits, configuration, revolute, branch,
                    checked, copy_keys, copy_tokens, copy_verdicts, copy_owner, copy_count)


def memo_arrays(dof: int) -> tuple[np.ndarray, ...]:
    """An empty path memo: keys (slots, 2·dof) of bits, scene tokens, verdicts (−1 empty,
    0 free, 1 collides) and the count of entries."""
    return (np.zeros((MEMO_SLOTS, 2 * dof), dtype=np.int64),
            np.zeros(MEMO_SLOTS, dtype=np.int64), np.full(MEMO_SLOTS, -1, dtype=np.int8),
            np.zeros(1, dtype=np.int64))


def copy_memo_arrays(dof: int) -> tuple[np.ndarray, ...]:
    """An empty turn-copy memo: keys (slots, 2·dof + 1: the rounded ends and the grid),
    scene tokens, states (``COPY_EMPTY`` …), the owner of each pending slot and the count
    of entries."""
    return (np.zeros((COPY_SLOTS, 2 * dof + 1), dtype=np.int64),
            np.zeros(COPY_SLOTS, dtype=np.int64), np.full(COPY_SLOTS, COPY_EMPTY, dtype=np.int8),
            np.zeros(COPY_SLOTS, dtype=np.int64), np.zeros(1, dtype=np.int64))


# ------------------------------------------------------------------------- path memo
@njit(inline="always")
def _slot(keys, tokens, states, token, key):
    """The slot of ``key`` (int64) in scene ``token`` of an open-addressing table (the path
    memo, the turn-copy memo: rows of ``keys``, ``tokens``, ``states`` with −1 for an
    empty slot): where it is, or the empty slot where it would go."""
    h = np.uint64(14695981039346656037) ^ np.uint64(token)
    for j in range(len(key)):
        h = (h ^ np.uint64(key[j])) * np.uint64(1099511628211)
    mask = len(tokens) - 1
    slot = int(h ^ (h >> np.uint64(29))) & mask
    while states[slot] != -1:
        if tokens[slot] == token:
            same = True
            for j in range(len(key)):
                if keys[slot, j] != key[j]:
                    same = False
                    break
            if same:
                return slot
        slot = (slot + 1) & mask
    return slot


@njit(inline="always")
def _memo_slot(ep, token, start, end, key):
    """The memo slot of the path ``start`` → ``end`` in scene ``token`` (keyed by the exact
    bits of both ends, written into ``key``): where it is, or the empty slot where it would
    go."""
    dof = len(start)
    key[:dof], key[dof:] = start.view(np.int64), end.view(np.int64)
    return _slot(ep.memo_keys, ep.memo_tokens, ep.memo_verdicts, token, key)


@njit(inline="always")
def _memo_put(ep, token, start, end, hit, key):
    """Remember the verdict of ``start`` → ``end`` in scene ``token`` (``key``: room for
    its key)."""
    if 2 * ep.memo_count[0] >= len(ep.memo_tokens):  # half full: start afresh
        ep.memo_verdicts[:] = -1
        ep.memo_count[0] = 0
    slot = _memo_slot(ep, token, start, end, key)
    if ep.memo_verdicts[slot] < 0:
        ep.memo_count[0] += 1
    ep.memo_keys[slot] = key
    ep.memo_tokens[slot] = token
    ep.memo_verdicts[slot] = 1 if hit else 0


@njit
def _paths_collide(ep, bound, rows, starts, ends):
    """(M,) bool: path m (``starts[m]`` → ``ends[m]``, in the scene of row ``rows[m]``)
    collides; from the memo where it is there, then from a turn copy's proved verdict
    (:func:`_copy_verdicts`), the others in one kernel call, then remembered."""
    count = len(rows)
    out = np.zeros(count, dtype=np.bool_)
    missing = np.empty(count, dtype=np.int64)
    key = np.empty(2 * starts.shape[1], dtype=np.int64)
    misses = 0
    for m in range(count):
        slot = _memo_slot(ep, ep.tokens[rows[m]], starts[m], ends[m], key)
        verdict = ep.memo_verdicts[slot]
        if verdict >= 0:
            out[m] = verdict == 1
        else:
            missing[misses] = m
            misses += 1
    if misses:
        picked = missing[:misses]
        first, last = starts[picked], ends[picked]
        steps = np.empty(misses, dtype=np.int64)
        path_steps(first, last, ep.lever, ep.numbers[RESOLUTION], steps)
        scenes = np.empty(misses, dtype=np.int64)
        for i in range(misses):
            scenes[i] = ep.scenes[rows[picked[i]]]
        hits = np.empty(misses, dtype=np.bool_)
        if ep.numbers[TURN_COPIES] != 0.0 and 2 * misses <= len(ep.copy_tokens):
            _copy_verdicts(ep, bound, rows[picked], first, last, steps, scenes, hits)
        else:
            _check(bound, scenes, first, last, steps, hits)
        for i in range(misses):
            m = picked[i]
            out[m] = hits[i]
            _memo_put(ep, ep.tokens[rows[m]], starts[m], ends[m], out[m], key)
    return out


@njit
def _check(bound, scenes, first, last, steps, hits):
    """``hits[i]``: path ``first[i]`` → ``last[i]`` (grid ``steps[i]``, in scene
    ``scenes[i]``) collides: one kernel call."""
    index = np.empty(len(steps), dtype=np.int64)
    bound_paths(bound, scenes, first, last, steps, _FLAGS[0], index)
    for i in range(len(steps)):
        hits[i] = index[i] >= 0


@njit(inline="always")
def _copy_verdicts(ep, bound, rows, first, last, steps, scenes, hits):
    """:func:`_check` of the paths of ``rows`` where their turn copies share it: paths
    whose ends differ by whole turns of revolute joints (the same shift at both ends)
    place every link alike along the way, up to rounding. A copy takes the verdict of a
    path the filter's proofs decided, without MuJoCo: those hold with a tolerance
    (``DISTANCE_TOLERANCE``, ``WITNESS_TOLERANCE``: micrometres) far above the
    nanometres by which copies, and paths keyed alike, can differ. Paths are keyed by
    their ends with the start's turns taken off both, rounded to 1 / ``COPY_GRID``, and
    by their grid; in the scene's token. Of the paths of one key in this call one is
    checked; where MuJoCo decided a sample of the call, every path is checked itself."""
    if 2 * (ep.copy_count[0] + len(steps)) > len(ep.copy_tokens):  # start afresh
        ep.copy_verdicts[:] = COPY_EMPTY
        ep.copy_count[0] = 0
    owner, slots = _copy_owners(ep, rows, first, last, steps, hits)
    checked = np.flatnonzero(owner == -1)
    found = np.empty(len(checked), dtype=np.bool_)
    proved = True
    if len(checked):
        before = bound.counters[1]
        _check(bound, scenes[checked], first[checked], last[checked], steps[checked], found)
        proved = bound.counters[1] == before  # no sample of the call went to MuJoCo
    for c in range(len(checked)):
        i = checked[c]
        hits[i] = found[c]
        if proved:
            ep.copy_verdicts[slots[i]] = COPY_HIT if found[c] else COPY_FREE
        else:
            ep.copy_verdicts[slots[i]] = COPY_UNPROVED
    copies = np.flatnonzero(owner >= 0)
    if proved:
        for copy in copies:
            hits[copy] = hits[owner[copy]]
    elif len(copies):
        found = np.empty(len(copies), dtype=np.bool_)
        _check(bound, scenes[copies], first[copies], last[copies], steps[copies], found)
        for c in range(len(copies)):
            hits[copies[c]] = found[c]


@njit
def _copy_owners(ep, rows, first, last, steps, hits):
    """Per path of :func:`_copy_verdicts` its memo slot and who decides it (``owner``):
    −2 a proved verdict in the memo (into ``hits``), i ≥ 0 path i of this call, −1 the
    path itself, which then holds its slot pending until its verdict is in."""
    misses = len(steps)
    owner = np.full(misses, -1, dtype=np.int64)
    slots = np.empty(misses, dtype=np.int64)
    key = np.empty(2 * first.shape[1] + 1, dtype=np.int64)
    for i in range(misses):
        token = ep.tokens[rows[i]]
        _copy_key(ep.revolute, first[i], last[i], steps[i], key)
        slot = _copy_slot(ep, token, key)
        slots[i] = slot
        state = ep.copy_verdicts[slot]
        if state == COPY_FREE or state == COPY_HIT:
            hits[i], owner[i] = state == COPY_HIT, -2
        elif state == COPY_PENDING:
            owner[i] = ep.copy_owner[slot]
        else:
            if state == COPY_EMPTY:
                ep.copy_keys[slot] = key
                ep.copy_tokens[slot] = token
                ep.copy_count[0] += 1
            ep.copy_verdicts[slot], ep.copy_owner[slot] = COPY_PENDING, i
    return owner, slots


@njit
def _copy_key(revolute, start, end, steps, key):
    """The turn-copy key of the path ``start`` → ``end`` (``steps``) into ``key``: both
    ends less the start's whole turns of each revolute joint, rounded to
    1 / ``COPY_GRID``, then the grid."""
    dof = len(start)
    for j in range(dof):
        shift = 2.0 * np.pi * np.rint(start[j] / (2.0 * np.pi)) if revolute[j] else 0.0
        key[j] = np.int64(np.rint((start[j] - shift) * COPY_GRID))
        key[dof + j] = np.int64(np.rint((end[j] - shift) * COPY_GRID))
    key[2 * dof] = steps


@njit(inline="always")
def _copy_slot(ep, token, key):
    """The turn-copy memo slot of ``key`` in scene ``token``: where it is, or the empty
    slot where it would go."""
    return _slot(ep.copy_keys, ep.copy_tokens, ep.copy_verdicts, token, key)


# ------------------------------------------------------------------ process continuity
@njit(inline="always")
def _blocked(ep, r, w, b):
    """Row ``r``'s move into branch ``b`` of its next waypoint ``w`` reconfigures the arm
    inside a process segment (``envs.process``; never without continuity)."""
    if not ep.inside[r, w]:
        return False
    last = ep.branch[r]
    config = UNKNOWN if last < 0 else ep.configuration[last]
    return move_blocked(ep.q[r], config, ep.candidates[r, w, b], ep.configuration[b],
                        ep.limits[r], ep.revolute)


# A field of ``ep`` read in a loop over the K branches costs a reference count taken and
# dropped per read, more than the test it serves: the loops below read each field once.
@njit(inline="always")
def _allowed_row(ep, r, w, out):
    """``out[b]``: branch b of row ``r``'s next waypoint ``w`` is in its action mask (valid,
    and not :func:`_blocked`), for every b."""
    valid = ep.valid
    if not ep.inside[r, w]:  # no process segment: nothing is blocked
        for b in range(len(out)):
            out[b] = valid[r, w, b]
        return
    for b in range(len(out)):
        out[b] = valid[r, w, b] and not _blocked(ep, r, w, b)


@njit(inline="always")
def _blocked_row(ep, r, w, out):
    """``out[b]`` = :func:`_blocked` (row ``r``, waypoint ``w``, branch b) for every b."""
    if not ep.inside[r, w]:
        out[:] = False
        return
    for b in range(len(out)):
        out[b] = _blocked(ep, r, w, b)


@njit
def masks(ep, rows, out):
    """``out[i]`` (K): the action mask of row ``rows[i]`` — the valid branches of its next
    waypoint that do not reconfigure the arm inside a process segment; every branch once
    its episode is over (any action then)."""
    index, lengths = ep.index, ep.lengths
    for i in range(len(rows)):
        r = rows[i]
        w = index[r]
        if w >= lengths[r]:
            out[i] = True
        else:
            _allowed_row(ep, r, w, out[i])


# ---------------------------------------------------------------------------- survey
@njit
def survey(ep, bound, rows):
    """Price the moves of ``rows`` from their current state and assemble their
    observations (module docstring)."""
    live_count = 0
    live = np.empty(len(rows), dtype=np.int64)
    for r in rows:
        if ep.index[r] < ep.lengths[r]:
            live[live_count] = r
            live_count += 1
    live = live[:live_count]
    if ep.numbers[CHECKED_MOVES] > 0:
        collision = _least_travel_paths(ep, bound, live)
    else:
        collision = _slot_paths(ep, bound, live)
        if live_count:
            _price_rows(ep, live, collision)
    onward = np.full(collision.shape, np.inf)
    ahead = np.full(collision.shape, np.inf)
    if ep.layout[ONWARD0] >= 0:
        _onward(ep, bound, live, collision, onward, ahead)
    _observe(ep, rows, live, collision, onward, ahead)


@njit(inline="always")
def _slot_paths(ep, bound, live):
    """(len(live), K): the move from each row's configuration to each valid branch of its
    next waypoint collides (its path; at a free start the branch's own configuration)."""
    k = ep.valid.shape[2]
    collision = np.zeros((len(live), k), dtype=np.bool_)
    lines = np.empty(len(live) * k, dtype=np.int64)
    branches = np.empty(len(live) * k, dtype=np.int64)
    count = 0
    allowed, endpoint = np.empty(k, dtype=np.bool_), ep.endpoint
    for line in range(len(live)):
        r = live[line]
        w = ep.index[r]
        still = ep.free_start[r] and w == 0
        _allowed_row(ep, r, w, allowed)
        for b in range(k):
            if not allowed[b]:
                continue
            if still:
                collision[line, b] = endpoint[r, 0, b]
                continue
            lines[count], branches[count] = line, b
            count += 1
    if count:
        rows, branches = live[lines[:count]], branches[:count]
        hits = _paths_collide(ep, bound, rows, ep.q[rows], _targets(ep, rows, branches))
        for i in range(count):
            collision[lines[i], branches[i]] = hits[i]
    return collision


@njit(inline="always")
def _least_travel_paths(ep, bound, live):
    """:func:`_slot_paths` where the batch checks ``CHECKED_MOVES`` = n moves, and the
    prices of ``live`` rows: per row its allowed moves in order of least travel (ties: the
    lower branch) are checked until n of them are free or none is left; the rest stay
    unchecked (``ep.checked`` False) and read as colliding here, so neither the
    observation nor the onward search takes them for free. Their price is that of a free
    move until :func:`advance` checks one that is taken. At a free start every verdict is
    the branch's own configuration's: nothing is left unchecked."""
    count, k = len(live), ep.valid.shape[2]
    collision = np.zeros((count, k), dtype=np.bool_)
    if not count:
        return collision
    _price_rows(ep, live, collision)  # the travel that orders the moves
    order, size = _travel_order(ep, live, collision)
    done, free = np.zeros(count, dtype=np.int64), np.zeros(count, dtype=np.int64)
    target = int(ep.numbers[CHECKED_MOVES])
    while True:  # a round: each row's next moves, as many as it lacks free ones
        lines, branches = _next_checks(order, size, done, free, target)
        if not len(lines):
            break
        rows = live[lines]
        hits = _paths_collide(ep, bound, rows, ep.q[rows], _targets(ep, rows, branches))
        for i in range(len(lines)):
            collision[lines[i], branches[i]] = hits[i]
            free[lines[i]] += 0 if hits[i] else 1
    checked = ep.checked
    for line in range(count):
        for i in range(done[line], size[line]):
            checked[live[line], order[line, i]] = False
    _price_rows(ep, live, collision)
    for line in range(count):
        for i in range(done[line], size[line]):
            collision[line, order[line, i]] = True
    return collision


@njit(inline="always")
def _travel_order(ep, live, collision):
    """Per line of ``live``: its allowed moves by least priced travel (ties: the lower
    branch) in ``order[line, :size[line]]``, each marked checked until found otherwise; at
    a free start none (``collision`` takes the branches' own verdicts)."""
    count, k = len(live), ep.valid.shape[2]
    order = np.empty((count, k), dtype=np.int64)
    size = np.zeros(count, dtype=np.int64)
    checked, endpoint = ep.checked, ep.endpoint
    mask = np.empty(k, dtype=np.bool_)
    for line in range(count):
        r = live[line]
        w = ep.index[r]
        still = ep.free_start[r] and w == 0
        allowed = np.empty(k, dtype=np.int64)
        _allowed_row(ep, r, w, mask)
        for b in range(k):
            checked[r, b] = True
            if not mask[b]:
                continue
            if still:
                collision[line, b] = endpoint[r, 0, b]
                continue
            allowed[size[line]] = b
            size[line] += 1
        picked = allowed[: size[line]]
        ranked = np.argsort(ep.values[r, 1][picked], kind="mergesort")
        order[line, : size[line]] = picked[ranked]
    return order, size


@njit
def _next_checks(order, size, done, free, target):
    """(lines, branches) of a round of :func:`_least_travel_paths`: each line's next moves
    in ``order``, as many as it lacks free ones of ``target`` (``done`` advances)."""
    asked = 0
    for line in range(len(size)):
        asked += min(target - free[line], size[line] - done[line])
    lines, branches = np.empty(asked, dtype=np.int64), np.empty(asked, dtype=np.int64)
    i = 0
    for line in range(len(size)):
        for _ in range(min(target - free[line], size[line] - done[line])):
            lines[i], branches[i] = line, order[line, done[line]]
            done[line] += 1
            i += 1
    return lines, branches


@njit
def _targets(ep, rows, branches):
    """(M, dof): branch ``branches[m]`` of row ``rows[m]``'s next waypoint."""
    out = np.empty((len(rows), ep.q.shape[1]))
    for m in range(len(rows)):
        out[m] = ep.candidates[rows[m], ep.index[rows[m]], branches[m]]
    return out


@njit(inline="always")
def _check_taken(ep, bound, rows, actions):
    """Moves among ``rows``' actions that :func:`survey` left unchecked: their paths are
    checked (one kernel call), and a row whose move collides is priced again."""
    taken = np.empty(len(rows), dtype=np.int64)
    count = 0
    for i in range(len(rows)):
        r = rows[i]
        if ep.index[r] < ep.lengths[r] and not ep.checked[r, actions[i]]:
            taken[count] = i
            count += 1
    if not count:
        return
    owners, moves = rows[taken[:count]], actions[taken[:count]]
    hits = _paths_collide(ep, bound, owners, ep.q[owners], _targets(ep, owners, moves))
    for m in range(count):
        r, a = owners[m], moves[m]
        ep.checked[r, a] = True
        if hits[m]:
            collision = np.zeros((1, ep.valid.shape[2]), dtype=np.bool_)
            collision[0, a] = True
            _price_rows(ep, owners[m : m + 1], collision)


@njit
def _price_rows(ep, live, collision):
    """Every term of every move of ``live`` rows: one ``_price`` call."""
    count, k, dof = len(live), ep.valid.shape[2], ep.q.shape[1]
    origins = np.empty((count, 1, dof))
    candidates = np.empty((count, k, dof))
    valid = np.empty((count, k), dtype=np.bool_)
    waypoints = np.empty(count, dtype=np.int64)
    free_start = np.empty(count, dtype=np.bool_)
    lengths = np.empty(count, dtype=np.int64)
    verdicts = np.empty((count, 1, k), dtype=np.bool_)
    blocked = np.zeros((count, 1, k), dtype=np.bool_)
    for line in range(count):
        r = live[line]
        w = ep.index[r]
        origins[line, 0] = ep.q[r]
        candidates[line] = ep.candidates[r, w]
        valid[line] = ep.valid[r, w]
        waypoints[line], free_start[line], lengths[line] = w, ep.free_start[r], ep.lengths[r]
        verdicts[line, 0] = collision[line]
        _blocked_row(ep, r, w, blocked[line, 0])
    values = np.empty((ep.values.shape[1], count, 1, k))
    flags = np.empty((3, count, 1, k), dtype=np.bool_)
    numbers = ep.numbers
    _price(origins, candidates, valid, waypoints, verdicts, blocked, free_start, lengths,
           ep.weights,
           ep.speeds, numbers[TRAVEL_WEIGHT], numbers[TIME_WEIGHT], numbers[COLLISION_PENALTY],
           numbers[INVALID_PENALTY], numbers[TERMINATE] != 0.0, numbers[MAX_COST], values,
           flags)
    for line in range(count):
        r = live[line]
        ep.values[r] = values[:, line, 0]
        ep.flags[r] = flags[:, line, 0]


@njit
def _onward(ep, bound, live, collision, onward, ahead):
    """``onward[line]`` (K): per branch of a live row's next waypoint reachable without a
    hit, the least travel onward along a free path (+inf where none, and at the last
    waypoint): ``envs.moves.least_free_travel``, every row's rounds together. Where the
    layout has the free travel of ``ONWARD_MOVES`` = n ≥ 2 moves, ``ahead[line]`` (K):
    the least travel of the next n moves (fewer where the task ends sooner) along free
    paths, each ending in a free configuration."""
    inner, rows, pending = _onward_lines(ep, live, collision)
    count, k = pending.shape
    if not count:
        return
    waypoints = ep.index[rows]
    asking = pending.copy()
    free = _free_branches(ep, rows, waypoints + 1, np.zeros((count, k)))
    here, there, travel = _moves(ep, rows, waypoints, free, asking)
    out = _search(ep, bound, rows, here, there, travel, asking)
    for m in range(count):
        onward[inner[m]] = out[m]
    if ep.layout[AHEAD0] < 0:
        return
    # Backwards from the farthest move: the cost of a branch of waypoint w + j is the
    # least travel of the moves from it to waypoint w + n (0 at w + n and at the task's
    # last waypoint), +inf where no free path goes on. Every branch of w + j ≥ w + 2;
    # those of w + 1 only as the last two moves' search asks for them.
    costs = np.zeros((count, k))
    for j in range(int(ep.numbers[ONWARD_MOVES]) - 1, 1, -1):
        lines = np.empty(count, dtype=np.int64)
        deep = 0
        for m in range(count):
            if waypoints[m] + j + 1 < ep.lengths[rows[m]]:
                lines[deep] = m
                deep += 1
        if not deep:
            continue
        lines = lines[:deep]
        layer_waypoints = waypoints[lines] + j
        asking = _free_branches(ep, rows[lines], layer_waypoints, np.zeros((deep, k)))
        here, there, travel = _costed_moves(ep, rows[lines], layer_waypoints, asking,
                                            costs[lines])
        layer = _search(ep, bound, rows[lines], here, there, travel, asking)
        for i in range(deep):
            costs[lines[i]] = layer[i]
    out = _least_two_moves(ep, bound, rows, waypoints, pending, costs)
    for m in range(count):
        ahead[inner[m]] = out[m]


@njit(inline="always")
def _least_two_moves(ep, bound, rows, waypoints, pending, costs):
    """The search of :func:`_onward`'s layers over two moves, the same values: per line m
    and branch a of waypoint w = ``waypoints[m]`` where ``pending[m, a]``, the least
    travel(a → c) + travel(c → d) + ``costs[m, d]`` along free paths (c a free branch of
    w + 1, d one of w + 2 with a finite cost; c alone where w + 1 is the task's last
    waypoint).

    The cost of c (its least way on) is found only when a search asks for it: each branch
    a takes its cheapest untried c by travel(a → c) + the cost of c where known, else its
    lower bound, the least travel(c → d) + ``costs[m, d]`` over every d regardless of
    paths. A pick whose cost is a bound is costed first and picked again; a costed pick
    is checked. Bounds never exceed costs, so the first free costed pick is the cheapest
    (ties: the lower index, as the eager search takes them). Moves that would reconfigure
    the arm inside a process segment are no moves. ``pending`` is consumed."""
    lines, middle, mid, far, targets = _second_moves(ep, rows, waypoints, costs)
    deep_costs = costs[lines]
    estimate, known, at = _cost_bounds(ep, rows, waypoints, lines, mid, far, targets,
                                       deep_costs)
    # The first moves: into the branches of w + 1 with a finite cost bound.
    here, there, first = _moves(ep, rows, waypoints, estimate < np.inf, pending)
    count, k = pending.shape
    # What each asking branch has tried, one row per branch that asks (most do not).
    slot = np.full((count, k), -1, dtype=np.int64)
    asking = 0
    for m in range(count):
        for a in range(k):
            if pending[m, a]:
                slot[m, a] = asking
                asking += 1
    tried = np.zeros((asking, k), dtype=np.bool_)
    out = np.full((count, k), np.inf)
    while True:
        asked_lines, asked_branches = _pending_rows(pending)
        if not len(asked_lines):
            break
        columns = np.full(len(asked_lines), -1, dtype=np.int64)
        need = np.zeros((len(lines), k), dtype=np.bool_)
        if _pick(first, estimate, known, at, tried, slot, asked_lines, asked_branches,
                 pending, columns, need):  # cost the bounded picks, then pick again
            _cost_picks(ep, bound, rows, lines, middle, mid, far, targets, deep_costs,
                        need, estimate, known)
            continue
        picked = columns >= 0
        asked_lines, asked_branches = asked_lines[picked], asked_branches[picked]
        columns = columns[picked]
        starts = _rows_of(here, asked_lines, asked_branches)
        hits = _paths_collide(ep, bound, rows[asked_lines], starts,
                              _rows_of(there, asked_lines, columns))
        for i in range(len(columns)):
            m, a, c = asked_lines[i], asked_branches[i], columns[i]
            if hits[i]:
                tried[slot[m, a], c] = True
            else:
                out[m, a] = first[m, a, c] + estimate[m, c]
                pending[m, a] = False
    return out


@njit(inline="always")
def _cost_picks(ep, bound, rows, lines, middle, mid, far, targets, costs, need, estimate,
                known):
    """The cost of every pick of :func:`_least_two_moves` to cost (``need[i, c]``, branch
    c of line ``lines[i]``'s waypoint w + 1): the least travel(c → d) + ``costs[i, d]``
    over the d its free paths reach, into ``estimate`` (``known``). One search over the
    picks, each its own line of one branch: only their moves are summed (as
    :func:`_costed_moves` sums them: travel, a move reconfiguring the arm inside a process
    segment none, then the cost of its end)."""
    count, k = need.shape
    dof = ep.q.shape[1]
    picks = 0
    for i in range(count):
        for c in range(k):
            picks += need[i, c]
    owners, branches = np.empty(picks, dtype=np.int64), np.empty(picks, dtype=np.int64)
    here, there = np.empty((picks, 1, dof)), np.empty((picks, k, dof))
    ends = np.empty((picks, k), dtype=np.bool_)
    travel = np.empty((picks, 1, k))
    asking = np.ones((picks, 1), dtype=np.bool_)
    q = 0
    for i in range(count):
        for c in range(k):
            if need[i, c]:
                owners[q], branches[q] = i, c
                here[q, 0], there[q], ends[q] = mid[i, c], far[i], targets[i]
                q += 1
    _onward_travel(here, there, asking, ends, ep.weights, travel)
    for q in range(picks):
        i, c = owners[q], branches[q]
        asking[q, 0] = asking[q, 0] and _block_moves_from(
            ep, rows[lines[i]], middle[i] + 1, here[q, 0], c, there[q], travel[q, 0])
        for d in range(k):
            travel[q, 0, d] += costs[i, d]
    found = _search(ep, bound, rows[lines[owners]], here, there, travel, asking)
    for q in range(picks):
        m = lines[owners[q]]
        estimate[m, branches[q]], known[m, branches[q]] = found[q, 0], True


@njit
def _rows_of(configurations, lines, branches):
    """(M, dof): ``configurations[lines[i], branches[i]]`` per i."""
    out = np.empty((len(lines), configurations.shape[2]))
    for i in range(len(lines)):
        out[i] = configurations[lines[i], branches[i]]
    return out


@njit(inline="always")
def _second_moves(ep, rows, waypoints, costs):
    """The second moves of :func:`_least_two_moves`, for the lines whose task has
    waypoint w + 2 (``lines``): their waypoints w + 1 (``middle``), the branches of both
    ends (``mid``, ``far``) and the free branches of w + 2 with a finite cost
    (``targets``). Their travel is summed where it is asked for: every move's in
    :func:`_cost_bounds`, and a move's own row where its cost is searched."""
    count, k = costs.shape
    lines = np.empty(count, dtype=np.int64)
    deep = 0
    for m in range(count):
        if waypoints[m] + 2 < ep.lengths[rows[m]]:
            lines[deep] = m
            deep += 1
    lines = lines[:deep]
    middle = waypoints[lines] + 1
    dof = ep.q.shape[1]
    mid, far = np.empty((deep, k, dof)), np.empty((deep, k, dof))
    for i in range(deep):
        r, w = rows[lines[i]], middle[i]
        mid[i], far[i] = ep.candidates[r, w], ep.candidates[r, w + 1]
    targets = _free_branches(ep, rows[lines], middle + 1, costs[lines])
    return lines, middle, mid, far, targets


@njit
def _cost_bounds(ep, rows, waypoints, lines, mid, far, targets, costs):
    """Per line and branch c of w + 1: what is known of its cost (``estimate``; ``known``
    where it is the cost): for its free branches 0 where w + 1 is the task's last
    waypoint, else the least of its second moves regardless of paths, travel(c → d) +
    ``costs[i, d]`` over the ``targets`` d it may move to (+inf where it has none, and
    for the other branches); ``at``: each line's index in ``lines`` (−1: none).

    A second move's travel is summed as :func:`_costed_moves` sums it (Σ_j w_j|Δq_j| in
    joint order, then the cost of its end), over every d of one c at once with the
    joints of w + 2 laid out by joint (a loop the compiler vectorises), and only its
    least is kept."""
    count, k = len(rows), ep.valid.shape[2]
    dof = ep.q.shape[1]
    estimate = np.full((count, k), np.inf)
    known = np.zeros((count, k), dtype=np.bool_)
    at = np.full(count, -1, dtype=np.int64)
    weights, valid, endpoint = ep.weights, ep.valid, ep.endpoint
    across = np.empty((dof, k))
    travel = np.empty(k)
    for i in range(len(lines)):
        m = lines[i]
        r, w = rows[m], waypoints[m] + 1
        at[m] = i
        _by_joint(far[i], across)
        for c in range(k):
            if valid[r, w, c] and not endpoint[r, w, c]:
                _travel_to_all(mid[i, c], across, weights, travel)
                estimate[m, c] = _least_second(ep, r, w + 1, c, mid[i, c], far[i], travel,
                                               targets[i], costs[i])
    for m in range(count):
        if at[m] < 0:
            r, w = rows[m], waypoints[m] + 1
            for c in range(k):
                if valid[r, w, c] and not endpoint[r, w, c]:
                    estimate[m, c], known[m, c] = 0.0, True
    return estimate, known, at


@njit(inline="always")
def _least_second(ep, r, w, c, start, ends, travel, targets, costs):
    """The least ``travel[d]`` + ``costs[d]`` over the ``targets`` d of waypoint ``w``
    (row ``r``) that branch ``c`` (at ``start``) may move to: none that reconfigures the
    arm inside a process segment; +inf where none is left. ``travel`` is overwritten."""
    _block_moves_from(ep, r, w, start, c, ends, travel)
    least = np.inf
    for d in range(len(travel)):
        if targets[d]:
            least = min(least, travel[d] + costs[d])
    return least


@njit
def _pick(first, estimate, known, at, tried, slot, lines, branches, pending, columns, need):
    """One round's picks of :func:`_least_two_moves`: per asking (``lines[i]``,
    ``branches[i]``) its cheapest untried c (ties: the lower index) into ``columns[i]``
    where c's cost is known; where it is a bound, ``need[at[line], c]`` instead (True is
    returned) and ``columns[i]`` stays −1; none left: the branch asks no more.
    ``tried[slot[m, a], c]``: branch a of line m found its path to c colliding."""
    costing = False
    for i in range(len(lines)):
        m, a = lines[i], branches[i]
        best, pick = np.inf, -1
        for c in range(first.shape[2]):
            travel = first[m, a, c]
            if not travel < np.inf or tried[slot[m, a], c]:
                continue
            value = travel + estimate[m, c]
            if value < best:
                best, pick = value, c
        if pick < 0:  # no way on left: +inf, done
            pending[m, a] = False
        elif not known[m, pick]:
            need[at[m], pick] = True
            costing = True
        else:
            columns[i] = pick
    return costing


@njit
def _free_branches(ep, rows, waypoints, costs):
    """(M, K): per line m the branches of waypoint ``waypoints[m]`` of row ``rows[m]``
    that are valid, whose configuration is free and whose ``costs[m]`` is finite."""
    count, k = costs.shape
    out = np.empty((count, k), dtype=np.bool_)
    valid, endpoint = ep.valid, ep.endpoint
    for m in range(count):
        r, w = rows[m], waypoints[m]
        for b in range(k):
            out[m, b] = valid[r, w, b] and not endpoint[r, w, b] and costs[m, b] < np.inf
    return out


@njit
def _moves(ep, rows, waypoints, targets, pending):
    """The moves of each line m from the branches of waypoint ``waypoints[m]`` where
    ``pending[m]`` to those of the one after where ``targets[m]``: both ends (``here``,
    ``there``) and their travel (+inf where no move: to a branch outside ``targets``,
    reconfiguring the arm inside a process segment; the rows of branches not pending are
    left unwritten); branches left with none ask no more."""
    count, k = pending.shape
    dof = ep.q.shape[1]
    here, there = np.empty((count, k, dof)), np.empty((count, k, dof))
    for m in range(count):
        r, w = rows[m], waypoints[m]
        here[m], there[m] = ep.candidates[r, w], ep.candidates[r, w + 1]
    travel = np.empty((count, k, k))
    _onward_travel(here, there, pending, targets, ep.weights, travel)
    _block_onward(ep, rows, waypoints, here, there, travel, pending)
    return here, there, travel


@njit(inline="always")
def _costed_moves(ep, rows, waypoints, pending, costs):
    """:func:`_moves` into the free branches of the waypoint after with a finite cost, the
    travel of each plus the cost of its end ``costs[m, b]``."""
    targets = _free_branches(ep, rows, waypoints + 1, costs)
    here, there, travel = _moves(ep, rows, waypoints, targets, pending)
    for m in range(len(rows)):
        for a in range(travel.shape[1]):
            if pending[m, a]:  # the only rows :func:`_moves` writes
                for b in range(travel.shape[2]):
                    travel[m, a, b] += costs[m, b]
    return here, there, travel


@njit
def _search(ep, bound, rows, here, there, travel, pending):
    """(M, K): per line m (row ``rows[m]``) and branch a where ``pending[m, a]``, the
    least ``travel[m, a, b]`` over the b whose path ``here[m, a]`` → ``there[m, b]`` is
    free: cheapest first, one kernel call per round for every line (a small round asks
    each branch's next target too: :func:`_targets_ahead`); +inf where there is none.
    ``pending`` is consumed."""
    count, k = pending.shape
    last = np.full((count, k), -1, dtype=np.int64)
    out = np.full((count, k), np.inf)
    while True:
        lines, branches = _pending_rows(pending)
        if not len(lines):
            break
        columns = np.empty(len(lines), dtype=np.int64)
        _next_targets(lines, branches, travel, last, columns)
        asked = 0
        for i in range(len(lines)):  # rows with no target left: +inf, done
            if columns[i] < 0:
                pending[lines[i], branches[i]] = False
            else:
                lines[asked], branches[asked], columns[asked] = lines[i], branches[i], columns[i]
                asked += 1
        if not asked:
            break
        lines, branches, columns = lines[:asked], branches[:asked], columns[:asked]
        ahead = _targets_ahead(lines, branches, columns, travel, last)
        owners, starts, ends = _round_paths(rows, lines, branches, columns, ahead, here, there)
        hits = _paths_collide(ep, bound, owners, starts, ends)
        _take_or_try_next(lines, branches, columns, hits[:asked], travel, last, out, pending)
        _take_ahead(lines, branches, ahead, hits[asked:], travel, last, out, pending)
    return out


@njit(inline="always")
def _targets_ahead(lines, branches, columns, travel, last):
    """Per asking branch of a round of :func:`_search` of at most ``SPECULATE`` / 2, its
    target after ``columns[i]`` in the same order (−1: none, and for every branch of a
    larger round): where the first collides, the next round's check is made already.
    The answers stay those of one target a round; the calls are fuller and fewer."""
    asked = len(lines)
    ahead = np.full(asked, -1, dtype=np.int64)
    if 2 * asked <= SPECULATE:
        for i in range(asked):
            m, a = lines[i], branches[i]
            after = last[m, a]
            last[m, a] = columns[i]
            _next_targets(lines[i : i + 1], branches[i : i + 1], travel, last, ahead[i : i + 1])
            last[m, a] = after
    return ahead


@njit(inline="always")
def _round_paths(rows, lines, branches, columns, ahead, here, there):
    """The paths of a round of :func:`_search`: each asking branch's target, then the
    targets ahead (:func:`_targets_ahead`) in the same order; their rows, starts, ends."""
    asked, dof = len(lines), here.shape[2]
    total = asked
    for i in range(asked):
        total += ahead[i] >= 0
    owners = np.empty(total, dtype=np.int64)
    starts, ends = np.empty((total, dof)), np.empty((total, dof))
    at = asked
    for i in range(asked):
        m, a = lines[i], branches[i]
        owners[i] = rows[m]
        starts[i], ends[i] = here[m, a], there[m, columns[i]]
        if ahead[i] >= 0:
            owners[at] = rows[m]
            starts[at], ends[at] = here[m, a], there[m, ahead[i]]
            at += 1
    return owners, starts, ends


@njit(inline="always")
def _take_ahead(lines, branches, ahead, hits, travel, last, out, pending):
    """The targets ahead of a round (``hits``: theirs, in order) decide the branches whose
    first target collided, as the next round would have."""
    at = 0
    for i in range(len(lines)):
        if ahead[i] < 0:
            continue
        m, a = lines[i], branches[i]
        if pending[m, a]:
            if not hits[at]:
                out[m, a] = travel[m, a, ahead[i]]
                pending[m, a] = False
            else:
                last[m, a] = ahead[i]
        at += 1


@njit
def _block_onward(ep, rows, waypoints, here, there, travel, pending):
    """Onward moves (branch a of waypoint ``waypoints[m]`` → branch b of the one after)
    that would reconfigure the arm inside a process segment are no moves (+inf travel); a
    branch left with none onward asks no more."""
    for m in range(len(rows)):
        r = rows[m]
        w = waypoints[m] + 1
        if not ep.inside[r, w]:
            continue
        for a in range(travel.shape[1]):
            if pending[m, a]:
                pending[m, a] = _block_moves_from(ep, r, w, here[m, a], a, there[m],
                                                  travel[m, a])


@njit(inline="always")
def _block_moves_from(ep, r, w, start, c, ends, travel):
    """The moves from branch ``c`` (at ``start``) to the branches of row ``r``'s waypoint
    ``w`` (at ``ends``) that would reconfigure the arm inside a process segment are no
    moves: +inf in ``travel`` (K). Returns whether a move with a finite travel is left."""
    inside = ep.inside[r, w]
    left = False
    for d in range(len(travel)):
        if inside and travel[d] < np.inf and move_blocked(
                start, ep.configuration[c], ends[d], ep.configuration[d], ep.limits[r],
                ep.revolute):
            travel[d] = np.inf
        left = left or travel[d] < np.inf
    return left


@njit
def _onward_lines(ep, live, collision):
    """The live rows with a waypoint after the next (their lines ``inner``, rows) and the
    branches of their next waypoint asking onward (valid, reached without a hit)."""
    k = ep.valid.shape[2]
    inner = np.empty(len(live), dtype=np.int64)
    count = 0
    for line in range(len(live)):
        if ep.index[live[line]] + 1 < ep.lengths[live[line]]:
            inner[count] = line
            count += 1
    inner = inner[:count]
    pending = np.empty((count, k), dtype=np.bool_)
    rows = np.empty(count, dtype=np.int64)
    for m in range(count):
        line = inner[m]
        r = live[line]
        w = ep.index[r]
        rows[m] = r
        _allowed_row(ep, r, w, pending[m])
        for b in range(k):
            pending[m, b] = pending[m, b] and not collision[line, b]
    return inner, rows, pending


@njit
def _pending_rows(pending):
    """(lines, branches) of every True entry of ``pending``, in row-major order."""
    count = 0
    for m in range(pending.shape[0]):
        for a in range(pending.shape[1]):
            count += pending[m, a]
    lines, branches = np.empty(count, dtype=np.int64), np.empty(count, dtype=np.int64)
    i = 0
    for m in range(pending.shape[0]):
        for a in range(pending.shape[1]):
            if pending[m, a]:
                lines[i], branches[i] = m, a
                i += 1
    return lines, branches


@njit
def _observe(ep, rows, live, collision, onward, ahead):
    """The observations of ``rows``: each task's template at the row's waypoint, the
    configuration normalised (clipped to [−1, 1]), and for ``live`` rows slot 0's travel,
    path collisions and (where the layout has them) onward free travel, and the free
    travel of ``ONWARD_MOVES`` moves over that many times the scale."""
    layout, obs = ep.layout, ep.observation
    scale = ep.numbers[TRAVEL_SCALE]
    ahead_scale = scale * ep.numbers[ONWARD_MOVES]
    q, centre, half_range = ep.q, ep.centre, ep.half_range
    for r in rows:
        obs[r] = ep.templates[r, ep.index[r]]
        for j in range(layout[Q1] - layout[Q0]):
            value = (q[r, j] - centre[j]) / half_range[j]
            obs[r, layout[Q0] + j] = min(max(value, -1.0), 1.0)
    values = ep.values
    allowed = np.empty(ep.valid.shape[2], dtype=np.bool_)
    for line in range(len(live)):
        r = live[line]
        w = ep.index[r]
        _allowed_row(ep, r, w, allowed)
        for b in range(len(allowed)):
            travel = values[r, 1, b] / scale
            obs[r, layout[TRAVEL0] + b] = min(travel, 1.0) if allowed[b] else 1.0
            obs[r, layout[PATH0] + b] = 1.0 if collision[line, b] else 0.0
            if layout[ONWARD0] >= 0:
                obs[r, layout[ONWARD0] + b] = min(onward[line, b] / scale, 1.0)
            if layout[AHEAD0] >= 0:
                obs[r, layout[AHEAD0] + b] = min(ahead[line, b] / ahead_scale, 1.0)


# --------------------------------------------------------------------------- advance
@njit
def advance(ep, bound, rows, actions, values, flags, success):
    """Rows ``rows`` move to branch ``actions`` of their next waypoint: per row i the
    priced ``values[:, i]`` and ``flags[:, i]`` (terminal, collision, invalid) of the move
    and ``success[i]`` (the episode ended with every waypoint reached, no collision, no
    invalid branch) are written; the state advances. A move :func:`survey` left
    unchecked is checked first."""
    if ep.numbers[CHECKED_MOVES] > 0:
        _check_taken(ep, bound, rows, actions)
    for i in range(len(rows)):
        r, a = rows[i], actions[i]
        w = ep.index[r]
        for v in range(values.shape[0]):
            values[v, i] = ep.values[r, v, a]
        for f in range(3):
            flags[f, i] = ep.flags[r, f, a]
        terminated, hit, invalid = flags[0, i], flags[1, i], flags[2, i]
        if not invalid:
            ep.q[r] = ep.candidates[r, w, a]
            ep.branch[r] = a
        ep.index[r] = ep.lengths[r] if terminated else w + 1
        ep.collided[r] = ep.collided[r] or hit
        ep.invalid[r] = ep.invalid[r] or invalid
        success[i] = (terminated and w == ep.lengths[r] - 1 and not ep.collided[r]
                      and not ep.invalid[r])
