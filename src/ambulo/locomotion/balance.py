"""Balance of a biped: ZMP, support polygon, capture point, and the centre of pressure measured
in the simulator.

Frames and units: everything is in the world frame ``w`` with z up, in metres and seconds; the
ground is the horizontal plane z = ``ground_height_m``. Planar quantities are ``(..., 2)`` (x, y).

Models (references in ``research/anchors-perception-nav.md`` §3.1):

- **Cart-table / LIPM** (Kajita et al., ICRA 2003): the robot is a point mass at height z_c above
  the ground with no angular momentum about it. Its zero-moment point is
  ``p = c - z_c / g * c_ddot`` and, equivalently, ``c_ddot = omega^2 (c - p)`` with
  ``omega = sqrt(g / z_c)``.
- **Capture point** (Pratt et al., Humanoids 2006; the divergent component of motion of
  Englsberger et al., T-RO 2015): ``xi = c + c_dot / omega``. With the CoP held at r the capture
  point runs away from it, ``xi(t) = r + (xi0 - r) exp(omega t)``, and the CoM converges to xi.
- **Centre of pressure**: the point of the ground plane about which the contact wrenches have
  no horizontal moment. Under the feet of a robot it is the ZMP (Sardain & Bessonnet 2004).

Functions accept numpy arrays and torch tensors alike (batched over leading dimensions) except
where a docstring says numpy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from ..utils.validate import Checked

try:
    import torch
except ImportError:  # torch is a core dependency; keep numpy-only use possible
    torch = None

GRAVITY_MPS2 = 9.81
"""Standard gravity, m/s^2 (what MuJoCo's default ``opt.gravity`` holds to 3 digits)."""


def _xp(x):
    """The array namespace of ``x``: ``torch`` for tensors, else ``numpy``."""
    return torch if torch is not None and isinstance(x, torch.Tensor) else np


# --------------------------------------------------------------------------- cart-table
def lipm_omega(com_height_m: float, gravity_mps2: float = GRAVITY_MPS2) -> float:
    """Natural frequency of the linear inverted pendulum, ``sqrt(g / z_c)`` in 1/s."""
    if com_height_m <= 0.0:
        raise ValueError(f"CoM height must be above the ground, got {com_height_m} m")
    return math.sqrt(gravity_mps2 / com_height_m)


def cart_table_zmp(com_pos_w, com_acc_w, com_height_m: float | None = None, *,
                   ground_height_m: float = 0.0, gravity_mps2: float = GRAVITY_MPS2):
    """ZMP of a point-mass CoM: ``p = c_xy - z_c / (g + z_ddot) * c_ddot_xy``.

    Args:
      com_pos_w: (..., 3) CoM position, world frame, m; or (..., 2) (x, y) with ``com_height_m``.
      com_acc_w: (..., 3) or (..., 2) CoM acceleration, m/s^2, same layout as ``com_pos_w``.
      com_height_m: z_c, height of the CoM above the ground, m. Required for (..., 2) input;
        for (..., 3) input None takes ``com_pos_w[..., 2] - ground_height_m``.
      ground_height_m: height of the ground plane, m.

    Returns:
      (..., 2) ZMP on the ground plane, world frame, m (array or tensor like the input).

    With 3-D input the vertical acceleration enters as ``g + z_ddot``; for ``z_ddot = 0`` (the
    cart-table model's constant height) it is Kajita's ``p = c - z_c / g * c_ddot``.
    """
    if com_pos_w.shape[-1] not in (2, 3) or com_acc_w.shape[-1] != com_pos_w.shape[-1]:
        raise ValueError(f"CoM position and acceleration must both be (..., 2) or (..., 3); got "
                         f"{tuple(com_pos_w.shape)} and {tuple(com_acc_w.shape)}")
    if com_pos_w.shape[-1] == 2:
        if com_height_m is None:
            raise ValueError("(..., 2) CoM input needs com_height_m (or pass (..., 3) positions)")
        scale = com_height_m / gravity_mps2
    else:
        height = (com_pos_w[..., 2] - ground_height_m) if com_height_m is None else com_height_m
        scale = (height / (gravity_mps2 + com_acc_w[..., 2]))
        if not isinstance(scale, float):
            scale = scale[..., None]
    return com_pos_w[..., :2] - scale * com_acc_w[..., :2]


def capture_point(com_pos_xy, com_vel_xy, com_height_m: float, gravity_mps2: float = GRAVITY_MPS2):
    """Instantaneous capture point ``xi = c + c_dot / omega``, ``omega = sqrt(g / z_c)``.

    Args:
      com_pos_xy: (..., 2) or (..., 3) CoM position, world frame, m (z ignored).
      com_vel_xy: (..., 2) or (..., 3) CoM velocity, m/s (z ignored).
      com_height_m: z_c, CoM height above the ground, m.

    Returns:
      (..., 2) capture point on the ground, world frame, m.
    """
    return com_pos_xy[..., :2] + com_vel_xy[..., :2] / lipm_omega(com_height_m, gravity_mps2)


# --------------------------------------------------------------------------- polygons
@dataclass(kw_only=True)
class FootShape(Checked):
    """A rectangular sole in its foot frame (x forward, y left, origin at the foot pose)."""

    length_m: float
    """Sole length along the foot's x axis, m."""
    width_m: float
    """Sole width along the foot's y axis, m."""
    center_offset_m: tuple[float, float] = (0.0, 0.0)
    """Sole centre in the foot frame, m (e.g. the ankle sits behind the sole centre)."""


def foot_polygon(pose_xy_yaw, foot: FootShape) -> np.ndarray:
    """Corners of a sole at ``pose_xy_yaw`` = (x m, y m, yaw rad), world frame.

    Returns:
      (4, 2) float64 corners, counter-clockwise, m. A (K, 3) batch of poses gives (K, 4, 2).
    """
    pose = np.asarray(pose_xy_yaw, dtype=np.float64)
    half_l, half_w = 0.5 * foot.length_m, 0.5 * foot.width_m
    local = np.array([[half_l, half_w], [-half_l, half_w], [-half_l, -half_w], [half_l, -half_w]])
    local = local + np.asarray(foot.center_offset_m, dtype=np.float64)
    cos, sin = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    rot = np.stack([np.stack([cos, -sin], -1), np.stack([sin, cos], -1)], -2)  # (..., 2, 2)
    return np.einsum("...ij,kj->...ki", rot, local) + pose[..., None, :2]


def convex_hull(points_xy) -> np.ndarray:
    """Convex hull of (P, 2) points (Andrew's monotone chain), (M, 2) counter-clockwise,
    collinear points dropped. numpy."""
    pts = np.unique(np.asarray(points_xy, dtype=np.float64).reshape(-1, 2), axis=0)
    if len(pts) < 3:
        return pts

    def half(seq):
        chain: list[np.ndarray] = []
        for p in seq:
            while len(chain) >= 2:
                a, b = chain[-2], chain[-1]
                if (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) > 1e-15:
                    break
                chain.pop()
            chain.append(p)
        return chain

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def support_polygon(foot_poses_xy_yaw, foot: FootShape) -> np.ndarray:
    """Support polygon of the feet on the ground: one sole's rectangle, or for double support
    the convex hull of both soles.

    Args:
      foot_poses_xy_yaw: (3,) one pose or (K, 3) poses (x m, y m, yaw rad) of the feet in
        contact, world frame.

    Returns:
      (M, 2) float64 vertices, counter-clockwise, m (M = 4 for one foot, 4..8 for two).
    """
    poses = np.asarray(foot_poses_xy_yaw, dtype=np.float64).reshape(-1, 3)
    return convex_hull(foot_polygon(poses, foot).reshape(-1, 2))


def polygon_signed_distance(points_xy, polygon_xy):
    """Signed distance from points to a convex polygon's boundary: positive inside (the margin
    to the nearest edge), negative outside (minus the Euclidean distance to the polygon).

    Args:
      points_xy: (..., 2) points, m (array or tensor).
      polygon_xy: (M, 2) convex polygon, counter-clockwise, m (``support_polygon``).

    Returns:
      (...,) signed distance, m, like ``points_xy``.
    """
    xp = _xp(points_xy)
    poly = np.asarray(polygon_xy, dtype=np.float64)
    if poly.ndim != 2 or poly.shape[0] < 3 or poly.shape[1] != 2:
        raise ValueError(f"polygon must be (M >= 3, 2) vertices, got shape {poly.shape}")
    edge = np.roll(poly, -1, axis=0) - poly  # (M, 2)
    if np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1]) <= 0:
        raise ValueError("polygon must be counter-clockwise with non-zero area (use support_polygon)")
    length = np.linalg.norm(edge, axis=1)
    if xp is torch:
        poly, edge, length = (torch.as_tensor(a, dtype=points_xy.dtype, device=points_xy.device)
                              for a in (poly, edge, length))
    rel = points_xy[..., None, :] - poly  # (..., M, 2)
    cross = edge[:, 0] * rel[..., 1] - edge[:, 1] * rel[..., 0]  # > 0: left of the edge = inside
    inside = xp.all(cross >= 0.0, axis=-1)
    t = xp.clip((rel * edge).sum(-1) / length**2, 0.0, 1.0)
    gap = rel - t[..., None] * edge
    dist = xp.amin(xp.sqrt((gap * gap).sum(-1)), axis=-1)  # to the nearest edge segment
    return xp.where(inside, dist, -dist)


