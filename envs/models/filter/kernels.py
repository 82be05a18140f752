"""The kernels: the free step around a sample, configuration checks and path checks.

A sample is decided by whichever proof holds: bounds that keep every pair farther than
its margin prove it free (and, along a path, its neighbours within the free step); inner
shapes of one pair closer than its margin prove it in contact (``layout.inner``; a
cylinder is also measured as itself against the other's inner sphere or capsule); MuJoCo's
``mj_kinematics`` + ``mj_collision`` decide the rest, called from the kernel. Every kernel
takes the scene stack's arrays and, per row or path, the scene it belongs to (a filter of
its own is a stack of one).
"""

from __future__ import annotations

import math

import numpy as np
from numba.core import types
from numba.experimental import structref

from ikbranch_gym.envs.jit import njit

from .. import native
from .lanes import (
    LANES,
    P_CURRENT,
    P_HI,
    P_LANE,
    P_LO,
    P_MID,
    P_OWNER,
    P_PATH,
    PATHS_FIELDS,
    PATHS_SCALAR,
)
from .layout import BOX, CAPSULE, CYLINDER, SPHERE
from .shapes import _axis_in_cylinder, _bound_pair, _box_box, _inner_distance, _skewers
from .tree import _forward, _local_speed, _path_rates, _path_sample, _place_slots, _slot_growth

#: What :func:`_sample_step` returns besides a free step (≥ 0).
UNDECIDED, CONTACT = -1.0, -2.0
#: Who decided a configuration (``check_configurations``' ``how``).
BY_BOUNDS, BY_WITNESS, BY_MUJOCO = 0, 1, 2
#: The filter's counters, in order: samples bounded, MuJoCo checks, exact pair bounds
#: computed, MuJoCo checks that found no contact (samples free that the bounds could not
#: prove free), samples a witness (:func:`_witnessed`) proved in contact, samples the
#: lanes bounded (:mod:`.lanes`; those they did not prove free are bounded again, and
#: counted, as "bounded"), calls of the lane kernel, lane samples the lanes' witnesses
#: proved in contact (those are not bounded again).
COUNTERS = ("bounded", "mujoco", "pair bounds", "mujoco found free", "witnessed",
            "lane samples", "lane calls", "lane contacts")
#: The fewest configurations, and samples a round, worth the lanes (a lane call costs
#: about as much for one sample as for four): with fewer the scalar kernel bounds them one
#: by one. Paths take the lanes from one on (a lone path fills them with 16 intervals).
LANE_MIN = 2
#: Where a scene's lanes are in its row of ``exact`` (``CompiledFilter``): the kernel's
#: address (0: no lanes), its ``Scene`` struct, the doubles of a call's work array, the
#: address of the path search that calls it (``lane_paths``).
LANE_FUNCTION, LANE_SCENE, LANE_WORK, LANE_PATHS = 6, 7, 8, 9


