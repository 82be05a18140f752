"""The plan animated: frames along the joint-space moves, rendered headless, captioned,
written as a GIF."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .playing import Plan, PlanRun, Step

if TYPE_CHECKING:
    pass

# ------------------------------------------------------------------------------- the GIF
@dataclass(frozen=True)
class Frame:
    """One animation frame: the configuration, its caption and how long it shows (s)."""

    q: np.ndarray
    lines: tuple[str, ...]
    duration: float
    alert: bool = False


def animation_frames(plan: Plan, run: PlanRun | None = None, fps: float = 12.0,
                     speed: float = 1.0, hold: float = 0.5) -> list[Frame]:
    """The plan as frames: each joint-space move interpolated linearly (the path the env
    checks) in real time at the env's joint speeds (``speed`` times faster: a move of
    ``time`` s gets ``ceil(time · fps / speed)`` frames), and each waypoint held ``hold``
    s. Captions say the waypoint, the branch label and the travel so far (interpolated
    along each move); a colliding move's frames say so, in red."""
    run = plan.chosen_run if run is None else run
    steps = run.reached
    n = run.n_waypoints
    frames: list[Frame] = []

    def frame(q: np.ndarray, step: Step, travel: float, moving: bool,
              duration: float) -> Frame:
        # The CSV's 0-based waypoint index (of 0 … n − 1), then the file's name for it.
        where = f"{'to ' if moving else ''}waypoint {step.waypoint} of 0–{n - 1}"
        return Frame(
            q=np.asarray(q), duration=duration,
            lines=(f"{where}: {plan.names[step.waypoint]}",
                   f"branch {step.branch}: {step.label}",
                   f"travel {math.degrees(travel):.1f} deg   [{run.name}]"
                   + ("   COLLISION" if step.collision else "")),
            alert=step.collision)

    if not steps:
        return frames
    travelled, tick = 0.0, 1.0 / fps
    if plan.free_start or steps[0].waypoint != 0:
        previous = steps[0].q
    else:
        previous = plan.start
        frames.append(Frame(q=previous, lines=("start", "", f"travel 0.0 deg   [{run.name}]"),
                            duration=hold))
    for step in steps:
        count = 1
        if not np.array_equal(previous, step.q):
            count = max(1, math.ceil(step.time * fps / speed))
            for k in range(1, count):
                t = k / count
                frames.append(frame(previous + t * (step.q - previous), step,
                                    travelled + t * step.travel, True, tick))
        travelled += step.travel
        frames.append(frame(step.q, step, travelled, False, hold + (tick if count > 1 else 0)))
        previous = step.q
    return frames


def _font(size: int) -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError, ImportError):  # Pillow without FreeType: the bitmap font
        return ImageFont.load_default()


def annotate(rgb: np.ndarray, lines: Sequence[str], alert: bool = False) -> np.ndarray:
    """``rgb`` with ``lines`` written on a dark band at its top (red text if ``alert``)."""
    from PIL import Image, ImageDraw

    image = Image.fromarray(rgb)
    draw = ImageDraw.Draw(image, "RGBA")
    size = max(10, rgb.shape[0] // 26)
    font = _font(size)
    band = 6 + len(lines) * (size + 4)
    draw.rectangle((0, 0, rgb.shape[1], band), fill=(0, 0, 0, 160))
    colour = (255, 90, 80) if alert else (255, 255, 255)
    for i, line in enumerate(lines):
        draw.text((6, 4 + i * (size + 4)), line, fill=colour, font=font)
    return np.asarray(image)


def render_frames(plan: Plan, frames: Sequence[Frame], width: int = 480,
                  height: int = 360) -> list[np.ndarray]:
    """Rendered, annotated RGB frames; the camera frames the arm over every pose it sweeps
    (its own geoms and the tool, not the whole cell)."""
    from ikbranch_gym.envs.render import SceneRenderer, arm_geoms

    samples = [frame.q for frame in frames]
    with SceneRenderer(plan.model, width=width, height=height, frame_qs=samples,
                       frame_geoms=arm_geoms(plan.model)) as renderer:
        return [annotate(renderer.render(frame.q), frame.lines, frame.alert)
                for frame in frames]


def gif_bytes(images: Sequence[np.ndarray], durations: Sequence[float]) -> bytes:
    """An endlessly looping GIF; ``durations`` in seconds, one per image."""
    import imageio.v3 as iio

    return iio.imwrite("<bytes>", np.stack(images), extension=".gif",
                       duration=[round(1000.0 * d) for d in durations], loop=0)