def zmp_in_support(zmp_xy, polygon_xy, margin_m: float = 0.0):
    """(...,) bool: the ZMP lies inside the support polygon, at least ``margin_m`` from its
    edges (a negative margin tolerates points that far outside)."""
    return polygon_signed_distance(zmp_xy, polygon_xy) >= margin_m


# --------------------------------------------------------------------------- capture region
@dataclass(frozen=True)
class CaptureRegion:
    """Where to put the next foot so that one step captures the LIPM (Koolen et al., IJRR 2012,
    one-step capturability with a finite stance foot).

    Model: LIPM at constant height z_c; during the swing of ``step_time_s`` the CoP may be
    anywhere in the stance polygon P, so the capture point at touchdown is anywhere in
    ``exp(w T) xi0 + (1 - exp(w T)) P`` (exact: for CoP paths in convex P the set is the same as
    for constant CoPs). The state is captured after touchdown if that capture point lies in the
    new sole, so the new foot's position (at the given touchdown yaw) must be in the Minkowski
    sum of that set with the mirrored sole, and within ``max_reach_m`` of the stance foot (the
    kinematic reach, a disc). Swing dynamics, step-time limits and the CoM height change at
    touchdown are not modelled.
    """

    polygon_xy: np.ndarray
    """(M, 2) convex, counter-clockwise: foot poses (x, y), world frame, m, whose sole covers a
    reachable capture point at touchdown."""
    capture_point_xy: np.ndarray
    """(M', 2) convex: the capture points reachable at touchdown, world frame, m."""
    reach_center_xy: np.ndarray
    """(2,) centre of the reach disc (the stance foot), m."""
    reach_radius_m: float
    """Radius of the reach disc, m."""

    def contains(self, foot_xy, margin_m: float = 0.0) -> np.ndarray:
        """(...,) bool: a foot placed at (..., 2) positions captures the robot in one step."""
        foot_xy = np.asarray(foot_xy, dtype=np.float64)
        reach = np.linalg.norm(foot_xy - self.reach_center_xy, axis=-1) <= self.reach_radius_m
        return reach & (polygon_signed_distance(foot_xy, self.polygon_xy) >= margin_m)


