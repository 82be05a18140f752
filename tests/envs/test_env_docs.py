"""The class docstring is the user documentation: Gymnasium's sections, and an Arguments
table that matches the constructor. Bad arguments fail at ``gym.make`` with a ValueError."""

from __future__ import annotations

import ast
import inspect
import re

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs as envs
from ikbranch_gym.envs.ik_branch_env import IKBranchEnv

SECTIONS = ("Description", "Action space", "Observation space", "Rewards", "Starting state",
            "Episode end", "Arguments", "Version history")


def _doc() -> str:
    return inspect.getdoc(IKBranchEnv)


def test_docstring_has_gymnasiums_sections_in_order():
    headings = re.findall(r"^## (.+)$", _doc(), flags=re.MULTILINE)
    assert tuple(headings) == SECTIONS


def _arguments_table() -> dict[str, str]:
    """name -> default as written, from the reST simple table under ``## Arguments``."""
    section = _doc().split("## Arguments", 1)[1].split("\n## ", 1)[0]
    lines = section.splitlines()
    borders = [i for i, line in enumerate(lines) if re.fullmatch(r"=+( +=+)+", line.strip())]
    assert len(borders) == 3, "a simple table: border, header, border, rows, border"
    rows = {}
    for line in lines[borders[1] + 1 : borders[2]]:
        name, default, *_ = line.split(maxsplit=2)
        assert name not in rows, f"{name} documented twice"
        rows[name] = default
    return rows


def test_arguments_table_matches_the_signature():
    table = _arguments_table()
    parameters = {
        name: p for name, p in inspect.signature(IKBranchEnv.__init__).parameters.items()
        if name != "self"
    }
    assert list(table) == list(parameters)  # every parameter, no extra, in signature order
    for name, written in table.items():
        assert ast.literal_eval(written) == parameters[name].default, name


#: What ``gym.make`` passes for an argument an id leaves out.
DEFAULTS = {
    name: p.default for name, p in inspect.signature(IKBranchEnv.__init__).parameters.items()
    if name != "self"
}


