"""Allowed contacts and clearance (envs/models/contacts.py): exactly the named pairs leave
the collision checks (MuJoCo's own pair rule says so, and its contacts), and the
clearance agrees with the checker's verdicts."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.models.collision import candidate_pairs
from ikbranch_gym.envs.models.contacts import allow_contacts, clearance

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def _welding_env(**kwargs) -> IKBranchEnv:
    tool = json.loads((EXAMPLES / "welding_torch.json").read_text())
    return IKBranchEnv(arm="abb_irb2400", scene="file", task="file",
                       scene_file=str(EXAMPLES / "welding_cell.xml"),
                       task_file=str(EXAMPLES / "welding_seam.csv"), tool=tool, **kwargs)


def _named(model, pairs) -> set[tuple[str, str]]:
    def name(g):
        return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g))
    return {tuple(sorted((name(a), name(b)))) for a, b in pairs}


def test_exactly_the_allowed_pairs_leave_the_checks():
    plain = _welding_env()
    allowed = _welding_env(allowed_contacts=[["tool", "scene/plate_*"],
                                             ["scene/jig_part00[01]", "forearm"]])
    before = _named(plain.model, candidate_pairs(plain.model))
    after = _named(allowed.model, candidate_pairs(allowed.model))
    left_out = {("scene/plate_left", "tool"), ("scene/plate_right", "tool"),
                ("forearm", "scene/jig_part000"), ("forearm", "scene/jig_part001")}
    assert before - after == left_out and after <= before
    assert {tuple(sorted(pair)) for pair in allowed.allowed_contacts} == left_out
    # The checker itself: with the TCP 8 mm beyond the nozzle the torch comes within the
    # 10 mm resolution of the plates at the seam; allowed, only they are let through.
    close = {"shape": "cylinder", "size": [0.016, 0.35], "tcp": {"pos": [0, 0, 0.358]}}
    verdicts = {}
    for allow in (None, [["tool", "scene/plate_*"]]):
        env = _welding_env(allowed_contacts=allow) if allow else _welding_env()
        env = IKBranchEnv(**{**env._kwargs, "tool": close})
        env.reset(seed=0)
        seam = env.candidates[3][env.valid[3]]
        verdicts[allow is None] = env.checker.collides(seam)
        if allow is None:
            touching = {(c.geom1, c.geom2) for c in env.checker.contacts(seam[0])}
            assert touching <= {("tool", "scene/plate_left"), ("tool", "scene/plate_right"),
                                ("scene/plate_left", "tool"), ("scene/plate_right", "tool")}
    assert verdicts[True].all() and not verdicts[False].any()


def test_bad_allowed_contacts_are_named(monkeypatch):
    env = _welding_env()
    with pytest.raises(ValueError, match=r"'nozzle' names no collision geom; the model's are"):
        allow_contacts(env.model, [["nozzle", "scene/plate_left"]])
    with pytest.raises(ValueError, match="two geom names"):
        allow_contacts(env.model, [["tool"]])
    import ikbranch_gym.envs.models.contacts as contacts

    monkeypatch.setattr(contacts, "MAX_ALLOWED_GEOMS", 3)
    with pytest.raises(ValueError, match="allowed contacts name 4 geoms; at most 3"):
        allow_contacts(env.model, [["tool", "scene/*plate_*"], ["tool", "scene/table_top"]])


def test_clearance_agrees_with_the_checkers_verdicts():
    env = _welding_env()
    env.reset(seed=0)
    checker, model = env.checker, env.model
    data = mujoco.MjData(model)
    pairs = candidate_pairs(model)
    rng = np.random.default_rng(2)
    arm = env.arm
    q = rng.uniform(arm.joint_limits[:, 0] / 3, arm.joint_limits[:, 1] / 3, size=(60, 6))
    q = np.concatenate([q, env.candidates[env.valid]])
    collides = checker.collides(q)
    decided = 0
    for row, hit in zip(q, collides, strict=True):
        gap, pair = clearance(model, data, row, pairs)
        if gap >= checker.resolution + 1e-9:
            assert not hit, (gap, pair)
            decided += 1
        elif gap < checker.resolution - 1e-9:
            assert hit, (gap, pair)
            decided += 1
    assert decided >= 50 and collides.any() and not collides.all()
