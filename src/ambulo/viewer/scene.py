"""The drawn worlds in viser's scene: one copy of the model's shapes per grid slot, each slot a frame
``/w<k>`` at its offset (``layout.grid_offsets_w``) holding a frame ``/w<k>/b<body>`` per body with
its meshes; only the poses of moving bodies travel after the first frame of a layout.

Ground planes (``geometry.is_ground``: horizontal planes at least 2 m wide) are drawn in slot 0 only, with a
grid on them (every world's ground is the same plane; copies would z-fight); the other worlds stand
on it or beside it. Other planes (an apartment's skirting, door casings, pictures) are scenery,
drawn in every slot without a grid.
"""

from __future__ import annotations

import mujoco
import numpy as np
import viser
from viser import _messages

from .geometry import GeomShape, is_ground, static_bodies
from .layout import grid_offsets_w


class GridScene:
    """Scene nodes of ``count`` worlds of one model (streaming thread, after ``set_model``)."""

    def __init__(self, server: viser.ViserServer):
        self.server = server
        self.model: mujoco.MjModel | None = None
        self.shapes: list[GeomShape] = []
        self.spacing_m = 0.0
        self.slots: list[dict[int, viser.FrameHandle]] = []
        """Per slot, body id -> its frame handle."""
        self.slot_frames: list[viser.FrameHandle] = []
        self.offsets_w = np.zeros((0, 3))
        self._static = np.zeros(0, bool)
        self._sent_static: list[bool] = []
        self._hidden: set[int] = set()

    def set_model(self, model: mujoco.MjModel, shapes: list[GeomShape], spacing_m: float) -> None:
        self.clear()
        self.model, self.shapes, self.spacing_m = model, shapes, spacing_m
        self._static = static_bodies(model)

    def clear(self) -> None:
        for frame in self.slot_frames:
            frame.remove()
        self.slot_frames, self.slots, self._sent_static = [], [], []
        self.offsets_w = np.zeros((0, 3))

    def layout(self, count: int, spacing_m: float | None = None) -> None:
        """Draw ``count`` worlds (adds or removes slots; a new spacing moves them)."""
        if spacing_m is not None and spacing_m != self.spacing_m:
            self.spacing_m = spacing_m
        offsets = grid_offsets_w(count, self.spacing_m)
        while len(self.slots) > count:
            self.slot_frames.pop().remove()
            self.slots.pop()
            self._sent_static.pop()
        for k, frame in enumerate(self.slot_frames):
            if not np.allclose(self.offsets_w[k], offsets[k]):
                frame.position = tuple(offsets[k])
        for k in range(len(self.slots), count):
            self._add_slot(k, offsets[k])
        self.offsets_w = offsets

    def _add_slot(self, k: int, offset_w: np.ndarray) -> None:
        scene = self.server.scene
        slot_frame = scene.add_frame(f"/w{k}", show_axes=False, position=tuple(offset_w))
        bodies: dict[int, viser.FrameHandle] = {}
        for shape in self.shapes:
            ground = is_ground(shape)
            if ground and k > 0:
                continue
            b = shape.body_id
            if b not in bodies:
                bodies[b] = scene.add_frame(f"/w{k}/b{b}", show_axes=False, visible=b not in self._hidden)
            rgb = tuple(int(round(255 * c)) for c in shape.rgba[:3])
            opacity = None if shape.rgba[3] >= 1.0 else shape.rgba[3]
            scene.add_mesh_simple(f"/w{k}/b{b}/g{shape.geom_id}", shape.vertices_b, shape.faces, color=rgb,
                                  opacity=opacity, cast_shadow=not shape.is_plane, receive_shadow=True)
            if ground:
                half = float(np.abs(shape.vertices_b[:, :2]).max())
                scene.add_grid(f"/w{k}/b{b}/grid{shape.geom_id}", width=2 * half, height=2 * half,
                               position=tuple(shape.vertices_b[:, :3].mean(axis=0) + [0, 0, 1e-3]),
                               cell_size=0.5, section_size=1.0, plane_opacity=0.0)
        self.slot_frames.append(slot_frame)
        self.slots.append(bodies)
        self._sent_static.append(False)

    def send(self, xpos_w: np.ndarray, xquat_w: np.ndarray) -> None:
        """Queue the poses of slot k's bodies from row k of (K, nbody, 3) ``xpos_w`` and (K, nbody, 4)
        ``xquat_w`` (world frame; each slot's frame adds its offset). Call inside ``server.atomic()``."""
        for k, bodies in enumerate(self.slots[:len(xpos_w)]):
            moving = [b for b in bodies if not (self._static[b] and self._sent_static[k])]
            _queue_poses([bodies[b] for b in moving], xpos_w[k][moving].tolist(), xquat_w[k][moving].tolist())
            self._sent_static[k] = True

    def set_visible(self, bodies: list[int], visible: bool) -> None:
        """Show or hide ``bodies`` in every slot (and in slots added later)."""
        (self._hidden.difference_update if visible else self._hidden.update)(bodies)
        for slot in self.slots:
            for b in bodies:
                if b in slot:
                    slot[b].visible = visible


def _queue_poses(handles: list, positions: list, quats_wxyz: list) -> None:
    """Queue new poses of scene nodes: what ``handle.position = ...; handle.wxyz = ...`` does in
    viser 1.1.1 (``_scene_handles._set_pose_vector``) without its per-value cast and ``np.allclose``
    test, a tenth of the streaming thread's time per frame (0.3 ms instead of 3.4 ms for 19
    bodies, measured). Private API: viser is pinned in pyproject.toml, and the page test
    (tests/viewer/test_viewer_browser.py) fails if the page stops following the poses."""
    for handle, position, wxyz in zip(handles, positions, quats_wxyz):
        impl = handle._impl
        impl.position[:] = position
        impl.wxyz[:] = wxyz
        impl.api._queue_scene_message(_messages.SetPositionMessage(impl.name, tuple(position)))
        impl.api._queue_scene_message(_messages.SetOrientationMessage(impl.name, tuple(wxyz)))