@njit(inline="always")
def _sample_step(tree, geometry, qpos, xpos, xmat, wpos, wrot, rates, coarse, cap, counters,
                 motion, local, witness, active):
    """The free step around the sample ``qpos``: the largest s ≤ ``cap`` (in path
    parameter t) such that every pair stays farther than its margin for |t − t_i| ≤ s, from
    lower bounds only; ``CONTACT`` if a witness proves a pair in contact (:func:`_witnessed`,
    only with ``witness``), ``UNDECIDED`` if neither proof holds (MuJoCo must decide).

    Bounding spheres first (``coarse``: their step per pair); exact container bounds only
    for pairs whose sphere step is below the best step found so far, the nearest first.
    A static pair's step is the larger of two valid ones: at the global rate (lever arms
    over all configurations), and, with ``local`` = (dq, growth, speeds), from the
    configuration itself: a moving slot's points move at most V0 + W·|t − t_i| per unit t
    (V0 from its actual distances to the hinge axes, W how fast later joints can change
    those), so within s they cover at most V0·s + W·s²/2. ``local`` None: configurations
    only (no step needed beyond 0). ``active``: which pairs the sphere pass tests
    (:func:`_sphere_steps`).
    """
    (body_parent, body_pos, body_rot, body_jntadr, body_jntnum, body_flags, jnt_type,
     jnt_qposadr, jnt_pos, jnt_axis, jnt_axis_code, qpos0) = tree
    (slot_body, slot_static, slot_pos, slot_rot, slot_type, slot_size, slot_radius,
     pair_a, pair_b, pair_margin, _, pair_reach, pair_kind, pair_fixed, slot_pairs,
     slot_inner, slot_inner_size, pair_contact, pair_skewer) = geometry
    _forward(body_parent, body_pos, body_rot, body_jntadr, body_jntnum, body_flags,
             jnt_type, jnt_qposadr, jnt_pos, jnt_axis, jnt_axis_code, qpos0, qpos, xpos,
             xmat)
    _place_slots(slot_body, slot_static, slot_pos, slot_rot, xpos, xmat, wpos, wrot)
    if local is not None:
        local[2][:] = -1.0  # per-slot V0, computed when a pair needs it
    # Bounding spheres (a half-space for a plane) farther apart than the pair can close
    # within ``cap`` cannot limit the step: no sqrt, no division for them. The others are
    # kept, with their sphere step, in ``coarse`` (pair, step) rows.
    survivors, nearest, nearest_step = _sphere_steps(slot_pairs, pair_a, wpos, pair_b,
                                                     pair_reach, pair_kind, pair_fixed, rates,
                                                     cap, coarse, active)
    best = cap
    if nearest_step >= best:
        return best
    # Finer bounds, the nearest pair first (it usually sets ``best``), then every pair whose
    # coarser bound could still limit the step: a's bounding sphere against a static b's
    # container, then the two containers.
    for visit in range(-1, survivors):
        row = nearest if visit < 0 else visit
        if (visit >= 0 and row == nearest) or coarse[row, 1] >= best:
            continue
        k = int(coarse[row, 0])
        a, b = pair_a[k], pair_b[k]
        ca, cb, rb, sb = _centre(wpos, a), _centre(wpos, b), _rotation(wrot, b), _size(slot_size, b)
        # A pair whose bound reaches ``enough`` cannot limit the step (nor, at a
        # configuration, be in contact): its bound need not be refined further.
        enough = pair_margin[k] + best * rates[k]
        ka, kb, ra, sa = slot_type[a], slot_type[b], _rotation(wrot, a), _size(slot_size, a)
        coarser = _coarser_gap(ka, ca, ra, sa, slot_radius[a], kb, cb, rb, sb, slot_static[b],
                               enough) - pair_margin[k]
        if coarser > 0.0 and (rates[k] == 0.0 or coarser >= best * rates[k]):
            continue
        counters[2] += 1
        # Both are lower bounds of the same distance.
        gap = max(coarser, _bound_pair(ka, ca, ra, sa, kb, cb, rb, sb, enough) - pair_margin[k])
        if not gap > 0.0:
            if not witness:
                return UNDECIDED
            return _witnessed(coarse, survivors, pair_a, pair_b, pair_contact, pair_skewer,
                              slot_inner, slot_inner_size, slot_type, slot_size, wpos, wrot)
        step = _rate_step(gap, rates[k])
        if local is not None and slot_static[b] and step < best:
            dq, growth, speeds = local
            if speeds[a] < 0.0:
                speeds[a] = _local_speed(a, motion, xpos, xmat, jnt_pos, jnt_axis, jnt_type,
                                         wpos, slot_radius[a], dq)
                growth[a] = _slot_growth(a, motion, jnt_type, dq)
            step = _local_step(step, gap, speeds[a], growth[a])
        if step < best:
            best = step
    return best


@njit
def _witnessed(coarse, survivors, pair_a, pair_b, pair_contact, pair_skewer, slot_inner,
               slot_inner_size, slot_type, slot_size, wpos, wrot):
    """``CONTACT`` if the inner shapes of a pair whose bounding spheres may be within its
    margin (a ``coarse`` row with step −1) are closer than the pair's contact distance
    (not a capsule skewering a box, which MuJoCo's capsule–box collider misses), or one's
    inner sphere or capsule is that close to the other's cylinder itself
    (``shapes._axis_in_cylinder``: a cylinder's inner shape leaves its rims out), else
    ``UNDECIDED``. The cylinder pass runs only where no inner pair proved a contact."""
    for row in range(survivors):
        k, limit = _witness_row(coarse, row, pair_contact)
        if k < 0:
            continue
        a, b = pair_a[k], pair_b[k]
        distance = _inner_distance(slot_inner[a], _centre(wpos, a), _rotation(wrot, a),
                                   _size(slot_inner_size, a), slot_inner[b], _centre(wpos, b),
                                   _rotation(wrot, b), _size(slot_inner_size, b))
        if distance < limit and not (pair_skewer[k] and _skewers(
                slot_inner[a], _centre(wpos, a), _rotation(wrot, a), _size(slot_inner_size, a),
                slot_inner[b], _centre(wpos, b), _rotation(wrot, b),
                _size(slot_inner_size, b))):
            return CONTACT
    for row in range(survivors):
        k, limit = _witness_row(coarse, row, pair_contact)
        if k < 0:
            continue
        for side in range(2):
            a, b = (pair_a[k], pair_b[k]) if side == 0 else (pair_b[k], pair_a[k])
            ka = slot_inner[a]
            if slot_type[b] == CYLINDER and (ka == SPHERE or ka == CAPSULE) and _axis_in_cylinder(
                    ka, _centre(wpos, a), _rotation(wrot, a), _size(slot_inner_size, a),
                    _centre(wpos, b), _rotation(wrot, b), _size(slot_size, b), limit):
                return CONTACT
    return UNDECIDED


