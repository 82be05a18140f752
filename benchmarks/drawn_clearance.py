"""Free moves re-checked against the drawn geometry by a second collision library (coal).

    .venv/bin/python benchmarks/drawn_clearance.py [--ids ID ...] [--episodes 20] [--seed 0]
                                                   [--policy dp_oracle|random]

The current ids collide the drawn shapes themselves (a drawn box as its 8-vertex convex
mesh); the generation before collided a drawn cylinder as the capsule inside it and
excluded overlapping wrist parts from each other. This measures what a generation's
collision shapes leave out. Per id: seeded episodes (held-out scenes where the id draws
clutter) played by the DP oracle (full episodes of free moves, as a trained policy plays
them) or by masked random actions; every move the env paid no collision penalty for is
sampled on the env's own path grid (consecutive samples at most δ = the collision
resolution apart) and, at every sample, every pair of bodies the collision checker tests
is measured again with coal's signed distances (placed by MuJoCo's forward kinematics):

- between their **collision** geoms: a check of the check (MuJoCo reported no contact
  closer than δ there, so coal should find them at least δ apart, up to its tolerance);
- between their **drawn** geoms (the models' visual group: cylinders as cylinders, boxes
  as boxes, the floor as a half-space).

Columns: moves checked, samples, moves whose collision shapes come closer than δ − 0.1 mm,
moves whose drawn shapes overlap (signed distance < 0), the deepest overlap (mm) and the
pair of bodies; then the same for the body pairs the model excludes explicitly other than
a joint's own two sides (the earlier wrists' housings): the checker never tests them, so
an overlap there is hidden by the exclusion (a parent and its child meet at their joint by
design). Those are measurements on the grid; the last column is continuous: the free moves
whose drawn shapes (tested and excluded pairs) ``Measure.certify`` proves apart all along
the move, between the samples too.

Needs coal (``pip install coal``; not a dependency of the package).
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import gymnasium as gym
import numpy as np

from ikbranch_gym.agents import make_baseline
from ikbranch_gym.envs import CURRENT_IDS
from ikbranch_gym.envs.models.independent import Measure
from ikbranch_gym.envs.seeds import held_out


def measure(env_id: str, episodes: int, seed: int, policy: str) -> dict:
    env = gym.make(env_id, **held_out(env_id))
    base = env.unwrapped
    oracle = make_baseline("dp_oracle", env) if policy == "dp_oracle" else None
    probe, checker = Measure(env), base.checker
    delta = checker.resolution
    rng = np.random.default_rng(seed)
    moves = samples = close_collision = overlapping = excluded_overlapping = certified = 0
    deepest, worst, excluded_deepest = 0.0, "", 0.0
    per_pair: dict[str, float] = defaultdict(float)
    start = time.perf_counter()
    for episode in range(episodes):
        obs, info = env.reset(seed=seed + episode)
        probe.refresh()
        done = False
        while not done:
            before = base.q
            if oracle is not None:
                action = int(oracle.predict(obs, action_masks=info["action_mask"])[0])
            else:
                action = int(rng.choice(np.flatnonzero(info["action_mask"])))
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            if info["reward_collision"] != 0.0 or info["invalid"]:
                continue
            moves += 1
            path = checker.path_samples(before, base.q)
            samples += len(path)
            collision = min(float(probe.distances(q, probe.collision).min()) for q in path)
            if collision < delta - 1e-4:
                close_collision += 1
            drawn = [probe.distances(q, probe.drawn) for q in path]
            least = np.min(drawn, axis=0)
            if least.min() < 0.0:
                overlapping += 1
                k = int(np.argmin(least))
                g1, g2 = probe.drawn[k]
                name = (f"{base.model.body(int(base.model.geom_bodyid[g1])).name}–"
                        f"{base.model.body(int(base.model.geom_bodyid[g2])).name}")
                per_pair[name] = max(per_pair[name], -float(least[k]))
                if -least[k] > deepest:
                    deepest, worst = -float(least[k]), name
            if len(probe.excluded):
                hidden = min(float(probe.distances(q, probe.excluded).min()) for q in path)
                if hidden < 0.0:
                    excluded_overlapping += 1
                    excluded_deepest = max(excluded_deepest, -hidden)
            pairs = np.concatenate([probe.drawn, probe.excluded])
            certified += probe.certify(before, base.q, pairs).certified
    return {"moves": moves, "samples": samples, "collision closer than δ": close_collision,
            "drawn overlapping": overlapping, "deepest mm": 1e3 * deepest, "pair": worst,
            "excluded overlapping": excluded_overlapping,
            "excluded deepest mm": 1e3 * excluded_deepest, "certified": certified,
            "seconds": time.perf_counter() - start}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--ids", nargs="*", help="default: the current generation's ids")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--policy", choices=("dp_oracle", "random"), default="dp_oracle")
    args = parser.parse_args()
    ids = args.ids or list(CURRENT_IDS)
    print(f"{args.episodes} episodes per id played by {args.policy}, seed {args.seed}\n")
    print("| id | free moves | samples | collision shapes closer than δ | drawn shapes "
          "overlapping | deepest (mm) | pair | excluded pairs' drawn shapes overlapping | "
          "deepest (mm) | drawn shapes certified apart all along | s |")
    print("|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|")
    for env_id in ids:
        r = measure(env_id, args.episodes, args.seed, args.policy)
        print(f"| {env_id} | {r['moves']:,} | {r['samples']:,} | "
              f"{r['collision closer than δ']} | {r['drawn overlapping']} | "
              f"{r['deepest mm']:.1f} | {r['pair'] or '–'} | {r['excluded overlapping']} | "
              f"{r['excluded deepest mm']:.1f} | {r['certified']} | {r['seconds']:.0f} |",
              flush=True)


if __name__ == "__main__":
    main()
