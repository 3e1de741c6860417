"""The page's overlays: each a checkbox in the "Overlays" folder and scene nodes under ``/overlay``,
drawn by the streaming thread (at its capped rate) from copied state or from what features fed.

| overlay | scene node(s) | source |
|---|---|---|
| contact forces | ``/overlay/contacts`` (arrows) | the watched world's state, ``physics_overlay`` |
| COM / ZMP / capture point | ``/overlay/balance/{com,com_ground,zmp,capture_point}`` (spheres) | same, ``locomotion.balance`` |
| camera | the "Camera" image in the panel | the model's cameras rendered on the viewer thread (``images``) |
| map | ``/overlay/map`` (an image on the ground) | ``WebViewer.show_map`` / the navigator |
| plan | ``/overlay/plan`` (line) | ``WebViewer.show_plan`` / the navigator's route |
| footsteps | ``/overlay/footsteps`` (boxes) | ``WebViewer.show_footsteps`` / the navigator's plan |
| walked path | ``/overlay/path`` (line) | ``WebViewer.show_path`` / the navigator |
| points | ``/overlay/points/<name>`` (point cloud) | ``WebViewer.show_points`` (a lidar's ``points_w``) |
| images, detections | one panel image per name | ``WebViewer.show_image`` / ``show_detections`` |

Everything is drawn in the watched world's frame (grid slot 0, which sits where the simulation says).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import trimesh
import viser

from .feed import FedImage, Footsteps, MapLayer, OverlayFeed
from .images import IMAGE_KINDS, CameraRenders, camera_names, draw_detections
from .physics_overlay import BalanceProbe, StateReplay, contact_arrows_w

ROOT = "/overlay"
IMAGE_PERIOD_S = 0.2
"""s between camera renders (5 per second: a thumbnail, not a video)."""
GROUND_LIFT_M = 0.005
"""Ground overlays (map, plan, footsteps) sit this far above z = 0 so the floor does not hide them."""
FOOT_THICKNESS_M = 0.01
PLAN_COLOUR, PATH_COLOUR = (30, 110, 255), (20, 20, 20)
LEFT_FOOT, RIGHT_FOOT = (40, 170, 240), (240, 120, 40)
COM_COLOUR, ZMP_COLOUR, CP_COLOUR = (255, 255, 255), (230, 30, 30), (30, 90, 230)
CONTACT_COLOUR = (255, 60, 200)


def map_image(layer: MapLayer) -> np.ndarray:
    """(num_y, num_x, 4) RGBA of an occupancy map, top row = largest y (an image's first row is its
    top): free cells light and see-through, occupied dark, unknown clear."""
    occ = np.asarray(layer.occupancy)
    rgba = np.zeros(occ.shape + (4,), np.uint8)
    known = occ >= 0
    shade = (235 - 2.0 * np.clip(occ, 0, 100)).astype(np.uint8)  # 0 % -> 235, 100 % -> 35
    rgba[..., :3] = np.where(known, shade, 0)[..., None]
    rgba[..., 3] = np.where(known, np.where(occ >= 50, 230, 110), 0)
    return rgba[::-1]


def yaw_wxyz(yaw_rad: np.ndarray) -> np.ndarray:
    """(K, 4) quaternions (w, x, y, z) of rotations by ``yaw_rad`` about +z."""
    half = 0.5 * np.asarray(yaw_rad, dtype=float)
    return np.stack([np.cos(half), np.zeros_like(half), np.zeros_like(half), np.sin(half)], axis=1)


def polyline_segments(points_w: np.ndarray) -> np.ndarray:
    """(K - 1, 2, 3) segments joining consecutive points of a (K, 3) polyline."""
    return np.stack([points_w[:-1], points_w[1:]], axis=1)


class Overlays:
    """The "Overlays" folder of the page and the nodes it draws (streaming thread only, but for
    the checkboxes' callbacks, which only flag a redraw)."""

    def __init__(self, server: viser.ViserServer, feed: OverlayFeed):
        self.server, self.feed = server, feed
        gui = server.gui
        with gui.add_folder("Overlays", expand_by_default=False):
            self.contacts = gui.add_checkbox("contact forces", False, hint="an arrow per contact, 1 mm per N")
            self.balance = gui.add_checkbox("COM / ZMP / capture point", False,
                                            hint="white: CoM and its ground point, red: measured ZMP, blue: capture point")
            self.camera = gui.add_checkbox("camera", False, hint="a camera of the model, rendered for the page")
            self.camera_name = gui.add_dropdown("camera name", ("none",), initial_value="none")
            self.camera_kind = gui.add_dropdown("image", IMAGE_KINDS, initial_value="rgb")
            self.map = gui.add_checkbox("map", True, hint="the navigator's occupancy map")
            self.plan = gui.add_checkbox("plan", True, hint="the navigator's route")
            self.footsteps = gui.add_checkbox("footsteps", True, hint="the planned footsteps (blue left, orange right)")
            self.path = gui.add_checkbox("walked path", True)
            self.points = gui.add_checkbox("points", True, hint="point clouds (lidar)")
            self.images = gui.add_checkbox("images", True, hint="images and detections features show")
        self.camera_image = None
        self._image_handles: dict[str, object] = {}
        self._nodes: dict[str, object] = {}
        self._seen: dict[str, int] = {}
        self._replay: StateReplay | None = None
        self._balance: BalanceProbe | None = None
        self._renders: CameraRenders | None = None
        self._model: mujoco.MjModel | None = None
        self._next_image_s = 0.0
        for box in (self.map, self.plan, self.footsteps, self.path, self.points, self.images):
            box.on_update(lambda _e: self._seen.clear())  # redraw the fed layers as they now are

    # -- what the simulation thread asks ----------------------------------------------------------
    @property
    def needs_state(self) -> bool:
        """Whether frames must carry the watched world's state (an overlay recomputes from it)."""
        return bool(self.contacts.value or self.balance.value or self.camera.value)

    def set_model(self, model: mujoco.MjModel, robot_root: int | None, robot_bodies: list[int]) -> None:
        """A (re)compiled model: the replay, balance probe and camera list follow it."""
        self._model = model
        self._replay = StateReplay(model)
        try:
            self._balance = BalanceProbe(model, robot_root, robot_bodies) if robot_root is not None else None
        except ValueError:  # nothing to stand on: the overlay stays empty
            self._balance = None
        # (a camera renderer of the old model is replaced by the streaming thread, which owns its GL context)
        names = camera_names(model)
        self.camera_name.options = tuple(names) if names else ("none",)
        self.camera_name.value = self.camera_name.options[0]

    # -- drawing (streaming thread) -------------------------------------------------------------------
    def draw(self, state: dict[str, np.ndarray], now_s: float) -> None:
        """Draw every switched-on overlay: the state ones from ``state`` (the watched world's copied
        rows, empty when none was copied), then the fed layers that changed."""
        data = self._replay.load(state) if state and self._replay is not None else None
        self._draw_contacts(data)
        self._draw_balance(data)
        if now_s >= self._next_image_s:
            self._next_image_s = now_s + IMAGE_PERIOD_S
            self._draw_camera(data)
        self._draw_fed()

    def close(self) -> None:
        """Free the camera renderer: on the streaming thread, whose GL context it is."""
        if self._renders is not None:
            self._renders.close()
            self._renders = None

    def _hide(self, name: str) -> None:
        node = self._nodes.get(name)
        if node is not None and node.visible:
            node.visible = False

    def _draw_contacts(self, data) -> None:
        name = f"{ROOT}/contacts"
        if not self.contacts.value or data is None:
            self._hide(name)
            return
        arrows_w, _ = contact_arrows_w(self._model, data)
        if len(arrows_w) == 0:
            self._hide(name)
            return
        self._nodes[name] = self.server.scene.add_arrows(name, arrows_w.astype(np.float32), CONTACT_COLOUR,
                                                         shaft_radius=0.008, head_radius=0.02, head_length=0.04)

    def _draw_balance(self, data) -> None:
        names = [f"{ROOT}/balance/{k}" for k in ("com", "com_ground", "zmp", "capture_point")]
        if not self.balance.value or data is None or self._balance is None:
            for name in names:
                self._hide(name)
            return
        b = self._balance(data)
        ground = np.array([b.com_w[0], b.com_w[1], self._balance.cop.ground_height_m])
        for name, point, colour, radius in zip(names, (b.com_w, ground, b.zmp_w, b.capture_point_w),
                                               (COM_COLOUR, COM_COLOUR, ZMP_COLOUR, CP_COLOUR),
                                               (0.04, 0.025, 0.03, 0.03)):
            if not np.all(np.isfinite(point)):
                self._hide(name)
                continue
            position = tuple(float(v) for v in point + [0.0, 0.0, GROUND_LIFT_M])
            node = self._nodes.get(name)
            if node is None:  # created at its place: a reader never sees it at the origin
                self._nodes[name] = self.server.scene.add_icosphere(name, radius=radius, color=colour, subdivisions=2,
                                                                     cast_shadow=False, position=position)
            else:
                node.position = position
                node.visible = True

    def _draw_camera(self, data) -> None:
        if not self.camera.value or data is None or self._model is None or self._model.ncam == 0:
            if self.camera_image is not None and self.camera_image.visible:
                self.camera_image.visible = False
            return
        if self._renders is not None and self._renders.model is not self._model:
            self.close()  # the model was recompiled
        if self._renders is None:
            self._renders = CameraRenders(self._model)
        cam_id = list(self.camera_name.options).index(self.camera_name.value)
        image = self._renders.render(data, cam_id, self.camera_kind.value, self._replay.model)
        detections = self.feed.get(f"detections/{self.camera_name.value}")
        if detections is not None and self.camera_kind.value == "rgb":
            image = draw_detections(image, *detections)
        if self.camera_image is None:
            self.camera_image = self.server.gui.add_image(image, label="camera", format="jpeg")
        else:
            self.camera_image.image = image
            self.camera_image.visible = True

    def _draw_fed(self) -> None:
        changed = self.feed.take(self._seen)
        for layer, value in changed.items():
            kind, _, name = layer.partition("/")
            if kind == "map":
                self._draw_map(value)
            elif kind in ("plan", "path"):
                self._draw_line(kind, value)
            elif kind == "footsteps":
                self._draw_footsteps(value)
            elif kind == "points":
                self._draw_points(name, value)
            elif kind == "image":
                self._draw_image(name, value)
            elif kind == "detections":
                image = self.feed.get(f"image/{name}")
                if image is not None:
                    self._draw_image(name, image)

    def _draw_map(self, layer: MapLayer) -> None:
        name = f"{ROOT}/map"
        if not self.map.value:
            self._hide(name)
            return
        ny, nx = layer.occupancy.shape
        r = layer.resolution_m
        centre = (layer.origin_xy_m[0] + 0.5 * nx * r, layer.origin_xy_m[1] + 0.5 * ny * r, GROUND_LIFT_M)
        self._nodes[name] = self.server.scene.add_image(name, map_image(layer), render_width=nx * r,
                                                        render_height=ny * r, format="png", position=centre,
                                                        cast_shadow=False, receive_shadow=False)

    def _draw_line(self, kind: str, points_w: np.ndarray) -> None:
        name = f"{ROOT}/{kind}"
        box = self.plan if kind == "plan" else self.path
        if not box.value or len(points_w) < 2:
            self._hide(name)
            return
        lifted = points_w + np.array([0.0, 0.0, 2 * GROUND_LIFT_M], np.float32)
        colour = PLAN_COLOUR if kind == "plan" else PATH_COLOUR
        self._nodes[name] = self.server.scene.add_line_segments(name, polyline_segments(lifted), colour,
                                                                thickness=0.03 if kind == "plan" else 0.02)

    def _draw_footsteps(self, steps: Footsteps) -> None:
        name = f"{ROOT}/footsteps"
        if not self.footsteps.value or len(steps.poses_xyyaw_w) == 0:
            self._hide(name)
            return
        length, width = steps.foot_size_m
        box = trimesh.creation.box(extents=(length, width, FOOT_THICKNESS_M))
        poses = steps.poses_xyyaw_w
        positions = np.stack([poses[:, 0], poses[:, 1], np.full(len(poses), GROUND_LIFT_M + FOOT_THICKNESS_M / 2)],
                             axis=1)
        colours = np.where((steps.sides > 0)[:, None], LEFT_FOOT, RIGHT_FOOT).astype(np.uint8)
        self._nodes[name] = self.server.scene.add_batched_meshes_simple(
            name, np.asarray(box.vertices, np.float32), np.asarray(box.faces, np.uint32),
            batched_wxyzs=yaw_wxyz(poses[:, 2]).astype(np.float32), batched_positions=positions.astype(np.float32),
            batched_colors=colours, cast_shadow=False, receive_shadow=False, lod="off")

    def _draw_points(self, cloud: str, value: tuple[np.ndarray, np.ndarray | tuple]) -> None:
        name = f"{ROOT}/points/{cloud}"
        points_w, colours = value
        if not self.points.value or len(points_w) == 0:
            self._hide(name)
            return
        self._nodes[name] = self.server.scene.add_point_cloud(name, points_w, colours, point_size=0.04,
                                                              point_shape="circle", precision="float32")

    def _draw_image(self, name: str, fed: FedImage) -> None:
        handle = self._image_handles.get(name)
        if not self.images.value:
            if handle is not None:
                handle.visible = False
            return
        detections = self.feed.get(f"detections/{name}")
        image = fed.rgb if detections is None else draw_detections(fed.rgb, *detections)
        if handle is None:
            self._image_handles[name] = self.server.gui.add_image(image, label=name, format="jpeg")
        else:
            handle.image = image
            handle.visible = True


def footsteps_of(poses_xyyaw_w, sides=None, foot_size_m=(0.22, 0.10)) -> Footsteps:
    """A ``Footsteps`` layer (copied); ``sides`` default alternate right, left, ... (a plan's rows
    0 and 1 are the start feet)."""
    poses = np.array(poses_xyyaw_w, dtype=np.float64, copy=True).reshape(-1, 3)
    if sides is None:
        sides = np.where(np.arange(len(poses)) % 2 == 0, -1, 1)
    sides = np.array(sides, dtype=np.int8, copy=True).reshape(-1)
    if len(sides) != len(poses):
        raise ValueError(f"footsteps: {len(poses)} poses but {len(sides)} sides")
    length, width = (float(v) for v in foot_size_m)
    if not (length > 0 and width > 0 and math.isfinite(length) and math.isfinite(width)):
        raise ValueError(f"footsteps: foot_size_m {foot_size_m} must be two positive lengths, m")
    return Footsteps(poses_xyyaw_w=poses, sides=sides, foot_size_m=(length, width))