@njit(inline="always")
def _witness_row(coarse, row, pair_contact):
    """(pair, its contact distance) of ``coarse`` row ``row`` if a witness may prove it
    in contact (its bounding spheres may be within the margin, and the pair has a
    witness at all), else (−1, −inf)."""
    if coarse[row, 1] >= 0.0:
        return -1, -math.inf
    k = int(coarse[row, 0])
    limit = pair_contact[k]
    if limit == -math.inf:
        return -1, limit
    return k, limit


@njit(inline="always")
def _rate_step(gap, rate):
    """How far (in t) a pair ``gap`` (> 0) beyond its margin stays so, closing at ``rate``:
    unlimited for a pair that cannot approach."""
    return gap / rate if rate > 0.0 else math.inf


@njit(inline="always")
def _sphere_steps(slot_pairs, pair_a, wpos, pair_b, pair_reach, pair_kind, pair_fixed, rates,
                  cap, coarse, active):
    """The bounding-sphere pass of :func:`_sample_step`: every pair that could limit the
    step within ``cap`` as a ``coarse`` row (pair, sphere step; −1 where the spheres may
    be within the margin). Returns (rows written, the row of the smallest step, that
    step; −1 and inf if none).

    ``active[0]`` ≥ 0: only the pairs ``active[1 : 1 + active[0]]`` are tested (the
    survivors of a path's first sample, a superset of every later sample's: each later
    sample's interval lies inside the first one's); −1: every pair, the survivors
    recorded there; −2: every pair, nothing recorded (configurations). One flat loop: a
    helper called per pair (numba reference-counts its array arguments) measured 10×
    slower."""
    survivors, nearest, nearest_step = 0, -1, math.inf
    listed = active[0]
    count = listed if listed >= 0 else len(pair_a)
    for i in range(count):
        k = active[1 + i] if listed >= 0 else i
        a = pair_a[k]
        reach = pair_reach[k]
        limit = reach + rates[k] * cap
        kind = pair_kind[k]
        if kind == 3:  # OUT_OF_REACH
            continue
        ax, ay, az = wpos[a, 0], wpos[a, 1], wpos[a, 2]
        if kind == 1:  # a fixed half-space
            height = (pair_fixed[k, 3] * (ax - pair_fixed[k, 0])
                      + pair_fixed[k, 4] * (ay - pair_fixed[k, 1])
                      + pair_fixed[k, 5] * (az - pair_fixed[k, 2]))
            if height >= limit:
                continue
            gap = height - reach
        else:
            if kind == 0:  # a fixed sphere
                dx, dy, dz = ax - pair_fixed[k, 0], ay - pair_fixed[k, 1], az - pair_fixed[k, 2]
            else:  # slot b's sphere
                b = pair_b[k]
                dx, dy, dz = ax - wpos[b, 0], ay - wpos[b, 1], az - wpos[b, 2]
            squared = dx * dx + dy * dy + dz * dz
            if squared >= limit * limit:
                continue
            gap = math.sqrt(squared) - reach
        step = _rate_step(gap, rates[k]) if gap > 0.0 else -1.0
        coarse[survivors, 0], coarse[survivors, 1] = k, step
        if step < nearest_step:
            nearest, nearest_step = survivors, step
        survivors += 1
    if listed == -1:
        for row in range(survivors):
            active[1 + row] = int(coarse[row, 0])
        active[0] = survivors
    return survivors, nearest, nearest_step


@njit(inline="always")
def _local_step(step, gap, v0, w):
    """A static pair's step from the configuration itself: a moving slot whose points move
    at most V0 + W·|t − t_i| per unit t covers at most V0·s + W·s²/2 within s, so the pair
    keeps ``gap`` for s < 2·gap/(V0 + √(V0² + 2·W·gap)); the larger of that and ``step``
    (the step at the global rate)."""
    root = math.sqrt(v0 * v0 + 2.0 * w * gap)
    if v0 + root > 0.0:
        step = max(step, 2.0 * gap / (v0 + root))
    return step


@njit(inline="always")
def _coarser_gap(ka, ca, ra, sa, radius_a, kb, cb, rb, sb, static_b, enough):
    """Cheap lower bounds on a pair's distance before the containers' own, for a box ``b``:
    a's bounding sphere against a static box, and the boxes around two solids by their
    separating axes (faces first, stopping at ``enough``: a few dozen operations where a
    capsule's exact distance to a box takes several times that); −inf where neither
    applies. Against other kinds the pair's own bound is about as cheap as these
    (``docs/models.md``), so they are not tried."""
    best = -math.inf
    if kb != BOX:
        return best
    if static_b:
        best = _bound_pair(SPHERE, ca, rb, (radius_a, 0.0, 0.0), kb, cb, rb, sb, math.inf)
        if best >= enough:
            return best
    if ka <= CYLINDER and kb <= CYLINDER and not (ka == BOX and kb == BOX):
        (a0, a1, a2), (b0, b1, b2) = _box_around(ka, sa), _box_around(kb, sb)
        best = max(best, _box_box(ca, ra, a0, a1, a2, cb, rb, b0, b1, b2, enough))
    return best


