"""Free moves re-checked against the drawn geometry by a second collision library (coal).

    .venv/bin/python benchmarks/drawn_clearance.py [--ids ID ...] [--episodes 20] [--seed 0]
                                                   [--policy dp_oracle|random]

The envs collide simplified shapes (docs/models.md): a drawn cylinder is collided as the
capsule inside it, a drawn box of an industrial arm as a convex mesh. This measures what
the simplification leaves out. Per id: seeded episodes (held-out scenes where the id draws
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
parent and child (a wrist's housings): the checker never tests them, so an overlap there
is hidden by the exclusion (a parent and its child meet at their joint by design). Between
grid samples the shapes move at most δ: a measurement on the grid, not a certified bound.

Needs coal (``pip install coal``; not a dependency of the package).
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import coal
import gymnasium as gym
import mujoco
import numpy as np

import ikbranch_gym
from ikbranch_gym.agents import make_baseline
from ikbranch_gym.envs.models.builders import VISUAL_GROUP
from ikbranch_gym.envs.seeds import held_out

#: Pairs whose bounding spheres are farther apart than this are not measured (m).
BROAD_PHASE = 0.05


def _shape(model: mujoco.MjModel, g: int) -> coal.ShapeBase | None:
    """coal's shape of geom ``g`` in the geom's frame (None: a type not measured)."""
    kind, size = model.geom_type[g], model.geom_size[g]
    if kind == mujoco.mjtGeom.mjGEOM_PLANE:
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return coal.Sphere(size[0])
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return coal.Capsule(size[0], 2 * size[1])
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return coal.Cylinder(size[0], 2 * size[1])
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return coal.Box(*(2 * size))
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        # The collision meshes are convex (boxes as meshes): their vertices' hull.
        start, count = model.mesh_vertadr[model.geom_dataid[g]], model.mesh_vertnum[
            model.geom_dataid[g]]
        vertices = model.mesh_vert[start:start + count].astype(np.float64)
        # Mesh vertices are stored in the geom's frame.
        points = coal.StdVec_Vec3s()
        for vertex in vertices:
            points.append(vertex)
        return coal.Convex.convexHull(points, False, "")
    return None


class Measure:
    """The body pairs a checker tests, their collision and drawn geoms as coal shapes."""

    def __init__(self, env: gym.Env) -> None:
        base = env.unwrapped
        self.model, self.dof = base.model, base.arm.dof
        self.data = mujoco.MjData(self.model)
        model = self.model
        checker = base.checker
        bodies = {tuple(sorted((int(model.geom_bodyid[a]), int(model.geom_bodyid[b]))))
                  for a, b in checker._pairs}
        self.collision = self._geom_pairs(checker._pairs)
        drawn: list[tuple[int, int]] = []
        for b1, b2 in sorted(bodies):
            for g1 in self._drawn(b1):
                drawn += [(g1, g2) for g2 in self._drawn(b2)]
        self.drawn = self._geom_pairs(np.array(drawn, dtype=np.int64).reshape(-1, 2))
        # Body pairs the model excludes explicitly that are not parent and child (e.g. a
        # wrist's housings): their drawn geoms, measured apart (the checker never tests
        # them; a parent and its child meet at their joint by design).
        excluded: list[tuple[int, int]] = []
        parent = model.body_parentid
        for signature in model.exclude_signature.tolist():
            b1, b2 = signature >> 16, signature & 0xFFFF
            if parent[b1] == b2 or parent[b2] == b1:
                continue
            for g1 in self._drawn(b1):
                excluded += [(g1, g2) for g2 in self._drawn(b2)]
        self.excluded = self._geom_pairs(np.array(excluded, dtype=np.int64).reshape(-1, 2))
        self.refresh()
        self.request = coal.DistanceRequest()
        self.request.enable_signed_distance = True

    def refresh(self) -> None:
        """coal's shapes of the model's geoms now (a reset lays a clutter of new sizes)."""
        self.shapes = {g: _shape(self.model, g)
                       for pairs in (self.collision, self.drawn, self.excluded)
                       for g in pairs.ravel().tolist()}

    def _drawn(self, body: int) -> list[int]:
        model = self.model
        geoms = np.flatnonzero(model.geom_bodyid == body)
        planes = [g for g in geoms if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE]
        return planes + [int(g) for g in geoms if model.geom_group[g] == VISUAL_GROUP]

    def _geom_pairs(self, pairs: np.ndarray) -> np.ndarray:
        """``pairs`` whose two shapes coal measures (every primitive; hfields are not)."""
        model = self.model
        keep = [(int(a), int(b)) for a, b in pairs
                if _shape(model, int(a)) is not None and _shape(model, int(b)) is not None]
        return np.array(keep, dtype=np.int64).reshape(-1, 2)

    def distances(self, q: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Signed distances of ``pairs`` at configuration ``q`` (inf beyond the broad
        phase)."""
        model, data = self.model, self.data
        data.qpos[: self.dof] = q
        mujoco.mj_kinematics(model, data)
        a, b = pairs[:, 0], pairs[:, 1]
        centre = np.linalg.norm(data.geom_xpos[a] - data.geom_xpos[b], axis=1)
        planar = (model.geom_type[a] == mujoco.mjtGeom.mjGEOM_PLANE) | (
            model.geom_type[b] == mujoco.mjtGeom.mjGEOM_PLANE)
        reach = model.geom_rbound[a] + model.geom_rbound[b]
        near = planar | (centre - reach < BROAD_PHASE)
        out = np.full(len(pairs), np.inf)
        for k in np.flatnonzero(near):
            out[k] = self._distance(int(a[k]), int(b[k]))
        return out

    def _distance(self, g1: int, g2: int) -> float:
        data = self.data
        t1 = coal.Transform3s(data.geom_xmat[g1].reshape(3, 3), data.geom_xpos[g1])
        t2 = coal.Transform3s(data.geom_xmat[g2].reshape(3, 3), data.geom_xpos[g2])
        result = coal.DistanceResult()
        return float(coal.distance(self.shapes[g1], t1, self.shapes[g2], t2, self.request,
                                   result))


