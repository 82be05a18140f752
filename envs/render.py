"""Offscreen pictures and animations of an arm in a scene.

    python -m envs.render anthropomorphic --scene milling_cell --q 0 0.5 -0.5 0 0.8 0 \\
        --out arm.png
    python -m envs.render anthropomorphic --scene milling_cell \\
        --path-from -0.39 0.40 -1.50 1.22 1.40 1.13 \\
        --path-to 0.85 0.07 -0.35 0 1.85 0.72 --out transfer.gif

``--q`` takes the arm's joint values (rad / m, kinematics order; default ``arm.home``);
``--path-from`` / ``--path-to`` give the ends of a linear joint-space motion, drawn as an
animated GIF. ``--milling-path I J`` draws the milling cell's transfer from branch I at
position 1 to branch J at position 2 (``arm.branch_labels`` order; 0 0 is the paper's
1.1 → 2.1).

Rendering is headless: ``MUJOCO_GL`` defaults to ``egl`` (set by ``envs/__init__.py``,
which runs before this module and before mujoco is imported);
where EGL is unavailable, ``MUJOCO_GL=osmesa`` (Mesa's software renderer, slower) works
with the same code.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

import imageio.v3 as iio
import mujoco
import numpy as np

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import SCENES, build_model, milling_cell_poses
from ikbranch_gym.envs.models.builders import COLLISION_GROUP, VISUAL_GROUP
from ikbranch_gym.envs.models.collision import PLANE

#: One arm configuration: joint values, kinematics order.
Configuration = Sequence[float] | np.ndarray


def framing_camera(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    configurations: Sequence[Configuration] | np.ndarray = (),
    *,
    azimuth: float = 135.0,
    elevation: float = -28.0,
    zoom: float = 1.0,
    geoms: np.ndarray | None = None,
) -> mujoco.MjvCamera:
    """A free camera that frames every non-plane geom at each of ``configurations``
    (leading qpos entries; none: ``data``'s current qpos). ``geoms``: frame only these
    (a bool mask or indices over the model's geoms, e.g. :func:`arm_geoms`), so a large
    cell does not shrink the arm to a few pixels."""
    solid = model.geom_type != PLANE
    if geoms is not None:
        chosen = np.zeros(model.ngeom, dtype=bool)
        chosen[np.asarray(geoms)] = True
        solid &= chosen
        if not solid.any():
            raise ValueError("framing_camera: no non-plane geom among the chosen ones")
    radii = model.geom_rbound[solid][:, None]
    lower, upper = np.full(3, np.inf), np.full(3, -np.inf)
    for q in list(configurations) or [data.qpos[: model.nq].copy()]:
        data.qpos[: len(q)] = q
        mujoco.mj_kinematics(model, data)
        centres = data.geom_xpos[solid]
        lower = np.minimum(lower, (centres - radii).min(axis=0))
        upper = np.maximum(upper, (centres + radii).max(axis=0))
    lower[2] = 0.0  # the floor belongs in the picture
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = (lower + upper) / 2
    half_diagonal = np.linalg.norm(upper - lower) / 2
    fovy = np.radians(model.vis.global_.fovy)
    camera.distance = 0.95 * half_diagonal / np.tan(fovy / 2) / zoom
    camera.azimuth = azimuth
    camera.elevation = elevation
    return camera


def arm_geoms(model: mujoco.MjModel) -> np.ndarray:
    """(ngeom,) bool: the geoms of the kinematic trees that have joints (the arm, its base
    and a held tool), not the static obstacles of the scene."""
    moving_roots = {int(model.body_rootid[b]) for b in range(model.nbody)
                    if model.body_jntnum[b] > 0}
    return np.isin(model.body_rootid[model.geom_bodyid], list(moving_roots))


class SceneRenderer:
    """Offscreen RGB frames of a model at given arm configurations.

    ``render(q)`` sets the first ``len(q)`` qpos entries, runs kinematics and returns an
    (height, width, 3) uint8 array. The camera is framed once, at construction, around the
    configurations ``frame_qs`` (default: qpos0), so the frames of an animation share it;
    ``frame_geoms`` frames only those geoms (``framing_camera``'s ``geoms``).
    ``show_collision`` draws the collision geoms instead of the visual ones.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        width: int = 640,
        height: int = 480,
        frame_qs: Sequence[Configuration] | np.ndarray = (),
        camera: mujoco.MjvCamera | str | None = None,
        show_collision: bool = False,
        azimuth: float = 135.0,
        elevation: float = -28.0,
        frame_geoms: np.ndarray | None = None,
    ) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self._renderer = mujoco.Renderer(model, height=height, width=width)
        self._option = mujoco.MjvOption()
        self._option.geomgroup[VISUAL_GROUP] = not show_collision
        self._option.geomgroup[COLLISION_GROUP] = show_collision
        if camera is None:
            camera = framing_camera(model, self.data, frame_qs, azimuth=azimuth,
                                    elevation=elevation, geoms=frame_geoms)
        self.camera = camera

    def render(self, q: Configuration | None = None) -> np.ndarray:
        if q is not None:
            self.data.qpos[: len(q)] = q
        mujoco.mj_kinematics(self.model, self.data)
        self._renderer.update_scene(self.data, camera=self.camera, scene_option=self._option)
        return self._renderer.render().copy()

    def render_path(self, samples: Iterable[Configuration]) -> list[np.ndarray]:
        return [self.render(q) for q in samples]

    def close(self) -> None:
        self._renderer.close()

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def linear_path(q0: Configuration, q1: Configuration, n_frames: int) -> np.ndarray:
    """(n_frames, dof) evenly spaced configurations from q0 to q1, both included."""
    q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    return q0 + np.linspace(0.0, 1.0, n_frames)[:, None] * (q1 - q0)


def save_png(path: str | Path, rgb: np.ndarray) -> None:
    iio.imwrite(path, rgb)


def save_gif(path: str | Path, frames: Sequence[np.ndarray], fps: float = 12.0) -> None:
    iio.imwrite(path, np.stack(frames), duration=1000.0 / fps, loop=0)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m envs.render", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("arm", help="arm name (envs.kinematics.ARM_NAMES)")
    parser.add_argument("--scene", default="empty", choices=sorted(SCENES))
    parser.add_argument("--seed", type=int, default=0, help="random_clutter seed")
    parser.add_argument("--tool", action=argparse.BooleanOptionalAction, default=None,
                        help="draw the held tool (default: on in the milling cell)")
    parser.add_argument("--q", type=float, nargs="+", help="configuration (default: home)")
    parser.add_argument("--path-from", type=float, nargs="+", metavar="Q")
    parser.add_argument("--path-to", type=float, nargs="+", metavar="Q")
    parser.add_argument("--milling-path", type=int, nargs=2, metavar=("I", "J"))
    parser.add_argument("--frames", type=int, default=40, help="GIF frames")
    parser.add_argument("--fps", type=float, default=12.0)
    parser.add_argument("--width", type=int, default=800)
    parser.add_argument("--height", type=int, default=600)
    parser.add_argument("--azimuth", type=float, default=135.0, help="camera, degrees")
    parser.add_argument("--elevation", type=float, default=-28.0, help="camera, degrees")
    parser.add_argument("--collision", action="store_true", help="draw collision geoms")
    parser.add_argument("--out", required=True, help=".png for a picture, .gif for a path")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    arm = make_arm(args.arm)
    kwargs = {"seed": args.seed} if args.scene == "random_clutter" else {}
    model = build_model(args.arm, args.scene, tool=args.tool, **kwargs)
    path = None
    if args.milling_path is not None:
        q1, _ = arm.ik(milling_cell_poses()[0])
        q2, _ = arm.ik(milling_cell_poses()[1])
        path = (q1[args.milling_path[0]], q2[args.milling_path[1]])
    elif args.path_from is not None or args.path_to is not None:
        if args.path_from is None or args.path_to is None:
            raise SystemExit("--path-from and --path-to go together")
        path = (args.path_from, args.path_to)
    for q in ([args.q] if args.q else []) + (list(path) if path else []):
        if len(q) != arm.dof or not np.all(np.isfinite(q)):
            raise SystemExit(f"{arm.name} needs {arm.dof} finite joint values, got {list(q)}")
    out = Path(args.out)
    if path is None:
        q = arm.home if args.q is None else args.q
        with SceneRenderer(model, width=args.width, height=args.height, frame_qs=[q],
                           show_collision=args.collision, azimuth=args.azimuth,
                           elevation=args.elevation) as renderer:
            save_png(out, renderer.render(q))
    else:
        if out.suffix.lower() != ".gif":
            raise SystemExit("a path is written as an animated .gif")
        samples = linear_path(path[0], path[1], args.frames)
        with SceneRenderer(model, width=args.width, height=args.height, frame_qs=samples,
                           show_collision=args.collision, azimuth=args.azimuth,
                           elevation=args.elevation) as renderer:
            save_gif(out, renderer.render_path(samples), fps=args.fps)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