@njit(inline="always")
def _box_around(kind, size):
    """Half-sizes of the box (in the container's frame) around a sphere, capsule, box or
    cylinder container of ``size``."""
    if kind == SPHERE:
        return size[0], size[0], size[0]
    if kind == CAPSULE:
        return size[0], size[0], size[1] + size[0]
    if kind == CYLINDER:
        return size[0], size[0], size[1]
    return size[0], size[1], size[2]


@njit(inline="always")
def _centre(wpos, s):
    return (wpos[s, 0], wpos[s, 1], wpos[s, 2])


@njit(inline="always")
def _size(size, s):
    return (size[s, 0], size[s, 1], size[s, 2])


@njit(inline="always")
def _rotation(wrot, s):
    return (wrot[s, 0, 0], wrot[s, 0, 1], wrot[s, 0, 2], wrot[s, 1, 0], wrot[s, 1, 1],
            wrot[s, 1, 2], wrot[s, 2, 0], wrot[s, 2, 1], wrot[s, 2, 2])


@njit
def _exact_contacts(qpos, exact):
    """``mj_kinematics`` + ``mj_collision`` at ``qpos`` on a checker's ``MjData``
    (``exact``: the addresses of its qpos and ncon, of the two functions, of the model and
    the data): the contact count."""
    # call-arg: numba's stubs give an intrinsic's call the parameters of its definition,
    # typing context included, which a kernel's call does not pass; and type it as raising
    # (a call from Python does), so mypy checks nothing after the first call_model_data.
    for j in range(len(qpos)):
        native.store_float64(exact[0], j, qpos[j])  # type: ignore[call-arg]
    native.call_model_data(exact[2], exact[4], exact[5])  # type: ignore[call-arg]
    native.call_model_data(exact[3], exact[4], exact[5])
    return native.load_int32(exact[1])


@njit
def _work(tree, geometry):
    """Scratch arrays of one kernel call: body frames (static ones preset), slot frames
    (static ones set per scene: :func:`_enter`), per-pair rates and sphere steps."""
    body_xpos, body_xmat = tree[-2], tree[-1]
    slot_pos, slot_rot, pair_a = geometry[2], geometry[3], geometry[7]
    return (body_xpos.copy(), body_xmat.copy(), slot_pos[0].copy(), slot_rot[0].copy(),
            np.ones(len(pair_a)), np.empty((len(pair_a), 2)))


@njit(inline="always")
def _scene(geometry, e):
    """The geometry of scene ``e`` of the stack: its row of every per-scene array."""
    (slot_body, slot_static, slot_pos, slot_rot, slot_type, slot_size, slot_radius, pair_a,
     pair_b, pair_margin, pair_lever, pair_reach, pair_kind, pair_fixed, slot_pairs,
     slot_inner, slot_inner_size, pair_contact, pair_skewer) = geometry
    return (slot_body, slot_static, slot_pos[e], slot_rot[e], slot_type, slot_size[e],
            slot_radius[e], pair_a, pair_b, pair_margin, pair_lever[e], pair_reach[e],
            pair_kind[e], pair_fixed[e], slot_pairs, slot_inner[e], slot_inner_size[e],
            pair_contact, pair_skewer)


@njit(inline="always")
def _enter(scene, wpos, wrot):
    """Set the static slots' world frames of ``scene`` (one :func:`_scene`) in the slot
    frame arrays: they change only between scenes."""
    slot_static, slot_pos, slot_rot = scene[1], scene[2], scene[3]
    for s in range(len(slot_static)):
        if slot_static[s]:
            for i in range(3):
                wpos[s, i] = slot_pos[s, i]
                for j in range(3):
                    wrot[s, i, j] = slot_rot[s, i, j]


@njit
def _fill_qpos(qpos, qpos0, row):
    """``qpos`` = ``qpos0`` with its leading entries replaced by ``row``."""
    for j in range(len(qpos0)):
        qpos[j] = row[j] if j < len(row) else qpos0[j]


@njit
def path_steps(start_rows, end_rows, lever, resolution, out):
    """``out[m]`` = n = max(⌈D/δ − 1e−12⌉, 1) grid intervals of path m, where
    D = Σ_j lever_j·|Δq_j| summed in joint order (the one definition every backend uses,
    so a path has the same grid whether it is checked alone or in a batch). A start
    array with one row serves every end row."""
    for m in range(end_rows.shape[0]):
        start = start_rows[0] if start_rows.shape[0] == 1 else start_rows[m]
        bound = 0.0
        for j in range(end_rows.shape[1]):
            bound += lever[j] * abs(end_rows[m, j] - start[j])
        n = math.ceil(bound / resolution - 1e-12)
        out[m] = n if n > 1 else 1