def capture_region(com_pos_xy, com_vel_xy, stance_polygon_xy, *, com_height_m: float,
                   step_time_s: float, max_reach_m: float, reach_center_xy=None,
                   swing_foot: FootShape | None = None, swing_yaw_rad: float = 0.0,
                   gravity_mps2: float = GRAVITY_MPS2) -> CaptureRegion:
    """One-step capture region of a LIPM state (see ``CaptureRegion`` for the model). numpy.

    Args:
      com_pos_xy, com_vel_xy: (2,) CoM position (m) and velocity (m/s), world frame.
      stance_polygon_xy: (M, 2) sole of the stance foot (``support_polygon``), m.
      com_height_m: z_c, m.
      step_time_s: time until the swing foot touches down, s.
      max_reach_m: how far from ``reach_center_xy`` the swing foot can land, m.
      reach_center_xy: (2,) reach centre, m; default the stance polygon's vertex mean.
      swing_foot: the swing sole; None treats it as a point (the foot must land on the
        capture point itself).
      swing_yaw_rad: yaw of the swing sole at touchdown, rad.
    """
    stance = np.asarray(stance_polygon_xy, dtype=np.float64)
    xi0 = capture_point(np.asarray(com_pos_xy, dtype=np.float64), np.asarray(com_vel_xy, dtype=np.float64),
                        com_height_m, gravity_mps2)
    growth = math.exp(lipm_omega(com_height_m, gravity_mps2) * step_time_s)
    reachable_xi = convex_hull(growth * xi0 + (1.0 - growth) * stance)
    if swing_foot is None:
        region = reachable_xi
    else:  # feet whose sole contains a point q: q - sole; Minkowski sum of convex sets = hull of sums
        sole = foot_polygon((0.0, 0.0, swing_yaw_rad), swing_foot)
        region = convex_hull((reachable_xi[:, None, :] - sole[None, :, :]).reshape(-1, 2))
    center = stance.mean(axis=0) if reach_center_xy is None else np.asarray(reach_center_xy, dtype=np.float64)
    return CaptureRegion(polygon_xy=region, capture_point_xy=reachable_xi,
                         reach_center_xy=center, reach_radius_m=float(max_reach_m))


