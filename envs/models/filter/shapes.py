"""Shape pairs: the distance of two shapes, in closed form, as bound or as witness.

One small function per pair of shapes (sphere, capsule, box, half-space). Applied to two
*containers* (a cylinder as the better of its capsule and its box) every value is a lower
bound of the geoms' distance, so a pair proven farther than its margin is free
(:func:`_bound_pair`). Applied to two *inner* shapes, which the geoms hold, the value is
at least the geoms' distance, so a pair proven closer than its margin is in contact
(:func:`_inner_distance`): sphere, capsule, box and half-space pairs are measured exactly;
two boxes by their edges (:func:`_box_box_distance`). A cylinder is also measured as itself
against the other's inner sphere or capsule (:func:`_axis_in_cylinder`): its own inner
shape leaves its rims out.
"""

from __future__ import annotations

import math

from ikbranch_gym.envs.jit import njit

from .layout import BOX, CAPSULE, CYLINDER, NO_INNER, PLANE, SPHERE, UNBOUNDED


@njit(inline="always")
def _clamp(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


@njit
def _point_segment_sq(px, py, pz, ax, ay, az, bx, by, bz):
    dx, dy, dz = bx - ax, by - ay, bz - az
    length = dx * dx + dy * dy + dz * dz
    t = 0.0
    if length > 0.0:
        t = _clamp(((px - ax) * dx + (py - ay) * dy + (pz - az) * dz) / length, 0.0, 1.0)
    ex, ey, ez = ax + t * dx - px, ay + t * dy - py, az + t * dz - pz
    return ex * ex + ey * ey + ez * ez


@njit
def _segment_segment_sq(p1x, p1y, p1z, q1x, q1y, q1z, p2x, p2y, p2z, q2x, q2y, q2z):
    """Squared distance of two segments (Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1x, d1y, d1z = q1x - p1x, q1y - p1y, q1z - p1z
    d2x, d2y, d2z = q2x - p2x, q2y - p2y, q2z - p2z
    rx, ry, rz = p1x - p2x, p1y - p2y, p1z - p2z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-18
    if a <= eps and e <= eps:
        return rx * rx + ry * ry + rz * rz
    if a <= eps:
        s, t = 0.0, _clamp(f / e, 0.0, 1.0)
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= eps:
            t, s = 0.0, _clamp(-c / a, 0.0, 1.0)
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            denom = a * e - b * b
            s = _clamp((b * f - c * e) / denom, 0.0, 1.0) if denom > eps * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t, s = 0.0, _clamp(-c / a, 0.0, 1.0)
            elif t > 1.0:
                t, s = 1.0, _clamp((b - c) / a, 0.0, 1.0)
    ex = p1x + d1x * s - (p2x + d2x * t)
    ey = p1y + d1y * s - (p2y + d2y * t)
    ez = p1z + d1z * s - (p2z + d2z * t)
    return ex * ex + ey * ey + ez * ez


@njit
def _to_box(px, py, pz, c, r):
    """World point -> box frame (``c`` centre, ``r`` rotation as a row-major 9-tuple,
    world = r @ local)."""
    dx, dy, dz = px - c[0], py - c[1], pz - c[2]
    return (r[0] * dx + r[3] * dy + r[6] * dz,
            r[1] * dx + r[4] * dy + r[7] * dz,
            r[2] * dx + r[5] * dy + r[8] * dz)


@njit
def _point_box(px, py, pz, c, r, h0, h1, h2):
    """Distance from a world point to a solid box of half-sizes h (0 inside)."""
    x, y, z = _to_box(px, py, pz, c, r)
    ex = max(abs(x) - h0, 0.0)
    ey = max(abs(y) - h1, 0.0)
    ez = max(abs(z) - h2, 0.0)
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit
def _piece_minimum(lo, hi, s0, s1, s2, d0, d1, d2, h0, h1, h2):
    """Least squared box distance of p(t) = s + t·d over [lo, hi], a piece on which no
    coordinate crosses a face plane: a quadratic qa t² + qb t + qc, minimised exactly."""
    mid = 0.5 * (lo + hi)
    qa = qb = qc = 0.0
    for k in range(3):
        if k == 0:
            s, d, h = s0, d0, h0
        elif k == 1:
            s, d, h = s1, d1, h1
        else:
            s, d, h = s2, d2, h2
        x = s + mid * d
        if x > h:
            offset = s - h
        elif x < -h:
            offset = s + h
        else:
            continue
        qa += d * d
        qb += 2.0 * d * offset
        qc += offset * offset
    if qa > 0.0:
        t = _clamp(-qb / (2.0 * qa), lo, hi)
    else:
        t = lo if qb > 0.0 else hi
    return (qa * t + qb) * t + qc


@njit(inline="always")
def _box_axis(axis, s0, s1, s2, d0, d1, d2, h0, h1, h2):
    """(start, direction, half-size) of the segment and the box along box axis ``axis``."""
    if axis == 0:
        return s0, d0, h0
    if axis == 1:
        return s1, d1, h1
    return s2, d2, h2


@njit(inline="always")
def _face_crossing(side, s, d, h):
    """(crosses, t): whether the segment s + t·d, 0 < t < 1, crosses the face plane at
    ``side``·h (``side`` ±1) strictly inside, and where; a parallel segment never does."""
    if d == 0.0:
        return False, 0.0
    t = (side * h - s) / d
    if not 0.0 < t < 1.0:
        return False, t
    return True, t


@njit(inline="always")
def _insert_sorted(t, c0, c1, c2, c3, c4, c5):
    """The sorted six-tuple c0 ≤ … ≤ c5 with ``t`` inserted in place of its largest entry
    (unused slots hold 2.0, above every breakpoint): one bubble pass, no allocation."""
    if t < c5:
        c5 = t
    if c5 < c4:
        c4, c5 = c5, c4
    if c4 < c3:
        c3, c4 = c4, c3
    if c3 < c2:
        c2, c3 = c3, c2
    if c2 < c1:
        c1, c2 = c2, c1
    if c1 < c0:
        c0, c1 = c1, c0
    return c0, c1, c2, c3, c4, c5


@njit(inline="always")
def _piece_end(piece, count, c0, c1, c2, c3, c4, c5):
    """Where piece ``piece`` of the segment ends: breakpoint ``piece`` of the sorted
    c0..c5, or t = 1 for the last piece (``piece`` == ``count``)."""
    if piece >= count:
        return 1.0
    if piece == 0:
        return c0
    if piece == 1:
        return c1
    if piece == 2:
        return c2
    if piece == 3:
        return c3
    if piece == 4:
        return c4
    return c5


@njit
def _segment_box(ax, ay, az, bx, by, bz, c, r, h0, h1, h2):
    """Exact distance from the segment a–b to a solid box: the squared distance along the
    segment is a sum of clamped quadratics, smooth between the breakpoints where a
    coordinate crosses a face plane; each piece is minimised in closed form."""
    s0, s1, s2 = _to_box(ax, ay, az, c, r)
    e0, e1, e2 = _to_box(bx, by, bz, c, r)
    d0, d1, d2 = e0 - s0, e1 - s1, e2 - s2
    # The ≤ 6 interior breakpoints, kept sorted by insertion (no allocation).
    c0 = c1 = c2 = c3 = c4 = c5 = 2.0
    count = 0
    for k in range(6):
        axis, side = k // 2, -1.0 if k % 2 == 0 else 1.0
        s, d, h = _box_axis(axis, s0, s1, s2, d0, d1, d2, h0, h1, h2)
        crosses, t = _face_crossing(side, s, d, h)
        if not crosses:
            continue
        c0, c1, c2, c3, c4, c5 = _insert_sorted(t, c0, c1, c2, c3, c4, c5)
        count += 1
    best = math.inf
    lo = 0.0
    for piece in range(count + 1):
        hi = _piece_end(piece, count, c0, c1, c2, c3, c4, c5)
        value = _piece_minimum(lo, hi, s0, s1, s2, d0, d1, d2, h0, h1, h2)
        if value < best:
            best = value
        lo = hi
    return math.sqrt(max(best, 0.0))


@njit
def _box_box(c1, r1, a0, a1, a2, c2, r2, b0, b1, b2, enough):
    """A lower bound on the distance of two boxes: the largest gap of their projections on
    the 15 separating-axis candidates (face normals first, then edge cross products); a
    projection never lengthens a distance. It stops as soon as a gap reaches ``enough``
    (the caller needs no more: the bound is still one)."""
    dx, dy, dz = c2[0] - c1[0], c2[1] - c1[1], c2[2] - c1[2]
    best = -math.inf
    for k in range(15):
        if k < 3:
            lx, ly, lz = r1[k], r1[3 + k], r1[6 + k]
        elif k < 6:
            lx, ly, lz = r2[k - 3], r2[k], r2[k + 3]
        else:
            i, j = (k - 6) // 3, (k - 6) % 3
            ux, uy, uz = r1[i], r1[3 + i], r1[6 + i]
            vx, vy, vz = r2[j], r2[3 + j], r2[6 + j]
            lx, ly, lz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
            norm = math.sqrt(lx * lx + ly * ly + lz * lz)
            if norm < 1e-9:
                continue
            lx, ly, lz = lx / norm, ly / norm, lz / norm
        extent = (a0 * abs(lx * r1[0] + ly * r1[3] + lz * r1[6])
                  + a1 * abs(lx * r1[1] + ly * r1[4] + lz * r1[7])
                  + a2 * abs(lx * r1[2] + ly * r1[5] + lz * r1[8])
                  + b0 * abs(lx * r2[0] + ly * r2[3] + lz * r2[6])
                  + b1 * abs(lx * r2[1] + ly * r2[4] + lz * r2[7])
                  + b2 * abs(lx * r2[2] + ly * r2[5] + lz * r2[8]))
        gap = abs(lx * dx + ly * dy + lz * dz) - extent
        if gap > best:
            best = gap
            if best >= enough:
                return best
    return best


@njit
def _plane_height(px, py, pz, c, r):
    """Height of a world point above a plane (its z axis; the half-space below is solid)."""
    return r[2] * (px - c[0]) + r[5] * (py - c[1]) + r[8] * (pz - c[2])


@njit
def _capsule_ends(c, r, half):
    return (c[0] - half * r[2], c[1] - half * r[5], c[2] - half * r[8],
            c[0] + half * r[2], c[1] + half * r[5], c[2] + half * r[8])


@njit
def _bound_shapes(ka, ca, ra, sa0, sa1, sa2, kb, cb, rb, sb0, sb1, sb2, enough):
    """Lower bound on the distance of two containers of kinds SPHERE/CAPSULE/BOX/PLANE
    (refined no further once it reaches ``enough``, where refining costs: box–box)."""
    if ka > kb:
        return _bound_ordered(kb, cb, rb, sb0, sb1, sb2, ka, ca, ra, sa0, sa1, sa2, enough)
    return _bound_ordered(ka, ca, ra, sa0, sa1, sa2, kb, cb, rb, sb0, sb1, sb2, enough)


@njit
def _bound_ordered(ka, ca, ra, sa0, sa1, sa2, kb, cb, rb, sb0, sb1, sb2, enough):
    """:func:`_bound_shapes` with ``ka <= kb``."""
    if ka == SPHERE:
        if kb == SPHERE:
            dx, dy, dz = ca[0] - cb[0], ca[1] - cb[1], ca[2] - cb[2]
            return math.sqrt(dx * dx + dy * dy + dz * dz) - sa0 - sb0
        if kb == CAPSULE:
            e = _capsule_ends(cb, rb, sb1)
            return math.sqrt(_point_segment_sq(ca[0], ca[1], ca[2], e[0], e[1], e[2],
                                               e[3], e[4], e[5])) - sa0 - sb0
        if kb == BOX:
            return _point_box(ca[0], ca[1], ca[2], cb, rb, sb0, sb1, sb2) - sa0
        return _plane_height(ca[0], ca[1], ca[2], cb, rb) - sa0
    if ka == CAPSULE:
        e = _capsule_ends(ca, ra, sa1)
        if kb == CAPSULE:
            f = _capsule_ends(cb, rb, sb1)
            return math.sqrt(_segment_segment_sq(e[0], e[1], e[2], e[3], e[4], e[5],
                                                 f[0], f[1], f[2], f[3], f[4], f[5])
                             ) - sa0 - sb0
        if kb == BOX:
            return _segment_box(e[0], e[1], e[2], e[3], e[4], e[5], cb, rb, sb0, sb1, sb2) - sa0
        return min(_plane_height(e[0], e[1], e[2], cb, rb),
                   _plane_height(e[3], e[4], e[5], cb, rb)) - sa0
    if ka == BOX:
        if kb == BOX:
            return _box_box(ca, ra, sa0, sa1, sa2, cb, rb, sb0, sb1, sb2, enough)
        reach = (sa0 * abs(rb[2] * ra[0] + rb[5] * ra[3] + rb[8] * ra[6])
                 + sa1 * abs(rb[2] * ra[1] + rb[5] * ra[4] + rb[8] * ra[7])
                 + sa2 * abs(rb[2] * ra[2] + rb[5] * ra[5] + rb[8] * ra[8]))
        return _plane_height(ca[0], ca[1], ca[2], cb, rb) - reach
    return -math.inf


@njit(inline="always")
def _cylinder_gap(x, y, z, r, h):
    """Distance of a point (cylinder frame) from the solid cylinder of radius ``r`` and
    half-height ``h`` about z, and the vector from its nearest point (0 inside)."""
    rho = math.sqrt(x * x + y * y)
    scale = 1.0 - r / rho if rho > r else 0.0
    dz = z - h if z > h else (z + h if z < -h else 0.0)
    ex, ey = x * scale, y * scale
    return math.sqrt(ex * ex + ey * ey + dz * dz), ex, ey, dz


@njit(inline="always")
def _segment_cylinder_floor(ax, ay, az, dx, dy, dz, r, h):
    """A cheap lower bound on the distance of the segment a + t·d, 0 ≤ t ≤ 1 (cylinder
    frame) from the solid cylinder: the larger of its least radial excess (the 2-D
    segment's distance from the axis, less r) and its least axial excess (|z| less h).
    Exact beside the side and over the flat ends; over a rim it may fall short by up to
    a factor √2."""
    length = dx * dx + dy * dy
    t = 0.0
    if length > 0.0:
        t = _clamp(-(ax * dx + ay * dy) / length, 0.0, 1.0)
    x, y = ax + t * dx, ay + t * dy
    radial = math.sqrt(x * x + y * y) - r
    z0, z1 = az, az + dz
    axial = -h if z0 * z1 <= 0.0 else min(abs(z0), abs(z1)) - h
    return max(radial, axial)


@njit(inline="always")
def _cylinder_slope(x, y, z, dx, dy, dz, r, h):
    """The distance of the point (x, y, z) (cylinder frame) from the solid cylinder and its
    derivative along (dx, dy, dz) (0 inside)."""
    f, ex, ey, ez = _cylinder_gap(x, y, z, r, h)
    return f, ((ex * dx + ey * dy + ez * dz) / f if f > 0.0 else 0.0)


@njit(inline="always")
def _tangents_floor(lo, hi, t1, f1, g1, t2, f2, g2):
    """The least over [lo, hi] of the larger of the tangent lines at t1 < t2 (values f,
    slopes g) of a convex function."""
    if g1 >= 0.0:
        return f1 + g1 * (lo - t1)
    if g2 <= 0.0:
        return f2 + g2 * (hi - t2)
    t = (f2 - f1 + g1 * t1 - g2 * t2) / (g1 - g2)
    return f1 + g1 * (t - t1)


@njit(inline="always")
def _cylinder_search(ax, ay, az, dx, dy, dz, r, h, below, above, precision):
    """Golden-section search for the least distance of the segment a + t·d, 0 ≤ t ≤ 1
    (cylinder frame) from the solid cylinder: (bound, seen), a lower bound on it over the
    whole segment and the least distance seen at a point of it. The distance from a convex
    set is convex along the segment and differentiable where it is positive, so every
    tangent line lies below it; the search keeps the minimiser bracketed, and the tangents
    at the bracket's two inner points bound the minimum from below over the bracket. It
    stops once the two are within ``precision``, the bound reaches ``above`` or the least
    value seen is at most ``below`` (no caller needs more)."""
    lo, hi = 0.0, 1.0
    ratio = 0.6180339887498949
    m1, m2 = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    f1, g1 = _cylinder_slope(ax + m1 * dx, ay + m1 * dy, az + m1 * dz, dx, dy, dz, r, h)
    f2, g2 = _cylinder_slope(ax + m2 * dx, ay + m2 * dy, az + m2 * dz, dx, dy, dz, r, h)
    # 0.618^80 of the segment: far below any length the tolerance can see.
    for _ in range(80):
        bound = _tangents_floor(lo, hi, m1, f1, g1, m2, f2, g2)
        seen = min(f1, f2)
        if seen - bound <= precision or bound >= above or seen <= below:
            return bound, seen
        if f1 <= f2:
            hi, m2, f2, g2 = m2, m1, f1, g1
            m1 = hi - ratio * (hi - lo)
            f1, g1 = _cylinder_slope(ax + m1 * dx, ay + m1 * dy, az + m1 * dz, dx, dy, dz,
                                     r, h)
        else:
            lo, m1, f1, g1 = m1, m2, f2, g2
            m2 = lo + ratio * (hi - lo)
            f2, g2 = _cylinder_slope(ax + m2 * dx, ay + m2 * dy, az + m2 * dz, dx, dy, dz,
                                     r, h)
    return _tangents_floor(lo, hi, m1, f1, g1, m2, f2, g2), min(f1, f2)


@njit
def _segment_cylinder(px, py, pz, qx, qy, qz, c, rot, r, h, floor, enough):
    """Lower bound on the distance of the segment pq from a solid cylinder (centre ``c``,
    rotation ``rot``, radius ``r``, half-height ``h``), within about 1e-7 of it unless it
    stops early: once the bound reaches ``enough`` (no caller needs more) or once the
    least distance seen is at most ``floor`` (no bound from here can beat the caller's).
    First the cheap radial and axial excesses (:func:`_segment_cylinder_floor`), then the
    tangents of :func:`_cylinder_search`."""
    ax, ay, az = _to_box(px, py, pz, c, rot)
    bx, by, bz = _to_box(qx, qy, qz, c, rot)
    dx, dy, dz = bx - ax, by - ay, bz - az
    quick = _segment_cylinder_floor(ax, ay, az, dx, dy, dz, r, h) - 1e-9
    if quick >= enough:
        return quick
    bound, _ = _cylinder_search(ax, ay, az, dx, dy, dz, r, h, floor, enough, 1e-7)
    # Rounding: a tangent evaluated in floating point may sit a few ulps above the
    # function; 1e-9 m covers it many times over.
    return max(bound - 1e-9, quick)


@njit
def _axis_in_cylinder(ka, ca, ra, sa, cb, rb, sb, limit):
    """Whether the inner sphere or capsule ``a`` (radius ``sa[0]``, axis half-length
    ``sa[1]``) comes closer than ``limit`` to the solid cylinder ``b`` itself (radius
    ``sb[0]``, half-height ``sb[1]``), shown at a point p of a's axis: dist(p, b) − radius
    < ``limit``. Each such value is at least the distance of the two shapes (a holds the
    ball of its radius around every point of its axis), so whatever point shows it proves
    it. The axis's ends first; then, unless the cheap radial and axial excesses
    (:func:`_segment_cylinder_floor`) already show that no point can, the search of
    :func:`_cylinder_search` until a point shows it or its tangents show that none can
    (to the last bits: the witness is sharp at ``limit``)."""
    target = limit + sa[0]
    half = 0.0 if ka == SPHERE else sa[1]
    e = _capsule_ends(ca, ra, half)
    ax, ay, az = _to_box(e[0], e[1], e[2], cb, rb)
    bx, by, bz = _to_box(e[3], e[4], e[5], cb, rb)
    r, h = sb[0], sb[1]
    if (_cylinder_gap(ax, ay, az, r, h)[0] < target
            or _cylinder_gap(bx, by, bz, r, h)[0] < target):
        return True
    dx, dy, dz = bx - ax, by - ay, bz - az
    if _segment_cylinder_floor(ax, ay, az, dx, dy, dz, r, h) >= target:
        return False
    _, seen = _cylinder_search(ax, ay, az, dx, dy, dz, r, h, target, target, 0.0)
    return seen < target


@njit
def _bound_pair(ka, ca, ra, sa, kb, cb, rb, sb, enough):
    """Lower bound on the distance of two slots' containers, any kinds: a cylinder is held
    by the capsule of its radius over its axis and by its box, so the larger of the two
    bounds holds; where that is short of ``enough`` and the partner is a sphere, capsule
    or cylinder (by its capsule), the distance of the partner's axis from the cylinder
    itself (:func:`_segment_cylinder`) bounds it too. An unbounded kind gives −inf (MuJoCo
    decides). A bound that reaches ``enough`` may stop there (``math.inf``: the best
    bound)."""
    if ka == UNBOUNDED or kb == UNBOUNDED or (ka == PLANE and kb == PLANE):
        return -math.inf
    # A sphere or capsule against a cylinder: the cylinder's capsule, then the cylinder
    # itself. Its box adds nothing the cylinder's own bound does not (which is within
    # 1e-7 of the distance) and an exact segment–box distance costs more than the
    # cylinder's first, cheap floor.
    if kb == CYLINDER and (ka == SPHERE or ka == CAPSULE):
        return _round_cylinder(ka, ca, ra, sa, cb, rb, sb, enough)
    if ka == CYLINDER and (kb == SPHERE or kb == CAPSULE):
        return _round_cylinder(kb, cb, rb, sb, ca, ra, sa, enough)
    best = _container_bound(ka, ca, ra, sa, kb, cb, rb, sb, enough)
    if best >= enough:
        return best
    if kb == CYLINDER and ka == CYLINDER:
        best = max(best, _axis_cylinder(ka, ca, ra, sa, cb, rb, sb, best, enough))
        if best >= enough:
            return best
        best = max(best, _axis_cylinder(kb, cb, rb, sb, ca, ra, sa, best, enough))
    return best


@njit
def _round_cylinder(ka, ca, ra, sa, cb, rb, sb, enough):
    """Lower bound on the distance of a sphere or capsule ``a`` from the solid cylinder
    ``b``: against the capsule around the cylinder, then, short of ``enough``, against the
    cylinder itself."""
    best = _bound_shapes(ka, ca, ra, sa[0], sa[1], sa[2], CAPSULE, cb, rb, sb[0], sb[1], 0.0,
                         enough)
    if best >= enough:
        return best
    return max(best, _axis_cylinder(ka, ca, ra, sa, cb, rb, sb, best, enough))


@njit
def _axis_cylinder(ka, ca, ra, sa, cb, rb, sb, floor, enough):
    """Lower bound on the distance of a sphere, capsule or cylinder (its capsule) ``a``
    from the solid cylinder ``b``; ``floor`` and ``enough`` (on that distance) as in
    :func:`_segment_cylinder`."""
    half = 0.0 if ka == SPHERE else sa[1]
    e = _capsule_ends(ca, ra, half)
    return _segment_cylinder(e[0], e[1], e[2], e[3], e[4], e[5], cb, rb, sb[0], sb[1],
                             floor + sa[0], enough + sa[0]) - sa[0]


@njit
def _container_bound(ka, ca, ra, sa, kb, cb, rb, sb, enough):
    """:func:`_bound_pair` over the containers alone."""
    best = -math.inf
    for use_a in range(2 if ka == CYLINDER else 1):
        ta, a0, a1, a2 = ka, sa[0], sa[1], sa[2]
        if ka == CYLINDER:
            ta, a0, a1, a2 = (BOX, sa[0], sa[0], sa[1]) if use_a else (CAPSULE, sa[0], sa[1], 0.0)
        for use_b in range(2 if kb == CYLINDER else 1):
            tb, b0, b1, b2 = kb, sb[0], sb[1], sb[2]
            if kb == CYLINDER:
                tb, b0, b1, b2 = ((BOX, sb[0], sb[0], sb[1]) if use_b
                                  else (CAPSULE, sb[0], sb[1], 0.0))
            value = _bound_shapes(ta, ca, ra, a0, a1, a2, tb, cb, rb, b0, b1, b2, enough)
            if value > best:
                best = value
    return best



@njit
def _box_box_distance(c1, r1, a0, a1, a2, c2, r2, b0, b1, b2):
    """The distance of two solid boxes (0 where they overlap): the least distance of an
    edge of either to the other box. Separated boxes have a nearest pair with a point on
    an edge of one of them (vertex–face, edge–edge and face–face contacts all include
    one), and overlapping ones an edge of one inside the other (every vertex of their
    intersection lies on an edge of one), so the least of the 24 segment–box distances is
    exact."""
    best = math.inf
    for which in range(2):
        if which == 0:
            c, r, h0, h1, h2, cb, rb, k0, k1, k2 = c1, r1, a0, a1, a2, c2, r2, b0, b1, b2
        else:
            c, r, h0, h1, h2, cb, rb, k0, k1, k2 = c2, r2, b0, b1, b2, c1, r1, a0, a1, a2
        for axis in range(3):  # the 4 edges parallel to each axis
            for corner in range(4):
                u = -1.0 if corner & 1 else 1.0
                v = -1.0 if corner & 2 else 1.0
                if axis == 0:
                    x0, y0, z0, x1, y1, z1 = -h0, u * h1, v * h2, h0, u * h1, v * h2
                elif axis == 1:
                    x0, y0, z0, x1, y1, z1 = u * h0, -h1, v * h2, u * h0, h1, v * h2
                else:
                    x0, y0, z0, x1, y1, z1 = u * h0, v * h1, -h2, u * h0, v * h1, h2
                px = c[0] + r[0] * x0 + r[1] * y0 + r[2] * z0
                py = c[1] + r[3] * x0 + r[4] * y0 + r[5] * z0
                pz = c[2] + r[6] * x0 + r[7] * y0 + r[8] * z0
                qx = c[0] + r[0] * x1 + r[1] * y1 + r[2] * z1
                qy = c[1] + r[3] * x1 + r[4] * y1 + r[5] * z1
                qz = c[2] + r[6] * x1 + r[7] * y1 + r[8] * z1
                d = _segment_box(px, py, pz, qx, qy, qz, cb, rb, k0, k1, k2)
                if d < best:
                    best = d
                    if best == 0.0:
                        return 0.0
    return best


@njit
def _inner_distance(ka, ca, ra, sa, kb, cb, rb, sb):
    """The distance of two inner shapes (kinds ``SPHERE``/``CAPSULE``/``BOX``/``PLANE``,
    centres, rotations as row-major 9-tuples, sizes), signed where the closed forms are
    (below 0: overlap); +inf where either has none (``NO_INNER``) or both are planes."""
    if ka == NO_INNER or kb == NO_INNER or (ka == PLANE and kb == PLANE):
        return math.inf
    if ka == BOX and kb == BOX:
        return _box_box_distance(ca, ra, sa[0], sa[1], sa[2], cb, rb, sb[0], sb[1], sb[2])
    # Every other pair of these kinds is measured exactly (the separating-axis bound is
    # used for box–box only).
    return _bound_shapes(ka, ca, ra, sa[0], sa[1], sa[2], kb, cb, rb, sb[0], sb[1], sb[2],
                         math.inf)


@njit
def _skewers(ka, ca, ra, sa, kb, cb, rb, sb):
    """A capsule (one of the two inner shapes, the other a box) whose axis passes through
    the box with both its ends outside: the overlap MuJoCo's capsule–box collider misses."""
    if ka == CAPSULE and kb == BOX:
        cc, rc, half, cx, rx, sx = ca, ra, sa[1], cb, rb, sb
    elif ka == BOX and kb == CAPSULE:
        cc, rc, half, cx, rx, sx = cb, rb, sb[1], ca, ra, sa
    else:
        return False
    e = _capsule_ends(cc, rc, half)
    if _segment_box(e[0], e[1], e[2], e[3], e[4], e[5], cx, rx, sx[0], sx[1], sx[2]) > 0.0:
        return False
    return (_point_box(e[0], e[1], e[2], cx, rx, sx[0], sx[1], sx[2]) > 0.0
            and _point_box(e[3], e[4], e[5], cx, rx, sx[0], sx[1], sx[2]) > 0.0)