@njit
def check_configurations(tree, geometry, motion, exact, scenes, rows, need, verdict, out,
                         how, counters):
    """``out[i]`` for configuration ``rows[i]`` (its leading qpos entries; the rest stay at
    ``qpos0``) in scene ``scenes[i]`` of the stack (one entry: every row's scene): 0 where
    the bounds prove it free, else MuJoCo's contact count, or with ``verdict`` 1 where
    a witness proves a contact; ``how[i]``: ``BY_BOUNDS``, ``BY_WITNESS`` or
    ``BY_MUJOCO``. ``need`` > 0: rows are checked in order until ``need`` free ones are
    found; the rows after are not checked (``out`` and ``how`` −1). ``counters``:
    :data:`COUNTERS`, added to."""
    if rows.shape[0] >= LANE_MIN and exact[scenes[0], LANE_FUNCTION] != 0:
        _lane_configurations(tree, geometry, motion, exact, scenes, rows, need, verdict, out,
                             how, counters)
        return
    work = _work(tree, geometry)
    qpos = np.empty(len(tree[11]))
    every_pair = np.full(1, -2, dtype=np.int64)
    free = 0
    entered = -1
    for i in range(rows.shape[0]):
        if need > 0 and free >= need:
            out[i] = how[i] = -1
            continue
        e = scenes[0] if len(scenes) == 1 else scenes[i]
        scene = _scene(geometry, e)
        if e != entered:
            _enter(scene, work[2], work[3])
            entered = e
        out[i], how[i] = _configuration(tree, scene, motion, exact[e], rows[i], verdict, qpos,
                                        work, every_pair, counters)
        if out[i] == 0:
            free += 1


@njit(inline="always")
def _configuration(tree, scene, motion, exact, row, verdict, qpos, work, every_pair,
                   counters):
    """(out, how) of :func:`check_configurations` for one row by the scalar kernel, the
    witnesses and MuJoCo (the slots' static frames already entered)."""
    xpos, xmat, wpos, wrot, rates, coarse = work
    _fill_qpos(qpos, tree[11], row)
    counters[0] += 1
    step = _sample_step(tree[:12], scene, qpos, xpos, xmat, wpos, wrot, rates, coarse, 0.0,
                        counters, motion, None, verdict, every_pair)
    if step >= 0.0:
        return 0, BY_BOUNDS
    if step == CONTACT:
        counters[4] += 1
        return 1, BY_WITNESS
    counters[1] += 1
    contacts = _exact_contacts(qpos, exact)
    if contacts == 0:
        counters[3] += 1
    return contacts, BY_MUJOCO


# The scalar kernel is inlined where it is the loop (``check_configurations``,
# ``check_paths``) and called where it only decides the few samples the lanes left:
# inlined there as well it costs compile time, not run time (docs/models.md).
@njit
def _configuration_called(tree, scene, motion, exact, row, verdict, qpos, work, every_pair,
                          counters):
    """:func:`_configuration`, compiled once as a function of its own."""
    return _configuration(tree, scene, motion, exact, row, verdict, qpos, work, every_pair,
                          counters)


@njit
def _sample_step_called(tree, geometry, qpos, xpos, xmat, wpos, wrot, rates, coarse, cap,
                        counters, motion, local, witness, active):
    """:func:`_sample_step`, compiled once as a function of its own."""
    return _sample_step(tree, geometry, qpos, xpos, xmat, wpos, wrot, rates, coarse, cap,
                        counters, motion, local, witness, active)


@njit
def _lane_configurations(tree, geometry, motion, exact, scenes, rows, need, verdict, out,
                         how, counters):
    """:func:`check_configurations` with the rows bounded ``LANES`` at a time (runs of one
    scene): a row the lanes prove free is free, one they prove in contact (a witness,
    with ``verdict``) is in contact, any other goes to the scalar kernel as there."""
    work = _work(tree, geometry)
    qpos = np.empty(len(tree[11]))
    every_pair = np.full(1, -2, dtype=np.int64)
    arrays, block = _lane_block(tree[11], len(geometry[7]), int(exact[scenes[0], LANE_WORK]))
    start, lane_step = arrays[0], arrays[5]
    free, entered, i, count = 0, -1, 0, rows.shape[0]
    while i < count:
        e = scenes[0] if len(scenes) == 1 else scenes[i]
        # A call costs about in proportion to its lanes: a few rows a free one wanted.
        most = LANES if need <= 0 else min(LANES, max(4 * (need - free), 1))
        width = 0
        while (i + width < count and width < most
               and (len(scenes) == 1 or scenes[i + width] == e)):
            for j in range(rows.shape[1]):
                start[j, width] = rows[i + width, j]
            width += 1
        if width >= LANE_MIN and (need <= 0 or free < need):
            _call_lanes(exact[e], block, width, counters)
        else:
            lane_step[:width] = UNDECIDED
        for lane in range(width):
            r = i + lane
            step = lane_step[lane]
            if need > 0 and free >= need:
                out[r] = how[r] = -1
                continue
            if step >= 0.0:
                out[r], how[r] = 0, BY_BOUNDS
            elif step == CONTACT and verdict:
                counters[7] += 1
                out[r], how[r] = 1, BY_WITNESS
            else:
                if e != entered:
                    _enter(_scene(geometry, e), work[2], work[3])
                    entered = e
                out[r], how[r] = _configuration_called(tree, _scene(geometry, e), motion,
                                                       exact[e], rows[r], verdict, qpos, work,
                                                       every_pair, counters)
            if out[r] == 0:
                free += 1
        i += width