# --------------------------------------------------------------------------- measured CoP
@dataclass(frozen=True)
class PressureCenter:
    """Centre of pressure of a set of contacts against the ground, world frame."""

    cop_w: np.ndarray
    """(3,) CoP on the ground plane (z = the plane's height), m; NaN without ground contact."""
    force_w: np.ndarray
    """(3,) total contact force the ground applies to the feet, N."""
    moment_w: np.ndarray
    """(3,) total contact moment about the world origin, N m."""
    num_contacts: int
    """Number of foot-ground contacts summed."""


def _resolve_geoms(model: mujoco.MjModel, names, what: str, *, bodies: bool) -> np.ndarray:
    ids: list[int] = []
    for name in names:
        if isinstance(name, (int, np.integer)):
            ids.append(int(name))
            continue
        obj = mujoco.mjtObj.mjOBJ_BODY if bodies else mujoco.mjtObj.mjOBJ_GEOM
        idx = mujoco.mj_name2id(model, obj, name)
        if idx < 0:
            pool = [model.body(i).name for i in range(model.nbody)] if bodies else \
                   [model.geom(i).name for i in range(model.ngeom)]
            raise ValueError(f"center of pressure: no {('body' if bodies else 'geom')} named {name!r} "
                             f"for the {what}; names: {[p for p in pool if p][:16]}")
        ids.append(idx)
    if bodies:
        return np.flatnonzero(np.isin(model.geom_bodyid, ids))
    return np.asarray(ids, dtype=np.int64)


