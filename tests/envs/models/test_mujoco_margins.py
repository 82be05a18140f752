"""The installed MuJoCo's contact margins behave as the clearance guarantee assumes.

``CollisionChecker`` gives every collision geom a margin of δ/2 and counts a pair as in
contact when ``mj_collision`` reports it: that is "closer than δ" only because MuJoCo adds
the two geoms' margins (docs/models.md). A MuJoCo that took the larger of the two, or
ignored margins for a pair type the models use, would let pairs between δ/2 and δ apart
pass as free; this checks the rule on the installed version for every pair of the
primitive shapes the models and scenes collide.
"""

from __future__ import annotations

import itertools

import mujoco
import pytest

#: Primitive shapes of the arm models and scenes, with a size whose surface point along
#: +x lies at ``REACH`` from the geom's centre.
REACH = 0.1
SHAPES = {
    "sphere": ("sphere", f"{REACH}"),
    "capsule": ("capsule", f"{REACH} 0.2"),  # axis along z: +x is on the cylinder part
    "box": ("box", f"{REACH} 0.15 0.15"),
    "cylinder": ("cylinder", f"{REACH} 0.2"),
}
MARGINS = (0.004, 0.006)  # unequal: a max() rule and a sum rule disagree


def _contacts(first: str, second: str, gap: float, margins: tuple[float, float]) -> int:
    """Contacts ``mj_collision`` reports for ``first`` at the origin and ``second`` at
    distance ``gap`` between their surfaces along x, each with its margin."""
    kind_a, size_a = SHAPES[first]
    kind_b, size_b = SHAPES[second]
    xml = f"""
    <mujoco>
      <worldbody>
        <geom name="a" type="{kind_a}" size="{size_a}" margin="{margins[0]}"/>
        <body pos="{2 * REACH + gap} 0 0">
          <freejoint/>
          <geom name="b" type="{kind_b}" size="{size_b}" margin="{margins[1]}"/>
        </body>
      </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    return int(data.ncon)


def test_the_installed_version_is_within_the_pinned_range():
    major = int(mujoco.__version__.split(".")[0])
    assert 3 <= major < 5, mujoco.__version__


@pytest.mark.parametrize(("first", "second"),
                         list(itertools.combinations_with_replacement(SHAPES, 2)))
def test_a_pair_is_in_contact_within_the_sum_of_its_margins_only(first, second):
    total = sum(MARGINS)
    # Inside the sum (and beyond the larger margin alone): a contact.
    for gap in (0.0005, max(MARGINS) + 0.0005, total - 0.0005):
        assert _contacts(first, second, gap, MARGINS) >= 1, (first, second, gap)
    # Beyond the sum: none.
    for gap in (total + 0.0005, total + 0.01):
        assert _contacts(first, second, gap, MARGINS) == 0, (first, second, gap)
    # And the rule is symmetric in which geom carries which margin.
    assert _contacts(first, second, total - 0.0005, MARGINS[::-1]) >= 1