@njit
def check_paths(tree, geometry, motion, exact, scenes, start_rows, end_rows, steps, first,
                out, counters):
    """``out[m]``: a grid index i of path m (q(t) = q0 + (i/n)(q1 − q0), n = ``steps[m]``;
    leading qpos entries, the rest at ``qpos0``) in scene ``scenes[m]`` of the stack (one
    entry: every path's scene) whose sample MuJoCo finds in contact, −1 if none has one.
    With ``first`` it is the lowest such index; otherwise the first one found (the verdict
    is the same). A start array with one row serves every end row.

    Samples are visited in raked order: the middle of every unresolved interval of grid
    indices, breadth first; a sample the bounds prove free clears every index within its
    free step on both sides, a sample a witness proves in contact is in contact,
    any other is checked by MuJoCo."""
    if len(steps) >= 1 and exact[scenes[0], LANE_FUNCTION] != 0:
        _lane_paths(tree, geometry, motion, exact, scenes, start_rows, end_rows, steps, first,
                    out, counters)
        return
    xpos, xmat, wpos, wrot, rates, coarse = _work(tree, geometry)
    kinematic = tree[:12]
    qpos0 = tree[11]
    nq = len(qpos0)
    dof = end_rows.shape[1]
    delta, qpos, start = np.zeros(nq), np.empty(nq), np.empty(nq)
    slots = len(motion[0])
    dq, growth, speeds = np.zeros(nq), np.zeros(slots), np.empty(slots)
    local = (dq, growth, speeds)
    size = _queue_size(steps)
    queue_lo, queue_hi = np.empty(size, np.int64), np.empty(size, np.int64)
    active = np.empty(len(geometry[7]) + 1, dtype=np.int64)
    entered = -1
    for m in range(len(steps)):
        n = steps[m]
        e = scenes[0] if len(scenes) == 1 else scenes[m]
        scene = _scene(geometry, e)
        if e != entered:
            _enter(scene, wpos, wrot)
            entered = e
        _fill_qpos(start, qpos0, start_rows[0] if start_rows.shape[0] == 1 else start_rows[m])
        _path_rates(start, end_rows, m, scene[10], delta, rates, dq)
        # The raked search stays here: as an inlined helper taking these arrays (numba
        # reference-counts them per call) it measured ~7 % slower on short paths.
        found = n + 1
        active[0] = -1  # the path's first sample lists the pairs that can matter
        settle = True
        head, tail = 0, 1  # circular queue of intervals [lo, hi]
        queue_lo[0], queue_hi[0] = 0, n
        while head != tail:
            lo, hi = queue_lo[head], queue_hi[head]
            head = (head + 1) % size
            if hi >= found:
                hi = found - 1
            if lo > hi:
                continue
            mid = (lo + hi) // 2
            fraction = mid / n
            _path_sample(qpos, start, delta, fraction, dof)
            counters[0] += 1
            step = _sample_step(kinematic, scene, qpos, xpos, xmat, wpos, wrot, rates,
                                coarse, max(mid - lo, hi - mid) / n, counters, motion, local,
                                True, active)
            settle = _settle(settle, step, active, rates)
            reach = 0
            if step < 0.0:
                if _sample_collides(step, qpos, exact[e], counters):
                    found = mid
                    if not first:
                        break
                    tail = _push_interval(queue_lo, queue_hi, tail, lo, mid - 1)
                    continue
            else:
                scaled = step * n
                reach = n if scaled >= n else int(scaled)
            tail = _push_interval(queue_lo, queue_hi, tail, lo, mid - reach - 1)
            tail = _push_interval(queue_lo, queue_hi, tail, mid + reach + 1, hi)
        out[m] = found if found <= n else -1