class CenterOfPressure:
    """Measured ZMP: the centre of pressure of the feet's contacts with the ground.

    Sums the wrenches of every contact between a foot geom and a ground geom
    (``mujoco.mj_contactForce``, rotated from each contact frame to the world) and returns the
    point of the ground plane z = h about which their moment has no horizontal component:
    ``px = (h Fx - My) / Fz``, ``py = (h Fy + Mx) / Fz`` with (F, M) the total force on the feet
    and its moment about the world origin.

    Args:
      model: the compiled model.
      foot_bodies: names or ids of the foot bodies; all their geoms count as feet.
      ground_geoms: names or ids of the ground geoms; default every geom of the world body.
      ground_height_m: height of the (horizontal) ground plane, m; default the height of the
        first ground geom's origin (the surface for a plane; pass it for boxes or height fields).
      min_normal_force_n: below this total vertical force the CoP is undefined (NaN).
    """

    def __init__(self, model: mujoco.MjModel, foot_bodies: Sequence[str | int], *,
                 ground_geoms: Sequence[str | int] | None = None, ground_height_m: float | None = None,
                 min_normal_force_n: float = 1e-6):
        self.model = model
        self.foot_geom_ids = _resolve_geoms(model, foot_bodies, "feet", bodies=True)
        if len(self.foot_geom_ids) == 0:
            raise ValueError(f"center of pressure: the bodies {list(foot_bodies)} have no geoms")
        if ground_geoms is None:
            self.ground_geom_ids = np.flatnonzero(model.geom_bodyid == 0)
        else:
            self.ground_geom_ids = _resolve_geoms(model, ground_geoms, "ground", bodies=False)
        if len(self.ground_geom_ids) == 0:
            raise ValueError("center of pressure: no ground geoms (the world body has none); pass ground_geoms")
        self.ground_height_m = (float(model.geom_pos[self.ground_geom_ids[0], 2])
                                if ground_height_m is None else float(ground_height_m))
        self.min_normal_force_n = min_normal_force_n
        self._is_foot = np.zeros(model.ngeom, dtype=bool)
        self._is_foot[self.foot_geom_ids] = True
        self._is_ground = np.zeros(model.ngeom, dtype=bool)
        self._is_ground[self.ground_geom_ids] = True
        self._scratch: mujoco.MjData | None = None

    def __call__(self, data: mujoco.MjData) -> PressureCenter:
        """CoP of ``data``'s current contacts (after ``mj_step``/``mj_forward``)."""
        ncon = data.ncon
        force, moment = np.zeros(3), np.zeros(3)
        if ncon == 0:
            return self._result(force, moment, 0)
        geom = np.asarray(data.contact.geom)[:ncon]
        foot_first = self._is_foot[geom[:, 0]] & self._is_ground[geom[:, 1]]
        foot_second = self._is_ground[geom[:, 0]] & self._is_foot[geom[:, 1]]
        rows = np.flatnonzero(foot_first | foot_second)
        frames = np.asarray(data.contact.frame)[rows].reshape(-1, 3, 3)  # rows: normal, tangents
        pos = np.asarray(data.contact.pos)[rows]
        wrench = np.zeros((len(rows), 6))
        for k, i in enumerate(rows):
            mujoco.mj_contactForce(self.model, data, int(i), wrench[k])
        # the contact frame's wrench acts on geom2 (the normal points from geom1 to geom2)
        sign = np.where(foot_second[rows], 1.0, -1.0)[:, None]
        f_w = sign * np.einsum("kji,kj->ki", frames, wrench[:, :3])
        tau_w = sign * np.einsum("kji,kj->ki", frames, wrench[:, 3:])
        force = f_w.sum(0)
        moment = (np.cross(pos, f_w) + tau_w).sum(0)
        return self._result(force, moment, len(rows))

    def _result(self, force: np.ndarray, moment: np.ndarray, count: int) -> PressureCenter:
        h = self.ground_height_m
        if force[2] < self.min_normal_force_n:
            cop = np.array([np.nan, np.nan, h])
        else:
            cop = np.array([(h * force[0] - moment[1]) / force[2], (h * force[1] + moment[0]) / force[2], h])
        return PressureCenter(cop_w=cop, force_w=force, moment_w=moment, num_contacts=count)

    def batch(self, engine, world_ids: Sequence[int] | None = None) -> np.ndarray:
        """(W, 3) CoP of each of an engine's worlds (``engine.get_data(world)``), m; NaN rows
        for worlds without ground contact. The per-world ``MjData`` is reused between calls."""
        ids = range(engine.num_worlds) if world_ids is None else world_ids
        out = []
        for world in ids:
            self._scratch = engine.get_data(int(world), self._scratch)
            out.append(self(self._scratch).cop_w)
        return np.array(out).reshape(-1, 3)


__all__ = [
    "GRAVITY_MPS2", "lipm_omega", "cart_table_zmp", "capture_point", "FootShape", "foot_polygon",
    "convex_hull", "support_polygon", "polygon_signed_distance", "zmp_in_support", "CaptureRegion",
    "capture_region", "PressureCenter", "CenterOfPressure",
]