#: Every id that must exist, written out by hand from the README's table, the version
#: history and the published results: (arm, scene, task, observation, clutter drawn per
#: episode). Published models and results name these ids; an id that goes missing or
#: changes what it makes breaks them.
REQUIRED_IDS = {
    "IKBranch/Cartesian-v1": ("cartesian", "random_clutter", "random", "ladder", False),
    "IKBranch/Cylindrical-v1": ("cylindrical", "random_clutter", "random", "ladder", False),
    "IKBranch/Spherical-v1": ("spherical", "random_clutter", "random", "ladder", False),
    "IKBranch/Anthropomorphic-v1": (
        "anthropomorphic", "random_clutter", "random", "ladder", False),
    "IKBranch/Cylindrical4-v1": ("cylindrical4", "random_clutter", "random", "ladder", False),
    "IKBranch/ToolTransfer-v0": (
        "anthropomorphic", "milling_cell", "tool_changes", "ladder", False),
    "IKBranch/DualRRPRPP-v0": ("dual_rrp_rpp", "empty", "relative_motion", "ladder", False),
    "IKBranch/DualRRRPPP-v0": ("dual_rrr_ppp", "empty", "relative_motion", "ladder", False),
    "IKBranch/DualPPRPRR-v0": ("dual_ppr_prr", "empty", "relative_motion", "ladder", False),
    "IKBranch/RodMechanism-v1": ("rod_mechanism", "empty", "random", "ladder", False),
    "IKBranch/Cartesian-v2": ("cartesian", "random_clutter", "random", "compact", True),
    "IKBranch/Cylindrical-v2": ("cylindrical", "random_clutter", "random", "compact", True),
    "IKBranch/Spherical-v2": ("spherical", "random_clutter", "random", "compact", True),
    "IKBranch/Anthropomorphic-v2": (
        "anthropomorphic", "random_clutter", "random", "compact", True),
    "IKBranch/Cylindrical4-v2": ("cylindrical4", "random_clutter", "random", "compact", True),
    "IKBranch/ToolTransfer-v1": (
        "anthropomorphic", "milling_cell", "tool_changes", "compact", False),
    "IKBranch/DualRRPRPP-v1": (
        "dual_rrp_rpp", "empty", "relative_motion_free", "compact", False),
    "IKBranch/DualRRRPPP-v1": (
        "dual_rrr_ppp", "empty", "relative_motion_free", "compact", False),
    "IKBranch/DualPPRPRR-v1": (
        "dual_ppr_prr", "empty", "relative_motion_free", "compact", False),
    "IKBranch/RodMechanism-v2": ("rod_mechanism", "empty", "random", "compact", False),
    "IKBranch/KukaKR6-v0": ("kuka_kr6_r700", "random_clutter", "random", "compact", True),
    "IKBranch/UR5e-v0": ("ur5e", "random_clutter", "random", "compact", True),
    "IKBranch/IRB2600Screwing-v0": ("abb_irb2600", "empty", "screwing", "compact", False),
    "IKBranch/IRB4600ToolTransfer-v0": (
        "abb_irb4600", "milling_cell", "tool_changes", "compact", False),
}
#: The current generation: each id of the one before, collided as drawn.
CURRENT = {
    "IKBranch/Cartesian-v3": "IKBranch/Cartesian-v2",
    "IKBranch/Cylindrical-v3": "IKBranch/Cylindrical-v2",
    "IKBranch/Spherical-v3": "IKBranch/Spherical-v2",
    "IKBranch/Anthropomorphic-v4": "IKBranch/Anthropomorphic-v3",  # see ONWARD
    "IKBranch/Cylindrical4-v3": "IKBranch/Cylindrical4-v2",
    "IKBranch/ToolTransfer-v2": "IKBranch/ToolTransfer-v1",
    "IKBranch/DualRRPRPP-v2": "IKBranch/DualRRPRPP-v1",
    "IKBranch/DualRRRPPP-v2": "IKBranch/DualRRRPPP-v1",
    "IKBranch/DualPPRPRR-v2": "IKBranch/DualPPRPRR-v1",
    "IKBranch/RodMechanism-v3": "IKBranch/RodMechanism-v2",
    "IKBranch/KukaKR6-v2": "IKBranch/KukaKR6-v1",  # see ONWARD
    "IKBranch/UR5e-v4": "IKBranch/UR5e-v3",  # see ONE_TURN
    "IKBranch/IRB4600ToolTransfer-v1": "IKBranch/IRB4600ToolTransfer-v0",
    "IKBranch/IRB2600Screwing-v1": "IKBranch/IRB2600Screwing-v0",
    "IKBranch/KukaKR6Deburring-v1": "IKBranch/KukaKR6Deburring-v0",  # see CONTINUOUS
}
#: Ids of the current generation that see several moves ahead, and those moves; the id
#: each succeeds is of the drawn generation, collided as drawn, and stays registered.
ONWARD = {"IKBranch/Anthropomorphic-v4": 3, "IKBranch/UR5e-v2": 2, "IKBranch/KukaKR6-v2": 2}
DRAWN_BEFORE = {"IKBranch/Anthropomorphic-v3": "IKBranch/Anthropomorphic-v2",
                "IKBranch/UR5e-v1": "IKBranch/UR5e-v0", "IKBranch/UR5e-v2": "IKBranch/UR5e-v1",
                "IKBranch/KukaKR6-v1": "IKBranch/KukaKR6-v0",
                "IKBranch/UR5e-v3": "IKBranch/UR5e-v2",
                "IKBranch/KukaKR6Deburring-v0": None}  # a new job, no generation before
#: Ids of the current generation that check the moves into the next waypoint until so
#: many are free; the id each succeeds sees several moves ahead and stays registered.
CHECKED = {"IKBranch/UR5e-v3": 8}
#: Ids of the current generation whose random task draws within one turn of each joint's
#: zero; the id each succeeds checks moves until so many are free and stays registered.
ONE_TURN = {"IKBranch/UR5e-v4": [[-np.pi, np.pi]] * 6}
#: Ids of the current generation that keep a process pass in one configuration, and their
#: step limit; the id each succeeds (a new job, no generation before it) names none and
#: stays registered.
CONTINUOUS = {"IKBranch/KukaKR6Deburring-v1": np.radians(30.0)}