@njit
def _lane_paths(tree, geometry, motion, exact, scenes, start_rows, end_rows, steps, first,
                out, counters):
    """:func:`check_paths` with the samples of up to ``LANES`` paths bounded ``LANES`` at a
    time. Each path keeps the scalar loop's raked search (its queue of intervals, its lowest
    contact ``found``), started from a few intervals at once when its scene has few paths,
    so that one path alone fills the lanes. Each round takes the next interval of every
    path in turn until the lanes are full, bounds the intervals' middle samples in one call
    of the lane kernel (:mod:`.lanes`), and goes on as the scalar loop does: a sample it
    proves free clears its step on both sides, one it proves in contact is a contact; any
    other is bounded by the scalar kernel (witnesses, MuJoCo). A finished path's place
    takes the next path of the same scene; a new scene waits until every path has
    finished (one call reads one scene).

    The rounds run in C (``lane_paths`` in lanes.c, the state in a ``Paths`` struct); it
    hands back each sample the lanes leave undecided, which this loop bounds with the
    scalar kernel, and goes on from there. Every path's start, change and rates are
    computed here first, as the scalar loop computes them."""
    xpos, xmat, wpos, wrot, rates, coarse = _work(tree, geometry)
    qpos0 = tree[11]
    nq, npair, count = len(qpos0), len(geometry[7]), len(steps)
    grid = np.empty(count, dtype=np.int64)
    scene_of = np.empty(len(scenes), dtype=np.int64)
    grid[:], scene_of[:] = steps, scenes
    starts, changes = np.empty((count, nq)), np.zeros((count, nq))
    path_rates = np.zeros((count, npair))
    dq = np.zeros(nq)
    for m in range(count):
        e = scene_of[0] if len(scene_of) == 1 else scene_of[m]
        _fill_qpos(starts[m], qpos0, start_rows[0] if start_rows.shape[0] == 1 else start_rows[m])
        _path_rates(starts[m], end_rows, m, geometry[10][e], changes[m], rates, dq)
        path_rates[m] = rates[:npair]
    addresses = np.empty(exact.shape[0], dtype=np.int64)
    for e in range(exact.shape[0]):
        addresses[e] = exact[e, LANE_SCENE]
    size = _queue_size(grid)
    queue_lo, queue_hi = np.empty((LANES, size), np.int64), np.empty((LANES, size), np.int64)
    block_arrays, block = _lane_block(qpos0, npair, int(exact[scene_of[0], LANE_WORK]))
    lane_step, found = block_arrays[5], np.empty(count, dtype=np.int64)
    state = np.zeros(PATHS_FIELDS, dtype=np.int64)
    state[0], state[1], state[2], state[3] = count, nq, npair, 1 if first else 0
    state[4], state[5], state[6] = size, LANE_MIN, len(scene_of)
    state[7], state[8] = grid.ctypes.data, scene_of.ctypes.data
    state[9], state[10] = addresses.ctypes.data, starts.ctypes.data
    state[11], state[12] = changes.ctypes.data, path_rates.ctypes.data
    state[13], state[14] = found.ctypes.data, counters.ctypes.data
    state[15], state[16], state[17] = queue_lo.ctypes.data, queue_hi.ctypes.data, block.ctypes.data
    function = exact[scene_of[0], LANE_PATHS]
    kinematic, local = tree[:12], (dq, np.zeros(len(motion[0])), np.empty(len(motion[0])))
    qpos = np.empty(nq)
    every_pair = np.full(1, -2, dtype=np.int64)
    entered = -1
    while native.call_status(function, state.ctypes.data) == PATHS_SCALAR:  # type: ignore[call-arg]
        # The sample of lane ``state[P_LANE]``, left undecided by the lanes.
        lane, e = state[P_LANE], state[P_CURRENT]
        p = state[P_OWNER + lane]
        m = state[P_PATH + p]
        n, a, b, i = grid[m], state[P_LO + lane], state[P_HI + lane], state[P_MID + lane]
        if e != entered:
            _enter(_scene(geometry, e), wpos, wrot)
            entered = e
        rates[:npair] = path_rates[m]
        np.abs(changes[m], dq)
        _path_sample(qpos, starts[m], changes[m], i / n, nq)  # (no change past the dof)
        counters[0] += 1
        step = _sample_step_called(kinematic, _scene(geometry, e), qpos, xpos, xmat, wpos,
                                   wrot, rates, coarse, max(i - a, b - i) / n, counters,
                                   motion, local, True, every_pair)
        if step < 0.0 and not _sample_collides(step, qpos, exact[e], counters):
            step = 0.0  # free as MuJoCo found it
        lane_step[lane] = step
    out[:] = found
    _alive((grid, scene_of, addresses, starts, changes, path_rates, queue_lo, queue_hi,
            block, state), block_arrays)


@njit(inline="always")
def _alive(arrays, more):
    """Nothing: called last, it keeps the arrays C reads by their addresses alive until
    then (numba frees an array after its last use in the code)."""
    return len(arrays) + len(more)


