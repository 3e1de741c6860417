"""``WebViewer``'s public overlay API: what a feature calls to have its state drawn (the navigator's
map, plan, footsteps and walked path; point clouds; images; detections). Every call copies its
arguments and returns (``feed.OverlayFeed``): safe from any thread, never waits for the page.
The page draws each while its checkbox in "Overlays" is ticked.
"""

from __future__ import annotations

import numpy as np

from .feed import FedImage, MapLayer, OverlayFeed, as_image, as_points_w
from .overlays import footsteps_of

POINT_COLOUR = (0, 200, 120)


class FeedApi:
    """Mixed into ``WebViewer`` (which owns ``feed``)."""

    feed: OverlayFeed

    def show_map(self, occupancy, origin_xy_m=None, resolution_m: float | None = None) -> None:
        """Draw a 2-D occupancy map on the ground: a ``maps.Grid2D``, or its ``occupancy`` (num_y,
        num_x) int8 (-1 unknown, 0..100 %) with ``origin_xy_m`` (lower-left corner of cell [0, 0], m)
        and ``resolution_m``."""
        if hasattr(occupancy, "occupancy"):
            occupancy, origin_xy_m, resolution_m = occupancy.occupancy, occupancy.origin_xy_m, occupancy.resolution_m
        occ = np.array(occupancy, dtype=np.int8, copy=True)
        if occ.ndim != 2 or origin_xy_m is None or resolution_m is None or resolution_m <= 0:
            raise ValueError("show_map: pass a maps.Grid2D, or a (num_y, num_x) occupancy with origin_xy_m "
                             "and resolution_m > 0")
        self.feed.put("map", MapLayer(occupancy=occ, origin_xy_m=(float(origin_xy_m[0]), float(origin_xy_m[1])),
                                      resolution_m=float(resolution_m)))

    def show_plan(self, points_w) -> None:
        """Draw a planned route, (K, 2) or (K, 3) world points, m, as a line on the ground."""
        self.feed.put("plan", as_points_w(points_w, "show_plan"))

    def show_path(self, points_w) -> None:
        """Draw the path walked so far, (K, 2) or (K, 3) world points, m."""
        self.feed.put("path", as_points_w(points_w, "show_path"))

    def show_footsteps(self, poses_xyyaw_w, sides=None, foot_size_m=(0.22, 0.10)) -> None:
        """Draw footsteps: (K, 3) x m, y m, yaw rad (world), ``sides`` (K,) +1 left / -1 right
        (default alternating from a right foot), soles ``foot_size_m`` (length, width), m. A
        ``nav.FootstepPlan`` goes as ``show_footsteps(plan.footsteps_xyyaw_w, plan.foot_sides)``."""
        self.feed.put("footsteps", footsteps_of(poses_xyyaw_w, sides, foot_size_m))

    def show_points(self, name: str, points_w, colour=POINT_COLOUR) -> None:
        """Draw a point cloud ``name``: (K, 3) world points, m (e.g. a lidar's
        ``get_current_frame().points_w[world]``, its misses dropped with ``hit``); one RGB colour
        or (K, 3) uint8 colours."""
        points = as_points_w(points_w, "show_points")
        colours = np.array(colour, dtype=np.uint8, copy=True)
        if colours.ndim == 2 and len(colours) != len(points):
            raise ValueError(f"show_points: {len(points)} points but {len(colours)} colours")
        self.feed.put(f"points/{name}", (points, colours if colours.ndim == 2 else tuple(int(c) for c in colours)))

    def show_image(self, name: str, image) -> None:
        """Show an image (H, W, 3) in the page's panel under ``name`` (a camera frame, a depth image
        already colour-mapped, e.g. with ``images.colour_depth``)."""
        self.feed.put(f"image/{name}", FedImage(rgb=as_image(image, "show_image")))

    def show_detections(self, name: str, detections) -> None:
        """Draw detections on the image ``name`` (one ``show_image`` fed, or a model camera shown by the
        "camera" overlay): an ``ambulo.detection`` ``Detections`` (``boxes_px`` (N, 4) x0 y0 x1 y1 px,
        ``labels``, ``scores``), or a (boxes_px, labels, scores) tuple."""
        if hasattr(detections, "boxes_px"):
            boxes, labels, scores = detections.boxes_px, detections.labels, detections.scores
        else:
            boxes, labels, scores = detections
        boxes = np.array(boxes, dtype=np.float32, copy=True).reshape(-1, 4)
        labels, scores = [str(v) for v in labels], np.array(scores, dtype=np.float32, copy=True).reshape(-1)
        if not len(boxes) == len(labels) == len(scores):
            raise ValueError(f"show_detections: {len(boxes)} boxes, {len(labels)} labels, {len(scores)} scores")
        self.feed.put(f"detections/{name}", (boxes, labels, scores))

    def navigator_observer(self, snapshot) -> None:
        """An observer for ``ambulo.navigation.Navigator.add_observer(viewer.navigator_observer,
        images=False)``: each ``NavSnapshot`` feeds the map (when it changed), the route, the
        footstep plan, the walked path and, when the navigator rendered one, its camera frame."""
        occupancy = getattr(snapshot, "occupancy", None)
        if occupancy is not None and occupancy is not getattr(self, "_last_nav_map", None):
            self._last_nav_map = occupancy  # the navigator replaces its map when it changes
            self.show_map(occupancy)
        if getattr(snapshot, "route_xy_m", None) is not None and len(snapshot.route_xy_m) >= 2:
            self.show_plan(snapshot.route_xy_m)
        plan = getattr(snapshot, "footsteps", None)
        if plan is not None and len(plan.footsteps_xyyaw_w):
            self.show_footsteps(plan.footsteps_xyyaw_w, plan.foot_sides)
        if getattr(snapshot, "walked_xy_m", None) is not None and len(snapshot.walked_xy_m) >= 2:
            self.show_path(snapshot.walked_xy_m)
        frame = getattr(snapshot, "frame", None)
        if frame is not None and getattr(frame, "rgb", None) is not None:
            self.show_image("navigator camera", frame.rgb)
