"""Let only some bodies' geoms collide with the terrain's static boxes (``terrain.boxes``); every
other pair, the heightfield's included, keeps colliding as before.

Why: MuJoCo Warp's all-pairs (nxn) broadphase tests every geom pair that passes MuJoCo's
contype/conaffinity filter, in every world and every physics step; ``mujoco_warp.put_model``
builds that list once (``nxn_geom_pair_filtered``). humanoid-rough's default terrain has 488 boxes
and one hfield: 23 colliding robot geoms x 489 = 11,247 candidate pairs a world, and the rough
task ran at 0.47 of the flat one's env-steps/s on an H200 (issue 30 asks 0.5). The boxes are
flat, stairs and border ground: only what walks on them needs them.

How: one contype bit ``B`` that no geom of the spec uses (neither bit field) becomes the boxes'
only bit (``contype = B``, ``conaffinity = 0``) and is added to the colliding geoms of the named
bodies (``conaffinity |= B``). MuJoCo collides geoms g1, g2 when ``contype1 & conaffinity2 or
contype2 & conaffinity1``, so a box now collides with geom g exactly when g's conaffinity has
``B``: the named bodies' geoms. No other geom's contype has ``B``, so the bit added to their
conaffinity creates no other pair; the boxes' old bits (contype = conaffinity = 1) meant nothing
between static geoms of one body. The hfield is untouched. Explicit ``<pair>`` contacts ignore
the bits and stay. A geom that is not named (a hand, the torso, a free object) passes through the
boxes and lands on the hfield below them (``boxes.SUNK_M`` under the lowest ground).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ambulo.core import geom_collides

_FREE_BITS = 16
"""Look for the box bit in the low 16 bits: ``core.randomize.placement`` moves static geoms' bits
into the upper 16 and refuses a model that already uses them."""


def restrict_box_colliders(spec: mujoco.MjSpec, terrain_body: str, bodies: tuple[str, ...]) -> int:
    """Make the static boxes of ``terrain_body`` (its box geoms; the hfield is left alone) collide only
    with the colliding geoms of ``bodies`` (full body names in ``spec``; each body's own geoms, not
    its children's). Returns the bit used (0 when the terrain has no boxes: nothing changes).

    ValueError for a body that is not in the spec or has no colliding geom, or when the low 16
    contype/conaffinity bits are all used."""
    terrain = spec.body(terrain_body)
    if terrain is None:
        raise ValueError(f"restrict_box_colliders: no body {terrain_body!r} in the spec; pass the terrain's body name")
    boxes = [g for g in terrain.geoms if g.type == mujoco.mjtGeom.mjGEOM_BOX and geom_collides(g)]
    colliders = []
    for name in bodies:
        body = spec.body(name)
        if body is None:
            raise ValueError(f"restrict_box_colliders: no body {name!r} in the spec; give full body names "
                             "(e.g. '/World/robot/left_foot')")
        geoms = [g for g in body.geoms if geom_collides(g)]
        if not geoms:
            raise ValueError(f"restrict_box_colliders: body {name!r} has no colliding geom (contype or conaffinity "
                             "set); name bodies that touch the ground")
        colliders += geoms
    if not boxes:
        return 0
    used = 0
    for g in spec.geoms:  # the boxes' own bits (1, 1) are about to go
        if not (g.parent is not None and g.parent.name == terrain_body and g.type == mujoco.mjtGeom.mjGEOM_BOX):
            used |= int(g.contype) | int(g.conaffinity)
    free = [1 << i for i in range(_FREE_BITS) if not used & (1 << i)]
    if not free:
        raise ValueError("restrict_box_colliders: every one of the low 16 contype/conaffinity bits is used by some "
                         "geom; free one or leave the terrain boxes colliding with everything")
    bit = free[0]
    for g in boxes:
        g.contype, g.conaffinity = bit, 0
    for g in colliders:
        g.conaffinity = int(g.conaffinity) | bit
    return bit


def candidate_geom_pairs(model: mujoco.MjModel) -> np.ndarray:
    """(P, 2) int the geom pairs MuJoCo's filter lets collide (contype/conaffinity, not both bodies
    welded together, not both without dofs, not parent and child unless ``filterparent`` is off, not
    ``<exclude>``d), plus the explicit ``<pair>`` contacts: the list MuJoCo Warp's nxn broadphase
    tests every step (``mujoco_warp.put_model``'s ``nxn_geom_pair_filtered``, without collision
    sensors); MuJoCo C applies the same filter to the pairs its sweep-and-prune finds overlapping."""
    g1, g2 = np.triu_indices(model.ngeom, k=1)
    weld = model.body_weldid
    w1, w2 = weld[model.geom_bodyid[g1]], weld[model.geom_bodyid[g2]]
    p1, p2 = weld[model.body_parentid[w1]], weld[model.body_parentid[w2]]
    bits = (model.geom_contype[g1] & model.geom_conaffinity[g2]) | (model.geom_contype[g2] & model.geom_conaffinity[g1])
    no_dofs = (model.body_dofnum[w1] == 0) & (model.body_dofnum[w2] == 0)
    filterparent = not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
    parent_child = filterparent & (w1 != 0) & (w2 != 0) & ((w1 == p2) | (w2 == p1))
    b1, b2 = model.geom_bodyid[g1], model.geom_bodyid[g2]
    excluded = np.isin((b1 << 16) + b2, model.exclude_signature)
    keep = (bits != 0) & (w1 != w2) & ~no_dofs & ~parent_child & ~excluded
    pairs = {(int(a), int(b)) for a, b in zip(g1[keep], g2[keep])}
    pairs |= {tuple(sorted((int(a), int(b)))) for a, b in zip(model.pair_geom1, model.pair_geom2)}
    return np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)


__all__ = ["candidate_geom_pairs", "restrict_box_colliders"]
