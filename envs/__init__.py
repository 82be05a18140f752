"""ikbranch-gym: Gymnasium environments for choosing closed-form IK branches.

``import envs`` registers every id in ``ENV_IDS``; ``gym.make(id)`` needs nothing else.
"""

from __future__ import annotations

import os

# Offscreen rendering needs its GL backend chosen before mujoco is first imported.
os.environ.setdefault("MUJOCO_GL", "egl")

import gymnasium as gym

#: id -> the constructor arguments that make it (see ``envs.ik_branch_env.IKBranchEnv``).
ENV_SPECS: dict[str, dict] = {
    "IKBranch/Cartesian-v1": {"arm": "cartesian", "scene": "random_clutter", "task": "random"},
    "IKBranch/Cylindrical-v1": {"arm": "cylindrical", "scene": "random_clutter", "task": "random"},
    "IKBranch/Spherical-v1": {"arm": "spherical", "scene": "random_clutter", "task": "random"},
    "IKBranch/Anthropomorphic-v1": {
        "arm": "anthropomorphic", "scene": "random_clutter", "task": "random",
    },
    "IKBranch/Cylindrical4-v1": {
        "arm": "cylindrical4", "scene": "random_clutter", "task": "random",
    },
    "IKBranch/ToolTransfer-v0": {
        "arm": "anthropomorphic", "scene": "milling_cell", "task": "tool_changes",
    },
    "IKBranch/DualRRPRPP-v0": {"arm": "dual_rrp_rpp", "scene": "empty", "task": "relative_motion"},
    "IKBranch/DualRRRPPP-v0": {"arm": "dual_rrr_ppp", "scene": "empty", "task": "relative_motion"},
    "IKBranch/DualPPRPRR-v0": {"arm": "dual_ppr_prr", "scene": "empty", "task": "relative_motion"},
    "IKBranch/RodMechanism-v1": {"arm": "rod_mechanism", "scene": "empty", "task": "random"},
}
# The v0/v1 ids observe the ladder layout their published models were trained on.
for _kwargs in ENV_SPECS.values():
    _kwargs.setdefault("observation", "ladder")
ENV_IDS: tuple[str, ...] = tuple(ENV_SPECS)

for _env_id, _kwargs in ENV_SPECS.items():
    if _env_id not in gym.registry:
        gym.register(_env_id, entry_point="envs.ik_branch_env:IKBranchEnv", kwargs=_kwargs)

__all__ = ["ENV_IDS", "ENV_SPECS"]