@pytest.mark.parametrize("version", [0, 1])
def test_the_deburring_job_is_the_kr6_on_its_cell_with_a_free_burr(version):
    env_id = f"IKBranch/KukaKR6Deburring-v{version}"
    made = {**DEFAULTS, **gym.spec(env_id).kwargs}
    assert (made["arm"], made["scene"], made["task"]) == (
        "kuka_kr6_r700", "deburring_cell", "deburring")
    assert made["collision_shapes"] == "drawn" and made["allowed_contacts"] == [
        ["tool_1", "part*"]]
    env = gym.make(env_id)
    assert env.action_space.n == 32 * 5  # the KR 6 R700's branches × the burr's spins
    # v0 names no step limit (its resets never applied one); v1 keeps the pass in one
    # configuration.
    limit = env.unwrapped.pricer.max_joint_step
    assert limit is None if version == 0 else limit == pytest.approx(np.radians(30.0))


def test_every_required_id_is_registered_and_makes_what_it_says():
    assert set(envs.ENV_IDS) == set(REQUIRED_IDS) | set(CURRENT) | set(DRAWN_BEFORE)
    assert envs.CURRENT_IDS == tuple(CURRENT)
    for env_id, (arm, scene, task, observation, per_episode) in REQUIRED_IDS.items():
        spec = gym.spec(env_id)
        assert spec.entry_point == "ikbranch_gym.envs.ik_branch_env:IKBranchEnv", env_id
        made = {**DEFAULTS, **spec.kwargs}
        assert (made["arm"], made["scene"], made["task"], made["observation"]) == (
            arm, scene, task, observation), env_id
        assert (made["scene_seed"] is None) == per_episode, env_id
        assert made["collision_shapes"] == "inscribed", env_id
    for env_id, before in {**CURRENT, **DRAWN_BEFORE}.items():
        if before is None:
            continue
        now, then = dict(gym.spec(env_id).kwargs), dict(gym.spec(before).kwargs)
        if env_id in ONWARD:
            assert (now.pop("onward_moves"), then.get("onward_moves", 1)) == (
                ONWARD[env_id], 1), env_id
            assert before in envs.SUCCESSORS.values() and now == then, env_id
            continue
        if env_id in CHECKED:
            assert (now.pop("checked_moves"), then.get("checked_moves")) == (
                CHECKED[env_id], None), env_id
            assert before in ONWARD and now == then, env_id
            continue
        if env_id in ONE_TURN:
            assert (now.pop("task_joint_range"), then.get("task_joint_range")) == (
                ONE_TURN[env_id], None), env_id
            assert before in CHECKED and now == then, env_id
            continue
        if env_id in CONTINUOUS:
            assert (now.pop("max_joint_step"), then.get("max_joint_step")) == (
                pytest.approx(CONTINUOUS[env_id]), None), env_id
            assert now == then, env_id
            continue
        assert (now.pop("collision_shapes"), then.pop("collision_shapes")) == (
            "drawn", "inscribed"), env_id
        assert now == then, env_id


def test_registered_ids_are_documented_constructor_arguments():
    for kwargs in envs.ENV_SPECS.values():
        assert set(kwargs) <= set(DEFAULTS)