@njit
def _sample_collides(step, qpos, exact, counters):
    """A sample the bounds did not prove free (``step`` < 0): in contact by a witness
    (``CONTACT``), else as MuJoCo finds it (counted as :func:`check_paths` counts)."""
    if step == CONTACT:
        counters[4] += 1
        return True
    counters[1] += 1
    if _exact_contacts(qpos, exact) > 0:
        return True
    counters[3] += 1
    return False


@njit(inline="always")
def _scene_run(scenes, taken, count):
    """How many paths from ``taken`` on share its scene (one entry: every path)."""
    if len(scenes) == 1:
        return count - taken
    run = 1
    while taken + run < count and scenes[taken + run] == scenes[taken]:
        run += 1
    return run


@njit
def _lane_block(qpos0, npair, work):
    """The lane kernel's ``Block`` (lanes.c) as an array of addresses, and the arrays they
    point at: start (qpos0 in every lane), change, t, cap, rates (zero), steps, work."""
    nq = len(qpos0)
    arrays = (np.empty((nq, LANES)), np.zeros((nq, LANES)), np.zeros(LANES), np.zeros(LANES),
              np.zeros((npair, LANES)), np.zeros(LANES), np.empty(work))
    for j in range(nq):
        arrays[0][j, :] = qpos0[j]
    block = np.empty(8, dtype=np.uint64)
    block[0], block[1] = arrays[0].ctypes.data, arrays[1].ctypes.data
    block[2], block[3] = arrays[2].ctypes.data, arrays[3].ctypes.data
    block[4], block[5] = arrays[4].ctypes.data, arrays[5].ctypes.data
    block[6] = arrays[6].ctypes.data
    return arrays, block


@njit
def _call_lanes(exact, block, width, counters):
    """Bound the first ``width`` lanes of ``block`` in the scene of ``exact`` (its row)."""
    block[7] = width
    native.call_model_data(exact[LANE_FUNCTION], exact[LANE_SCENE],  # type: ignore[call-arg]
                           block.ctypes.data)
    counters[5] += width
    counters[6] += 1


@njit(inline="always")
def _settle(first, step, active, rates):
    """After a path's ``first`` sample, proven free (``step`` ≥ 0): drop from ``active``
    the pairs whose rate along the path is 0. Their distance does not change along the
    path, and that sample's bounds kept it beyond the margin (every survivor of its
    sphere pass with a rate of 0 has a sphere step of −1, so it was bounded). Returns
    False: later samples settle nothing."""
    if not (first and step >= 0.0):
        return False
    keep = 0
    for i in range(active[0]):
        k = active[1 + i]
        if rates[k] > 0.0:
            active[1 + keep] = k
            keep += 1
    active[0] = keep
    return False


@njit(inline="always")
def _queue_size(steps):
    """Room for the interval queue of every path: its grid points, plus two."""
    size = 2
    for m in range(len(steps)):
        size = max(size, steps[m] + 2)
    return size


@njit(inline="always")
def _push_interval(queue_lo, queue_hi, tail, lo, hi):
    """Queue the interval [lo, hi] unless it is empty; returns the new tail."""
    if lo <= hi:
        queue_lo[tail], queue_hi[tail] = lo, hi
        tail = (tail + 1) % len(queue_lo)
    return tail


# ------------------------------------------------------------------------ bound calls
@structref.register
class _BoundType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(kind)) for name, kind in fields)


class Bound(structref.StructRefProxy):
    """A scene stack's kernel arguments as one object: ``tree``, ``geometry``, ``motion``
    (tuples of arrays), ``exact`` (the MuJoCo addresses per scene) and ``counters``. A
    kernel call unboxes it at once, where the ~45 arrays as separate arguments cost
    several µs a call (``bound_paths``, ``bound_configurations``)."""

    def __new__(cls, tree, geometry, motion, exact, counters):
        return structref.StructRefProxy.__new__(cls, tree, geometry, motion, exact, counters)


structref.define_proxy(Bound, _BoundType, ["tree", "geometry", "motion", "exact", "counters"])


@njit
def make_bound(tree, geometry, motion, exact, counters):
    """A :class:`Bound` of these arrays, made in compiled code: numba caches this on disk,
    where the proxy's own constructor is compiled again in every process (~0.5 s)."""
    return Bound(tree, geometry, motion, exact, counters)


@njit
def bound_paths(bound, scenes, start_rows, end_rows, steps, first, out):
    """:func:`check_paths` with the arguments of ``bound``."""
    check_paths(bound.tree, bound.geometry, bound.motion, bound.exact, scenes, start_rows,
                end_rows, steps, first, out, bound.counters)


@njit
def bound_configurations(bound, scenes, rows, need, verdict, out, how):
    """:func:`check_configurations` with the arguments of ``bound``."""
    check_configurations(bound.tree, bound.geometry, bound.motion, bound.exact, scenes, rows,
                         need, verdict, out, how, bound.counters)
