"""The plan animated: frames along the joint-space moves, rendered headless, captioned,
written as a GIF."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .playing import Plan, PlanRun, Step

#: The colour a colliding move's geoms in contact are drawn in (RGBA).
HIGHLIGHT = (1.0, 0.1, 0.1, 1.0)

# ------------------------------------------------------------------------------- the GIF
@dataclass(frozen=True)
class Frame:
    """One animation frame: the configuration, its caption, how long it shows (s), and for
    a colliding move the geoms in contact at its first colliding sample (drawn red)."""

    q: np.ndarray
    lines: tuple[str, ...]
    duration: float
    alert: bool = False
    highlight: tuple[str, ...] = ()


def animation_frames(plan: Plan, run: PlanRun | None = None, fps: float = 12.0,
                     speed: float = 1.0, hold: float = 0.5) -> list[Frame]:
    """The plan as frames: each joint-space move interpolated linearly (the path the env
    checks) in real time at the env's joint speeds (``speed`` times faster: a move of
    ``time`` s gets ``ceil(time · fps / speed)`` frames), and each waypoint held ``hold``
    s. Captions say the waypoint, the branch label and the travel so far (interpolated
    along each move); a colliding move's frames say so, in red, and draw the geoms in
    contact red."""
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
            alert=step.collision,
            highlight=tuple(sorted({name for pair in step.contacts for name in pair})))

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
    """DejaVu Sans (matplotlib's own copy: Latin, Greek, Cyrillic, arrows, dashes), else
    Pillow's default font."""
    from PIL import ImageFont

    try:
        from matplotlib import font_manager

        path = font_manager.findfont("DejaVu Sans", fallback_to_default=False)
        return ImageFont.truetype(path, size)
    except (ImportError, OSError, ValueError):
        pass
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError, ImportError):  # Pillow without FreeType: the bitmap font
        return ImageFont.load_default()


#: A character no font has: how a missing glyph is drawn.
_NO_GLYPH = "\uffff"


def printable(text: str, font: Any) -> str:
    """``text`` with every character ``font`` has no glyph for as '?' (a missing glyph is
    drawn as the font's empty box: its mask equals that of a character no font has)."""
    missing = font.getmask(_NO_GLYPH)
    box = (missing.size, bytes(missing))

    def has(ch: str) -> bool:
        if ch.isspace() or ch.isascii():
            return True
        mask = font.getmask(ch)
        return (mask.size, bytes(mask)) != box

    return "".join(ch if has(ch) else "?" for ch in text)


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
        draw.text((6, 4 + i * (size + 4)), printable(line, font), fill=colour, font=font)
    return np.asarray(image)


def render_frames(plan: Plan, frames: Sequence[Frame], width: int = 480,
                  height: int = 360) -> list[np.ndarray]:
    """Rendered, annotated RGB frames; the camera frames the arm over every pose it sweeps
    (its own geoms and the tool, not the whole cell)."""
    from ikbranch_gym.envs.render import SceneRenderer, arm_geoms

    model = plan.model
    samples = [frame.q for frame in frames]
    images = []
    with SceneRenderer(model, width=width, height=height, frame_qs=samples,
                       frame_geoms=arm_geoms(model)) as renderer:
        for frame in frames:
            ids = drawn_geoms(model, frame.highlight)
            saved = model.geom_rgba[ids].copy(), model.geom_matid[ids].copy()
            model.geom_rgba[ids], model.geom_matid[ids] = HIGHLIGHT, -1  # a material wins
            try:
                images.append(annotate(renderer.render(frame.q), frame.lines, frame.alert))
            finally:
                model.geom_rgba[ids], model.geom_matid[ids] = saved
    return images


def drawn_geoms(model: Any, names: Sequence[str]) -> np.ndarray:
    """The geoms drawn for collision geoms ``names``: each itself and its visual twin
    (``<name>_vis``; a decomposed mesh's parts ``<name>_partNNN`` share ``<name>_vis``)."""
    import mujoco

    ids = []
    for name in names:
        for candidate in (name, name + "_vis", re.sub(r"_part\d+$", "", name) + "_vis"):
            geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, candidate)
            if geom >= 0:
                ids.append(geom)
    return np.array(sorted(set(ids)), dtype=np.int64)


def gif_bytes(images: Sequence[np.ndarray], durations: Sequence[float]) -> bytes:
    """An endlessly looping GIF; ``durations`` in seconds, one per image."""
    import imageio.v3 as iio

    return iio.imwrite("<bytes>", np.stack(images), extension=".gif",
                       duration=[round(1000.0 * d) for d in durations], loop=0)