BAD_KWARGS = [
    ({"scene": "moon"}, "unknown scene"),
    ({"arm": "scara"}, "unknown arm"),
    ({"task": "dance"}, "unknown task"),
    ({"travel_weight": -1.0}, "travel_weight"),
    ({"time_weight": -0.1}, "time_weight"),
    ({"time_weight": float("nan")}, "time_weight"),
    ({"collision_penalty": -1.0}, "collision_penalty"),
    ({"invalid_penalty": -1.0}, "invalid_penalty"),
    ({"invalid_penalty": float("inf")}, "invalid_penalty"),
    ({"prismatic_scale": -1.0}, "prismatic_scale"),
    ({"joint_weights": [1, 1, 1, 1, 1, -1]}, "joint_weights"),
    ({"joint_weights": [1, 1]}, "joint_weights"),
    ({"joint_speeds": [1.0, 2.0]}, "joint_speeds"),
    ({"joint_speeds": [1, 1, 1, 1, 1, 1, 1]}, "joint_speeds"),
    ({"joint_speeds": [1, 1, 1, 1, 1, 0]}, "joint_speeds"),
    ({"lookahead": -1}, "lookahead"),
    ({"lookahead": 1.5}, "lookahead"),
    ({"n_waypoints": 0}, "n_waypoints"),
    ({"n_waypoints": -3}, "n_waypoints"),
    ({"n_waypoints": 2.5}, "n_waypoints"),
    ({"n_waypoints": 3.0}, "n_waypoints"),
    ({"n_waypoints": "3"}, "n_waypoints"),
    ({"n_waypoints": True}, "n_waypoints"),
    ({"collision_resolution": 0.0}, "collision_resolution"),
    ({"scene_seed": -1}, "scene_seed"),
    ({"width": 0}, "width"),
    ({"render_mode": "depth"}, "render_mode"),
    ({"arm_params": {"bogus": 1.0}}, "bogus"),
    ({"task": "relative_motion"}, "two-arm"),
    ({"task": "tool_changes"}, "milling_cell"),
    ({"task": "deburring"}, "needs scene='deburring_cell'"),
    ({"scene": "deburring_cell", "arm": "dual_rrp_rpp", "task": "random"}, "six-DOF"),
    ({"task_joint_range": [[0.0, 1.0]] * 5}, "6 pairs [low, high]"),
    ({"task_joint_range": [[0.0, float("nan")]] * 6}, "finite numbers"),
    ({"task_joint_range": "all"}, "6 pairs [low, high]"),
    ({"task_joint_range": [[1.0, 0.0]] * 6}, "joint 1's [1.0, 0.0] is not a range"),
    ({"task_joint_range": [[-1.0, 1.0]] * 5 + [[0.0, 10.0]]}, "joint 6's [0.0, 10.0]"),
    ({"scene": "milling_cell", "task": "tool_changes", "task_joint_range": [[0.0, 1.0]] * 6},
     "task_joint_range is for task='random'"),
]


@pytest.mark.filterwarnings("ignore:.*not in the possible render_modes:UserWarning")
@pytest.mark.parametrize(("kwargs", "message"), BAD_KWARGS, ids=lambda v: str(v)[:40])
def test_bad_arguments_fail_at_make_with_a_clear_value_error(kwargs, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        gym.make("IKBranch/Anthropomorphic-v1", **kwargs)


@pytest.mark.parametrize(
    ("env_id", "kwargs", "message"),
    [
        ("IKBranch/Cartesian-v1", {"task": "tool_changes"}, "milling_cell"),
        ("IKBranch/RodMechanism-v1", {"scene": "milling_cell"}, "six-DOF single arm"),
        ("IKBranch/ToolTransfer-v0", {"arm": "dual_rrp_rpp"}, "six-DOF single arm"),
        ("IKBranch/ToolTransfer-v0", {"task": "paper_transfer", "arm": "spherical"},
         "anthropomorphic"),
        ("IKBranch/ToolTransfer-v0", {"task": "paper_transfer", "n_waypoints": 3}, "exactly 2"),
        ("IKBranch/RodMechanism-v1", {"task": "relative_motion"}, "two-arm"),
        ("IKBranch/RodMechanism-v1", {"task": "helix"}, "six-DOF single arm"),
        ("IKBranch/Cylindrical4-v1", {"task": "circle"}, "six-DOF single arm"),
        ("IKBranch/DualRRPRPP-v0", {"task": "line"}, "six-DOF single arm"),
        ("IKBranch/DualRRPRPP-v0", {"joint_speeds": [1.0] * 5}, "joint_speeds"),
        ("IKBranch/RodMechanism-v1", {"joint_weights": [1.0] * 6}, "joint_weights"),
    ],
)
def test_a_task_that_does_not_fit_the_arm_fails_at_make(env_id, kwargs, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        gym.make(env_id, **kwargs)


def test_numpy_integers_are_accepted_as_counts():
    env = gym.make("IKBranch/ToolTransfer-v0", n_waypoints=np.int64(4), lookahead=np.int64(1))
    obs, _ = env.reset(seed=0)
    assert env.unwrapped.task.n_waypoints == 4 and env.observation_space.contains(obs)
