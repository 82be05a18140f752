"""Forward kinematics of the tree inside the kernels, slot frames and path samples."""

from __future__ import annotations

import math

from ikbranch_gym.envs.jit import njit

from .layout import _SLIDE


@njit
def _turn(m00, m01, m02, m10, m11, m12, m20, m21, m22, axis, c, s):
    """The frame m times the rotation by (c, s) = (cos θ, sin θ) about a local unit axis
    (``axis``, (3,)), applied on the right (Rodrigues' formula)."""
    ux, uy, uz = axis[0], axis[1], axis[2]
    t = 1.0 - c
    r00, r01, r02 = c + t * ux * ux, t * ux * uy - s * uz, t * ux * uz + s * uy
    r10, r11, r12 = t * ux * uy + s * uz, c + t * uy * uy, t * uy * uz - s * ux
    r20, r21, r22 = t * ux * uz - s * uy, t * uy * uz + s * ux, c + t * uz * uz
    return (m00 * r00 + m01 * r10 + m02 * r20, m00 * r01 + m01 * r11 + m02 * r21,
            m00 * r02 + m01 * r12 + m02 * r22,
            m10 * r00 + m11 * r10 + m12 * r20, m10 * r01 + m11 * r11 + m12 * r21,
            m10 * r02 + m11 * r12 + m12 * r22,
            m20 * r00 + m21 * r10 + m22 * r20, m20 * r01 + m21 * r11 + m22 * r21,
            m20 * r02 + m21 * r12 + m22 * r22)


