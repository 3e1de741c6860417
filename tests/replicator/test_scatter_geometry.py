"""The upright geometry a scatterer places an object by (``replicator.scatter``): how deep its lowest
point lies below its origin (its resting height) and the circle about its origin that holds it at any
yaw (the device draws' footprint), both from one set of bounding-box corners in the object's frame."""

import math

import mujoco
import pytest

from ambulo.core.randomize import subtree_geoms
from ambulo.replicator.scatter import bottom_offset, footprint_radius

# a box 0.2 x 0.4 x 0.6 m turned 90 deg about z, 0.3 m ahead of the origin; a child body 0.5 m below
# the origin with a 0.05 m sphere 0.4 m to the side
OBJECT = """<mujoco><worldbody>
  <body name="thing" pos="1 2 3"><freejoint/>
    <geom type="box" size=".1 .2 .3" pos=".3 0 0" euler="0 0 90"/>
    <body pos="0 0 -.5"><geom type="sphere" size=".05" pos="0 .4 0"/></body>
  </body>
</worldbody></mujoco>"""


def test_the_lowest_corner_and_the_yaw_circle_follow_the_geoms_and_the_child_bodies():
    model = mujoco.MjModel.from_xml_string(OBJECT)
    body = model.body("thing").id
    geoms = subtree_geoms(model, body)
    # the sphere's box bottom: 0.5 m down to its centre plus its radius
    assert bottom_offset(model, body, geoms) == pytest.approx(0.55, abs=1e-12)
    # the turned box reaches x = 0.3 + 0.2 with |y| = 0.1 (its long side now along x): farther than the sphere
    assert footprint_radius(model, body, geoms) == pytest.approx(math.hypot(0.5, 0.1), abs=1e-12)
