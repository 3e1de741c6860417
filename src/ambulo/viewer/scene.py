"""The drawn worlds in viser's scene: each visible geom's mesh is sent once, as one batched mesh
``/worlds/g<geom>`` with an instance per drawn world (the watched one first), at that world's grid
offset (``layout.grid_offsets_w``) plus its body's pose. A grid of 16 worlds costs one copy of
the meshes, not 16 (the page's GPU draws the instances); a frame updates one (K, 3) position and
one (K, 4) orientation array per geom of a moving body.

Ground planes (``geometry.is_ground``: horizontal planes at least 2 m wide) are drawn once, in the
watched world's place, with a grid on them (every world's ground is the same plane; copies would
z-fight), under a frame ``/ground/b<body>`` holding their body's pose. Other planes (an
apartment's skirting, door casings, pictures) are scenery, drawn for every world without a grid.
"""

from __future__ import annotations

import mujoco
import numpy as np
import viser

from .geometry import GeomShape, is_ground, static_bodies
from .layout import grid_offsets_w

IDENTITY_WXYZ = (1.0, 0.0, 0.0, 0.0)


class GridScene:
    """Scene nodes of ``count`` worlds of one model (streaming thread, after ``set_model``)."""

    def __init__(self, server: viser.ViserServer):
        self.server = server
        self.model: mujoco.MjModel | None = None
        self.shapes: list[GeomShape] = []
        self.spacing_m = 0.0
        self.count = 0
        """Worlds drawn (instances per batched mesh)."""
        self.geoms: dict[int, viser.BatchedMeshHandle] = {}
        """Geom id -> its batched mesh (ground planes aside)."""
        self.ground: dict[int, viser.FrameHandle] = {}
        """Body id -> the frame of its ground planes."""
        self.offsets_w = np.zeros((0, 3))
        self._static = np.zeros(0, bool)
        self._sent_static = False
        self._hidden: set[int] = set()

    def set_model(self, model: mujoco.MjModel, shapes: list[GeomShape], spacing_m: float) -> None:
        self.clear()
        self.model, self.shapes, self.spacing_m = model, shapes, spacing_m
        self._static = static_bodies(model)

    def clear(self) -> None:
        for node in (*self.geoms.values(), *self.ground.values()):
            node.remove()
        self.geoms, self.ground, self.count = {}, {}, 0
        self.offsets_w = np.zeros((0, 3))

    def layout(self, count: int, spacing_m: float | None = None) -> None:
        """Draw ``count`` worlds (a new count or spacing re-sends the batched meshes once)."""
        if spacing_m is not None and spacing_m != self.spacing_m:
            self.spacing_m = spacing_m
            self.count = 0
        if count == self.count:
            return
        self.offsets_w = grid_offsets_w(count, self.spacing_m)
        for node in self.geoms.values():
            node.remove()
        # the new meshes are published with their count at the end: a reader on another thread
        # (a test polling instance_positions_w, the viewer's own page) never sees the new count
        # beside a half-built dict
        geoms: dict[int, viser.BatchedMeshHandle] = {}
        self._sent_static = False
        scene = self.server.scene
        for shape in self.shapes:
            b, rgb = shape.body_id, tuple(int(round(255 * c)) for c in shape.rgba[:3])
            opacity = None if shape.rgba[3] >= 1.0 else shape.rgba[3]
            if is_ground(shape):
                if b not in self.ground:
                    self.ground[b] = scene.add_frame(f"/ground/b{b}", show_axes=False, visible=b not in self._hidden)
                if f"/ground/b{b}/g{shape.geom_id}" not in scene._handle_from_node_name:
                    self._add_ground(shape, rgb, opacity)
                continue
            # placed at the offsets until the first frame poses them
            geoms[shape.geom_id] = scene.add_batched_meshes_simple(
                f"/worlds/g{shape.geom_id}", shape.vertices_b, shape.faces,
                batched_wxyzs=np.tile(IDENTITY_WXYZ, (count, 1)), batched_positions=self.offsets_w.copy(),
                batched_colors=rgb, opacity=opacity, lod="off", cast_shadow=not shape.is_plane,
                receive_shadow=True, visible=b not in self._hidden)
        self.geoms, self.count = geoms, count

    def _add_ground(self, shape: GeomShape, rgb: tuple, opacity: float | None) -> None:
        scene, b = self.server.scene, shape.body_id
        scene.add_mesh_simple(f"/ground/b{b}/g{shape.geom_id}", shape.vertices_b, shape.faces, color=rgb,
                              opacity=opacity, cast_shadow=False, receive_shadow=True)
        half = float(np.abs(shape.vertices_b[:, :2]).max())
        scene.add_grid(f"/ground/b{b}/grid{shape.geom_id}", width=2 * half, height=2 * half,
                       position=tuple(shape.vertices_b[:, :3].mean(axis=0) + [0, 0, 1e-3]),
                       cell_size=0.5, section_size=1.0, plane_opacity=0.0)

    def send(self, xpos_w: np.ndarray, xquat_w: np.ndarray) -> None:
        """Pose the drawn worlds' geoms from (K, nbody, 3) ``xpos_w`` and (K, nbody, 4) ``xquat_w``
        (world frame; row k is drawn at offset k). Bodies welded to the world are posed once per
        layout. Call inside ``server.atomic()``."""
        k = min(len(xpos_w), self.count)
        if k == 0:
            return
        moving = [(geom, node) for geom, node in self.geoms.items()
                  if not (self._sent_static and self._static[self.model.geom_bodyid[geom]])]
        if moving:
            # one gather for all geoms, cast once to viser's float32: (k, G, 3) and (k, G, 4). viser copies
            # what it is given and sends a whole array per property (unchanged ones not at all), so a
            # column view is enough; only when fewer worlds than instances came are the others' rows kept
            bodies = self.model.geom_bodyid[[geom for geom, _ in moving]]
            positions = (xpos_w[:k, bodies] + self.offsets_w[:k, None]).astype(np.float32)
            wxyzs = xquat_w[:k, bodies].astype(np.float32)
            for j, (_, node) in enumerate(moving):
                p, q = positions[:, j], wxyzs[:, j]
                if k < self.count:
                    p, q = np.concatenate([p, node.batched_positions[k:]]), np.concatenate([q, node.batched_wxyzs[k:]])
                node.batched_positions, node.batched_wxyzs = p, q
        if not self._sent_static:
            for b, frame in self.ground.items():
                frame.position, frame.wxyz = tuple(xpos_w[0, b]), tuple(xquat_w[0, b])
        self._sent_static = True

    def set_visible(self, bodies: list[int], visible: bool) -> None:
        """Show or hide ``bodies`` in every drawn world (and after a new layout)."""
        (self._hidden.difference_update if visible else self._hidden.update)(bodies)
        hidden = set(bodies)
        for geom, node in self.geoms.items():
            if int(self.model.geom_bodyid[geom]) in hidden:
                node.visible = visible
        for b, frame in self.ground.items():
            if b in hidden:
                frame.visible = visible

    def instance_positions_w(self, geom: int) -> np.ndarray:
        """(K, 3) where ``geom``'s instances are drawn, page frame, m (what tests read)."""
        return np.asarray(self.geoms[geom].batched_positions)
