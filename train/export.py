"""Export a trained model's actor for a controller: ``ikbranch export``.

    ikbranch export models/UR5e-v1/bc_maskable_ppo.zip --env IKBranch/UR5e-v1 \\
        [--out ur5e.npz] [--episodes 20] [--env-kwargs '{...}']

Writes the actor of a PPO or MaskablePPO model (``BranchPolicy`` or ``MlpPolicy``) as an
``.npz`` of plain arrays that ``agents.exported.ExportedPolicy`` decides from with numpy
alone (no torch, no SB3). Before writing, the exported actor plays ``--episodes``
held-out tasks of ``--env`` (task seeds from ``envs.seeds.TEST_SEED``, held-out scenes)
beside the model: every decision must be the model's own, or nothing is written and the
command fails. It prints how many decisions it compared and the largest difference of the
logits (float32 rounding). ``--out`` defaults to the model's path with ``.npz``.
``python -m train.evaluate --policy FILE.npz`` evaluates the exported file.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch

import ikbranch_gym.envs as envs
from ikbranch_gym.agents.base import action_mask
from ikbranch_gym.agents.exported import ExportedPolicy, exported_arrays, write_exported
from ikbranch_gym.agents.sb3 import SB3Policy
from ikbranch_gym.envs.seeds import TEST_SEED, held_out


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="ikbranch export", description=__doc__.splitlines()[0])
    parser.add_argument("model", type=Path, help="an SB3 model zip (PPO or MaskablePPO)")
    parser.add_argument("--env", required=True, help="the env id the model was trained on")
    parser.add_argument("--out", type=Path, help="the .npz to write (default: MODEL.npz)")
    parser.add_argument("--episodes", type=int, default=20,
                        help="held-out tasks the export is checked on (default 20)")
    parser.add_argument("--env-kwargs", type=json.loads, default={},
                        help="JSON env kwargs, as in training (default: none)")
    args = parser.parse_args(argv)
    if args.env not in envs.ENV_IDS:
        parser.error(f"unknown env id {args.env!r}")
    if args.episodes < 1:
        parser.error("--episodes must be at least 1")
    args.out = args.out or args.model.with_suffix(".npz")
    if args.out.suffix != ".npz":
        parser.error(f"--out {args.out}: an exported policy is written as a .npz file")
    return args


def model_logits(model: SB3Policy, observations: np.ndarray) -> np.ndarray:
    """(B, K) the logits ``model``'s actor gives observations (B, size), in torch."""
    net: Any = model.model.policy  # SB3 types its modules as Tensor | Module
    with torch.inference_mode():
        features = net.extract_features(torch.as_tensor(observations), net.features_extractor)
        return net.action_net(net.mlp_extractor.forward_actor(features)).numpy()


def compare(model: SB3Policy, exported: ExportedPolicy, env: gym.Env,
            episodes: int) -> tuple[int, int, float]:
    """(decisions compared, decisions that differ, largest logit difference) of
    ``exported`` beside ``model`` on ``episodes`` held-out tasks of ``env`` (the model's
    choices are played)."""
    model.model.policy.set_training_mode(False)
    compared = differ = 0
    largest = 0.0
    for e in range(episodes):
        observation, info = env.reset(seed=TEST_SEED + e)
        done = False
        while not done:
            mask = action_mask(env, info)
            with torch.inference_mode():
                action, _ = model.predict(observation, deterministic=True, action_masks=mask)
            logits = model_logits(model, observation[None])
            mine, _ = exported.predict(observation, action_masks=mask)
            compared += 1
            differ += int(int(mine) != int(action))
            largest = max(largest, float(np.abs(exported.logits(observation[None]) -
                                                logits).max()))
            observation, _, terminated, truncated, info = env.step(int(action))
            done = bool(terminated or truncated)
    return compared, differ, largest


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    env = gym.make(args.env, **held_out(args.env, args.env_kwargs))
    try:
        model = SB3Policy.load(args.model, env)
        arrays = exported_arrays(model.model)
        exported = ExportedPolicy(arrays, name=args.out.stem, env=env)
    except ValueError as error:
        raise SystemExit(f"error: {error}") from error
    compared, differ, largest = compare(model, exported, env, args.episodes)
    env.close()
    if differ:
        print(f"{differ} of {compared} decisions on {args.episodes} held-out tasks differ "
              f"from the model's (largest logit difference {largest:.2e}): not written")
        return 1
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_exported(arrays, args.out)
    print(f"{args.out}: the actor of {args.model} ({exported.kind}, "
          f"{'masked' if exported.maskable else 'unmasked'}); its {compared} decisions on "
          f"{args.episodes} held-out tasks of {args.env} equal the model's (largest logit "
          f"difference {largest:.2e})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