@njit(inline="always")
def _forward(body_parent, body_pos, body_rot, body_jntadr, body_jntnum, body_flags,
             jnt_type, jnt_qposadr, jnt_pos, jnt_axis, jnt_axis_code, qpos0, qpos, xpos,
             xmat):
    """Body frames for ``qpos``, composed as ``mj_kinematics`` does (world = xmat @ local):
    the parent's frame times the body offset, then each joint in order (a slide shifts
    along its axis, a hinge turns about its anchor), joint values relative to ``qpos0``.

    Static bodies (``body_flags`` bit 0) keep the frames set at construction; bit 1 marks
    an identity body rotation. Hinges about a local ±x/±y/±z axis (``jnt_axis_code`` 0–5)
    turn two columns only. The frame being built lives in scalars: stores to ``xmat``
    would otherwise force reloads of the parent's frame (the two may alias).
    """
    for b in range(1, len(body_parent)):
        flags = body_flags[b]
        if flags & 1:
            continue
        p = body_parent[b]
        p00, p01, p02 = xmat[p, 0, 0], xmat[p, 0, 1], xmat[p, 0, 2]
        p10, p11, p12 = xmat[p, 1, 0], xmat[p, 1, 1], xmat[p, 1, 2]
        p20, p21, p22 = xmat[p, 2, 0], xmat[p, 2, 1], xmat[p, 2, 2]
        bx, by, bz = body_pos[b, 0], body_pos[b, 1], body_pos[b, 2]
        x0 = xpos[p, 0] + p00 * bx + p01 * by + p02 * bz
        x1 = xpos[p, 1] + p10 * bx + p11 * by + p12 * bz
        x2 = xpos[p, 2] + p20 * bx + p21 * by + p22 * bz
        if flags & 2:
            m00, m01, m02 = p00, p01, p02
            m10, m11, m12 = p10, p11, p12
            m20, m21, m22 = p20, p21, p22
        else:
            r = body_rot[b]
            m00 = p00 * r[0, 0] + p01 * r[1, 0] + p02 * r[2, 0]
            m01 = p00 * r[0, 1] + p01 * r[1, 1] + p02 * r[2, 1]
            m02 = p00 * r[0, 2] + p01 * r[1, 2] + p02 * r[2, 2]
            m10 = p10 * r[0, 0] + p11 * r[1, 0] + p12 * r[2, 0]
            m11 = p10 * r[0, 1] + p11 * r[1, 1] + p12 * r[2, 1]
            m12 = p10 * r[0, 2] + p11 * r[1, 2] + p12 * r[2, 2]
            m20 = p20 * r[0, 0] + p21 * r[1, 0] + p22 * r[2, 0]
            m21 = p20 * r[0, 1] + p21 * r[1, 1] + p22 * r[2, 1]
            m22 = p20 * r[0, 2] + p21 * r[1, 2] + p22 * r[2, 2]
        for j in range(body_jntadr[b], body_jntadr[b] + body_jntnum[b]):
            adr = jnt_qposadr[j]
            value = qpos[adr] - qpos0[adr]
            if jnt_type[j] == _SLIDE:
                ux, uy, uz = jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2]
                x0 += value * (m00 * ux + m01 * uy + m02 * uz)
                x1 += value * (m10 * ux + m11 * uy + m12 * uz)
                x2 += value * (m20 * ux + m21 * uy + m22 * uz)
                continue
            px, py, pz = jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2]
            a0 = x0 + m00 * px + m01 * py + m02 * pz
            a1 = x1 + m10 * px + m11 * py + m12 * pz
            a2 = x2 + m20 * px + m21 * py + m22 * pz
            code = jnt_axis_code[j]
            c = math.cos(value)
            s = math.sin(value) if code < 3 or code == 6 else -math.sin(value)
            axis = code % 3 if code < 6 else 3
            if axis == 0:  # columns 1, 2 turn: m·Rx
                m01, m02 = c * m01 + s * m02, c * m02 - s * m01
                m11, m12 = c * m11 + s * m12, c * m12 - s * m11
                m21, m22 = c * m21 + s * m22, c * m22 - s * m21
            elif axis == 1:  # columns 2, 0 turn: m·Ry
                m00, m02 = c * m00 - s * m02, c * m02 + s * m00
                m10, m12 = c * m10 - s * m12, c * m12 + s * m10
                m20, m22 = c * m20 - s * m22, c * m22 + s * m20
            elif axis == 2:  # columns 0, 1 turn: m·Rz
                m00, m01 = c * m00 + s * m01, c * m01 - s * m00
                m10, m11 = c * m10 + s * m11, c * m11 - s * m10
                m20, m21 = c * m20 + s * m21, c * m21 - s * m20
            else:
                m00, m01, m02, m10, m11, m12, m20, m21, m22 = _turn(
                    m00, m01, m02, m10, m11, m12, m20, m21, m22, jnt_axis[j], c, s)
            x0 = a0 - (m00 * px + m01 * py + m02 * pz)
            x1 = a1 - (m10 * px + m11 * py + m12 * pz)
            x2 = a2 - (m20 * px + m21 * py + m22 * pz)
        xpos[b, 0], xpos[b, 1], xpos[b, 2] = x0, x1, x2
        xmat[b, 0, 0], xmat[b, 0, 1], xmat[b, 0, 2] = m00, m01, m02
        xmat[b, 1, 0], xmat[b, 1, 1], xmat[b, 1, 2] = m10, m11, m12
        xmat[b, 2, 0], xmat[b, 2, 1], xmat[b, 2, 2] = m20, m21, m22


@njit(inline="always")
def _place_slots(slot_body, slot_static, slot_pos, slot_rot, xpos, xmat, wpos, wrot):
    """World frames of the moving slots' containers (static slots were placed once)."""
    for s in range(len(slot_body)):
        if slot_static[s]:
            continue
        b = slot_body[s]
        m00, m01, m02 = xmat[b, 0, 0], xmat[b, 0, 1], xmat[b, 0, 2]
        m10, m11, m12 = xmat[b, 1, 0], xmat[b, 1, 1], xmat[b, 1, 2]
        m20, m21, m22 = xmat[b, 2, 0], xmat[b, 2, 1], xmat[b, 2, 2]
        px, py, pz = slot_pos[s, 0], slot_pos[s, 1], slot_pos[s, 2]
        wpos[s, 0] = xpos[b, 0] + m00 * px + m01 * py + m02 * pz
        wpos[s, 1] = xpos[b, 1] + m10 * px + m11 * py + m12 * pz
        wpos[s, 2] = xpos[b, 2] + m20 * px + m21 * py + m22 * pz
        r = slot_rot[s]
        for k in range(3):
            r0, r1, r2 = r[0, k], r[1, k], r[2, k]
            wrot[s, 0, k] = m00 * r0 + m01 * r1 + m02 * r2
            wrot[s, 1, k] = m10 * r0 + m11 * r1 + m12 * r2
            wrot[s, 2, k] = m20 * r0 + m21 * r1 + m22 * r2



