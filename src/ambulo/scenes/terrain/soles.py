"""Feet that touch the terrain through spheres at their soles' corners, not through their boxes.

Why: MuJoCo Warp 4.0 collides a box with a heightfield by GJK/EPA against each triangular prism
under it, and for a flat box sole resting on flat ground (a degenerate face-face contact) EPA
often settles on the prism's far side: a contact whose normal points **down** with a depth of
about the box's height (-4.95 cm for the humanoid's 5 cm foot 0.5 mm into the ground). The
solver then drives the foot into the terrain; on humanoid-rough (H200, 4096 worlds) ~1 in 4
resting feet got such a contact, robots standing still in the default pose fell within 0.1-1.5
s, some worlds blew up (iteration 0's mean reward -2.5e7) and PPO never learnt to stand.
A sphere against a prism is no degenerate case: with its centre above the surface the deepest
point is unique, and the same 400 resting feet as spheres got no wrong contact
(``tests/scenes/test_terrain_soles.py``). The CPU engine (float64, its own convex collider) was
right either way; both engines now see the same sphere contacts. Stomping feet sink further: of
400 level feet, none got a contact deeper than it sank at 1-2 cm, 290 did at 3 cm (past the
radius). So humanoid-rough also stiffens the sole contacts (``timeconst_s`` 0.01 s, twice the
physics step): 16 robots under 150 steps of random actions then fell 37 times on Warp's CPU
device instead of 48 (CPU engine: 31 either way), with no 110 rad/s joint speed at the 2nd step.

``sphere_soles`` keeps the sole's plane and outline: the spheres sit inside the box, tangent to
its bottom face at its four corners (inset by the radius), weigh nothing (the box keeps the
foot's mass and inertia), and collide with world geoms only (``conaffinity`` 1, ``contype`` 0:
the humanoid's own geoms are ``contype`` 2, so robot-robot filtering is unchanged). The box stops
colliding through contype/conaffinity; the asset's explicit ``<pair>`` contacts (foot-foot,
foot-shank) ignore those bits and stay.
"""

from __future__ import annotations

import mujoco
import numpy as np


def sphere_soles(spec: mujoco.MjSpec, box_geoms: tuple[str, ...], radius_m: float = 0.02,
                 timeconst_s: float | None = None) -> list[str]:
    """Replace the world collisions of each named box geom (full spec names) by four spheres of
    ``radius_m`` at its bottom face's corners, in the same body; return the spheres' names.
    ``timeconst_s``: the spheres' contact time constant (``solref`` (timeconst_s, 1): critically
    damped), None: the box's. Stiffer contacts sink less, and MuJoCo Warp's sphere-hfield contacts
    stay right only while a sphere sinks less than its radius (its centre above the ground).

    The bottom face is the box's local -z face (the humanoid's soles); each sphere's centre is
    ``(+-(sx - r), +-(sy - r), -sz + r)`` in the box's frame, so the lowest points of the spheres
    lie in the box's sole plane."""
    names = []
    for name in box_geoms:
        box = spec.geom(name)
        if box is None or box.type != mujoco.mjtGeom.mjGEOM_BOX:
            raise ValueError(f"sphere_soles: {name!r} is not a box geom of this scene; pass the feet's box geoms "
                             "by their full names (e.g. '/World/robot/left_foot')")
        sx, sy, sz = (float(v) for v in box.size)
        if radius_m <= 0.0 or radius_m > min(sx, sy, sz):
            raise ValueError(f"sphere_soles: radius {radius_m} m must be in (0, {min(sx, sy, sz)}] for {name!r}")
        body = box.parent
        quat = np.asarray(box.quat, dtype=np.float64)
        for i, (ux, uy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
            local = np.array([ux * (sx - radius_m), uy * (sy - radius_m), -sz + radius_m])
            offset = np.zeros(3)
            mujoco.mju_rotVecQuat(offset, local, quat)
            sphere = body.add_geom(name=f"{name}/sole_sphere{i}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                                   size=[radius_m, 0.0, 0.0], pos=np.asarray(box.pos) + offset,
                                   contype=0, conaffinity=1, condim=box.condim, friction=box.friction,
                                   solref=box.solref if timeconst_s is None else [timeconst_s, 1.0],
                                   solimp=box.solimp, density=0.0, group=box.group + 1,
                                   rgba=box.rgba)
            sphere.mass = 0.0
            names.append(sphere.name)
        box.contype = 0
        box.conaffinity = 0
    return names


__all__ = ["sphere_soles"]
