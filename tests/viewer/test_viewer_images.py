"""The camera overlay's images: a model camera rendered on another thread (as the streaming thread
does) sees a red box where it stands, depth is colour-mapped by distance, segmentation gives the box
its own colour; detections are outlined where their boxes are."""

from __future__ import annotations

import threading

import mujoco
import numpy as np
import pytest

from ambulo.viewer.images import CameraRenders, colour_depth, colour_ids, draw_detections

SCENE = """<mujoco><worldbody><light pos="0 0 3" dir="0 0 -1"/>
<camera name="front" pos="0 -2 0.5" xyaxes="1 0 0 0 0 1"/>
<geom type="plane" size="5 5 .1" rgba=".8 .8 .8 1"/>
<body name="box" pos="0 0 0.5"><freejoint/><geom type="box" size=".2 .2 .2" rgba="1 0 0 1"/></body>
</worldbody></mujoco>"""


def test_colour_maps():
    depth = colour_depth(np.array([[0.2, 7.9, np.inf]]))
    assert depth[0, 0, 0] > depth[0, 0, 2] and depth[0, 1, 2] > depth[0, 1, 0]  # near red, far blue
    assert depth[0, 2].tolist() == [0, 0, 0]  # no return: black
    ids = colour_ids(np.array([[0, 1, 2, 1]]))
    assert ids[0, 0].tolist() == [0, 0, 0] and ids[0, 1].tolist() == ids[0, 3].tolist() != ids[0, 2].tolist()


def test_detections_are_outlined_at_their_boxes():
    out = draw_detections(np.zeros((50, 80, 3), np.uint8), np.array([[20.0, 15.0, 60.0, 40.0]]), ["cup"], [0.8])
    assert out[15, 40].any() and out[40, 40].any() and out[27, 20].any()  # top, bottom, left edges
    assert not out[27, 40].any()  # inside stays as it was


def test_camera_rendered_on_another_thread_sees_the_box():
    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    out, errors = {}, []

    def render():  # a GL context belongs to the thread that made it: the viewer's streaming thread
        try:
            renders = CameraRenders(model, width=80, height=60)
            try:
                out.update({k: renders.render(data, 0, k) for k in ("rgb", "depth", "segmentation")})
            finally:
                renders.close()
        except Exception as err:  # reported below (a missing OpenGL skips)
            errors.append(err)

    thread = threading.Thread(target=render)
    thread.start()
    thread.join(timeout=120)
    if errors and "OpenGL" in type(errors[0]).__name__ + str(errors[0]):
        pytest.skip(f"no OpenGL here: {errors[0]}")
    assert not errors, errors
    rgb, depth, seg = out["rgb"], out["depth"], out["segmentation"]
    assert rgb.shape == (60, 80, 3)
    centre, corner = rgb[30, 40].astype(int), rgb[2, 2].astype(int)
    assert centre[0] > 2 * centre[1] and centre[0] > 2 * centre[2]  # the red box at the image centre
    assert not (corner[0] > 2 * corner[1])  # the sky above it is not red
    # the box's face is 1.8 m away, the floor at the bottom edge nearer: different depth colours
    assert depth[30, 40].tolist() != depth[59, 40].tolist() and depth[30, 40].any()
    assert seg[30, 40].tolist() != seg[59, 40].tolist() and seg[30, 40].any()