def measure(env_id: str, episodes: int, seed: int, policy: str) -> dict:
    env = gym.make(env_id, **held_out(env_id))
    base = env.unwrapped
    oracle = make_baseline("dp_oracle", env) if policy == "dp_oracle" else None
    probe, checker = Measure(env), base.checker
    delta = checker.resolution
    rng = np.random.default_rng(seed)
    moves = samples = close_collision = overlapping = excluded_overlapping = 0
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
    return {"moves": moves, "samples": samples, "collision closer than δ": close_collision,
            "drawn overlapping": overlapping, "deepest mm": 1e3 * deepest, "pair": worst,
            "excluded overlapping": excluded_overlapping,
            "excluded deepest mm": 1e3 * excluded_deepest,
            "seconds": time.perf_counter() - start}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--ids", nargs="*", help="default: the current generation's ids")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--policy", choices=("dp_oracle", "random"), default="dp_oracle")
    args = parser.parse_args()
    ids = args.ids or [i for i in ikbranch_gym.ENV_IDS
                       if ikbranch_gym.ENV_SPECS[i].get("observation") == "compact"]
    print(f"{args.episodes} episodes per id played by {args.policy}, seed {args.seed}\n")
    print("| id | free moves | samples | collision shapes closer than δ | drawn shapes "
          "overlapping | deepest (mm) | pair | excluded pairs' drawn shapes overlapping | "
          "deepest (mm) | s |")
    print("|---|---:|---:|---:|---:|---:|---|---:|---:|---:|")
    for env_id in ids:
        r = measure(env_id, args.episodes, args.seed, args.policy)
        print(f"| {env_id} | {r['moves']:,} | {r['samples']:,} | "
              f"{r['collision closer than δ']} | {r['drawn overlapping']} | "
              f"{r['deepest mm']:.1f} | {r['pair'] or '–'} | {r['excluded overlapping']} | "
              f"{r['excluded deepest mm']:.1f} | {r['seconds']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
