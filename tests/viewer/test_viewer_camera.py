"""The page's camera: the World's viewport camera recovered from MuJoCo's free-camera angles, and
the pinhole projection the page's three.js camera applies."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

pytest.importorskip("viser")
from ambulo.viewer.camera import CameraPose, from_mjv_camera, project_w


def test_free_camera_angles_give_back_the_eye_set_camera_view_used():
    eye, target = np.array([2.8, -2.8, 1.9]), np.array([0.0, 0.0, 0.6])
    offset = eye - target
    cam = mujoco.MjvCamera()  # as ambulo.sim.set_camera_view fills it
    cam.lookat[:] = target
    cam.distance = float(np.linalg.norm(offset))
    cam.azimuth = math.degrees(math.atan2(-offset[1], -offset[0]))
    cam.elevation = -math.degrees(math.asin(offset[2] / cam.distance))
    pose = from_mjv_camera(cam, fovy_deg=45.0)
    np.testing.assert_allclose(pose.eye_w, eye, atol=1e-9)
    np.testing.assert_allclose(pose.target_w, target, atol=1e-12)
    assert pose.fovy_rad == pytest.approx(math.pi / 4)


def test_projection_by_hand():
    # looking along +x from the origin: +y is to the left on the page, +z up
    pose = CameraPose(eye_w=(0.0, 0.0, 0.0), target_w=(1.0, 0.0, 0.0), fovy_rad=math.radians(90.0))
    width, height = 400, 200
    focal = 0.5 * height / math.tan(math.radians(45.0))  # 100 px
    px = project_w([[1.0, 0.0, 0.0], [2.0, 1.0, 0.5], [-1.0, 0.0, 0.0]], pose, width, height)
    np.testing.assert_allclose(px[0], [200.0, 100.0])
    np.testing.assert_allclose(px[1], [200.0 - focal * 0.5, 100.0 - focal * 0.25])
    assert np.isnan(px[2]).all()  # behind the camera
