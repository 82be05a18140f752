"""ikbranch-gym: Gymnasium environments for choosing closed-form IK branches of industrial
manipulators along waypoint sequences (MuJoCo).

Importing the package registers every id in ``ENV_IDS`` with Gymnasium; so does naming it
in the id, which needs no import of its own::

    import gymnasium as gym
    env = gym.make("ikbranch_gym:IKBranch/UR5e-v0")

Subpackages: ``ikbranch_gym.envs`` (the environments, their kinematics, models and tasks),
``ikbranch_gym.agents`` (baselines, the DP oracle, SB3 policies; the last need the
``[train]`` extra) and ``ikbranch_gym.train`` (training, evaluation, sweeps, plans; the
``[train]``, ``[sweep]`` and ``[plan]`` extras).
"""

from __future__ import annotations

from importlib import metadata

from ikbranch_gym.envs import ENV_IDS, ENV_SPECS, warm_up

try:
    __version__ = metadata.version("ikbranch-gym")
except metadata.PackageNotFoundError:  # a checkout that was never installed
    __version__ = "0+unknown"

__all__ = ["ENV_IDS", "ENV_SPECS", "__version__", "warm_up"]
