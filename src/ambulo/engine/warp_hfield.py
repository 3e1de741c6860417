"""A depth limit on MuJoCo Warp's heightfield contacts (its convex-heightfield collision misfires).

MuJoCo Warp 4.0 collides a geom with a heightfield prism by prism through GJK/EPA. Once a sphere's
centre sinks below the surface (a sole sphere pressed deeper than its radius, as a stomping foot
does in one 5 ms step), EPA returns nonsense: contacts metres deep (-0.2 to -6.8 m) with sideways
normals, where MuJoCo's CPU collision gives the true 2-4 cm (2,000 random 2 cm spheres 0-4 cm
deep on humanoid-rough's terrain: 4 of 975 wrong at 0-2 cm, 302 of 1,025 at 2-4 cm; no
``ccd_iterations``, base depth or geom margin changed that). The solver turns a metres-deep
contact into a kick of hundreds of rad/s: humanoid-rough's robots ran away and fell on the GPU.

``limit_hfield_contact_depth(depth_m)`` wraps MuJoCo Warp's collision stage (the function its
``forward`` calls) with one kernel after it: a contact between a heightfield and another geom
deeper than ``depth_m`` becomes ``depth_m`` deep along the heightfield's up axis (away from the
terrain, the way the foot came in), at the geom's centre (misfired points lie 0.2-3 m off). True contacts that deep are rare (a sole sinks < 2 cm at
rest) and lose only depth; nonsense ones become a firm push out of the ground. The wrapper is
process-wide (MuJoCo Warp has one collision function) and a plain kernel launch, so CUDA graph
capture records it; ``None`` switches it off.
"""

from __future__ import annotations

import mujoco_warp as mjw
import warp as wp
from mujoco_warp._src import collision_driver
from mujoco_warp._src.math import make_frame

_HFIELD = int(mjw.GeomType.HFIELD)
_original_collision = collision_driver.collision
_max_depth_m: float | None = None


@wp.kernel
def _limit_depth(
    nacon: wp.array(dtype=int),
    geom_type: wp.array(dtype=int),
    geom_xpos: wp.array2d(dtype=wp.vec3),
    geom_xmat: wp.array2d(dtype=wp.mat33),
    contact_geom: wp.array(dtype=wp.vec2i),
    contact_worldid: wp.array(dtype=int),
    max_depth: float,
    contact_dist: wp.array(dtype=float),
    contact_pos: wp.array(dtype=wp.vec3),
    contact_frame: wp.array(dtype=wp.mat33),
):
    i = wp.tid()
    if i >= nacon[0] or contact_dist[i] >= -max_depth:
        return
    geoms = contact_geom[i]
    if geoms[0] < 0 or geoms[1] < 0:  # flex contacts
        return
    # the normal points from geom 0 to geom 1: up out of the terrain when it is geom 0
    sign = float(1.0)
    hfield = int(geoms[0])
    other = int(geoms[1])
    if geom_type[geoms[0]] != _HFIELD:
        if geom_type[geoms[1]] != _HFIELD:
            return
        sign = -1.0
        hfield = geoms[1]
        other = geoms[0]
    world = contact_worldid[i]
    rot = geom_xmat[world, hfield]
    up = wp.vec3(rot[0, 2], rot[1, 2], rot[2, 2]) * sign
    contact_dist[i] = -max_depth
    contact_frame[i] = make_frame(up)
    # the misfired point lies 0.2-3 m off (a lever arm for the push); the geom's centre is on the
    # push's line through a sphere's true contact point, so the push gets its true moment
    contact_pos[i] = geom_xpos[world, other]


def _collision(m, d, awake_prev=None):
    if awake_prev is None:
        _original_collision(m, d)
    else:
        _original_collision(m, d, awake_prev=awake_prev)
    if _max_depth_m is None or d.naconmax == 0:
        return
    wp.launch(_limit_depth, dim=d.naconmax,
              inputs=[d.nacon, m.geom_type, d.geom_xpos, d.geom_xmat, d.contact.geom, d.contact.worldid,
                      float(_max_depth_m)],
              outputs=[d.contact.dist, d.contact.pos, d.contact.frame])


def limit_hfield_contact_depth(depth_m: float | None) -> None:
    """Limit every heightfield contact of MuJoCo Warp in this process to ``depth_m`` deep, m
    (None: off, MuJoCo Warp's own contacts). Set it before an engine first steps: a captured
    CUDA graph keeps the depth it was captured with."""
    global _max_depth_m
    if depth_m is not None and not depth_m > 0.0:
        raise ValueError(f"hfield contact depth limit {depth_m!r}: pass a depth > 0 in m, e.g. 0.02, or None")
    _max_depth_m = None if depth_m is None else float(depth_m)
    collision_driver.collision = _collision if depth_m is not None else _original_collision


__all__ = ["limit_hfield_contact_depth"]