@njit(inline="always")
def _local_speed(a, motion, xpos, xmat, jnt_pos, jnt_axis, jnt_type, wpos, radius, dq):
    """V0: a bound on the speed of any point of slot ``a``'s bounding sphere at this
    sample, per unit path parameter, from the actual distances of its centre to the hinge
    axes that move it (plus the sphere's radius), slides at full speed."""
    slot_moved, jnt_body = motion[1], motion[2]
    speed = 0.0
    for j in range(len(jnt_body)):
        if not slot_moved[a, j] or dq[j] == 0.0:
            continue
        if jnt_type[j] == _SLIDE:
            speed += dq[j]
            continue
        b = jnt_body[j]
        # The hinge's anchor and axis in the world (a turn about it leaves both in place).
        px, py, pz = jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2]
        ax, ay, az = jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2]
        d0 = wpos[a, 0] - (xpos[b, 0] + xmat[b, 0, 0] * px + xmat[b, 0, 1] * py
                           + xmat[b, 0, 2] * pz)
        d1 = wpos[a, 1] - (xpos[b, 1] + xmat[b, 1, 0] * px + xmat[b, 1, 1] * py
                           + xmat[b, 1, 2] * pz)
        d2 = wpos[a, 2] - (xpos[b, 2] + xmat[b, 2, 0] * px + xmat[b, 2, 1] * py
                           + xmat[b, 2, 2] * pz)
        u0 = xmat[b, 0, 0] * ax + xmat[b, 0, 1] * ay + xmat[b, 0, 2] * az
        u1 = xmat[b, 1, 0] * ax + xmat[b, 1, 1] * ay + xmat[b, 1, 2] * az
        u2 = xmat[b, 2, 0] * ax + xmat[b, 2, 1] * ay + xmat[b, 2, 2] * az
        c0, c1, c2 = d1 * u2 - d2 * u1, d2 * u0 - d0 * u2, d0 * u1 - d1 * u0
        speed += dq[j] * (math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) + radius)
    return speed



@njit(inline="always")
def _path_rates(start, end_rows, m, lever_by_joint, delta, rates, dq):
    """Path ``m``'s joint change ``delta`` (its first dof entries; the rest stay 0), ``dq``
    = |Δq| and every pair's global rate Σ_j lever_kj·|Δq_j|, summed in joint order
    (``lever_by_joint``: (nq, pairs))."""
    npair = lever_by_joint.shape[1]
    dof = end_rows.shape[1]
    for j in range(dof):
        delta[j] = end_rows[m, j] - start[j]
    for j in range(len(dq)):
        dq[j] = abs(delta[j])
    rates[:npair] = 0.0
    for j in range(dof):
        step = dq[j]
        lever = lever_by_joint[j]
        for k in range(npair):
            rates[k] += lever[k] * step


@njit(inline="always")
def _slot_growth(a, motion, jnt_type, dq):
    """W of slot ``a``: how fast later joints can change its distances to the hinge axes
    that move it, along a path of joint change ``dq`` (computed when a sample first needs
    the slot's local speed)."""
    slot_lever, slot_moved, jnt_down = motion[0], motion[1], motion[3]
    total = 0.0
    for j in range(slot_lever.shape[1]):
        if slot_moved[a, j] and jnt_type[j] != _SLIDE and dq[j] > 0.0:
            later = 0.0
            for i in range(slot_lever.shape[1]):
                if jnt_down[j, i] and slot_moved[a, i]:
                    later += slot_lever[a, i] * dq[i]
            total += dq[j] * later
    return total


@njit(inline="always")
def _path_sample(qpos, start, delta, fraction, dof):
    """``qpos`` at ``fraction`` of the path: start + fraction·delta in the leading dof
    entries, the start (``qpos0``) in the rest."""
    for j in range(len(qpos)):
        qpos[j] = start[j] + fraction * delta[j] if j < dof else start[j]

