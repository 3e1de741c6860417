"""PhysX's schema attributes (``physx*:``) on a USD stage, honoured where MuJoCo has a meaning.

Isaac stages carry PhysX settings that MuJoCo's UsdPhysics importer skips. ``apply_physx``
edits the imported spec for those with a MuJoCo counterpart (``HONOURED`` says how, and
``docs/isaac-compatibility.md`` shows the table); every other authored ``physx*:`` attribute
whose value differs from PhysX's fallback is named in one warning per stage. Lengths are in
stage units: they are scaled by the default prim's transform (where ambulo's World puts its
metres-per-unit scale), not by a shape's own scale, as PhysX's offsets are distances.
"""

from __future__ import annotations

import itertools
import math
import warnings

import mujoco
import numpy as np

from .physx_attrs import is_fallback

HONOURED: dict[str, str] = {
    "physxRigidBody:linearDamping":
        "a force -c m v at the centre of mass (3 site actuators), so v decays as exp(-c t)",
    "physxRigidBody:angularDamping":
        "a torque -c I w about the principal axes (3 site actuators): angular momentum decays as exp(-c t)",
    "physxRigidBody:disableGravity": "gravcomp = 1 on the body (MuJoCo cancels its weight)",
    "physxRigidBody:solverPositionIterationCount": "the largest count on the World's stage sets opt.iterations",
    "physxArticulation:solverPositionIterationCount": "as physxRigidBody:solverPositionIterationCount",
    "physxScene:minPositionIterationCount": "a lower bound on opt.iterations",
    "physxScene:maxPositionIterationCount": "an upper bound on opt.iterations",
    "physxScene:timeStepsPerSecond": "the World's physics_dt = 1 / timeStepsPerSecond",
    "physxArticulation:enabledSelfCollisions":
        "false: contacts between any two links of the articulation are excluded",
    "physxCollision:contactOffset": "geom gap = contactOffset - restOffset (contacts are found this far apart)",
    "physxCollision:restOffset": "geom margin (bodies rest this far apart)",
    "physxJoint:armature": "joint armature",
    "physxJoint:jointFriction":
        "joint frictionloss = mu m g, m the mass the joint carries (PhysX scales mu by the joint's load)",
    "physxMaterial:frictionCombineMode": "'max' only: MuJoCo takes the larger friction of two geoms",
}
"""Attribute -> how ambulo honours it in MuJoCo."""

_WORLD_LEVEL = {"physxRigidBody:solverPositionIterationCount", "physxArticulation:solverPositionIterationCount",
                "physxScene:minPositionIterationCount", "physxScene:maxPositionIterationCount",
                "physxScene:timeStepsPerSecond"}
"""Scene-wide settings: the World reads them from its own stage (``ambulo.sim.usd_stage``)."""

_DAMPING = ("physxRigidBody:linearDamping", "physxRigidBody:angularDamping")
_OFFSETS = ("physxCollision:contactOffset", "physxCollision:restOffset")


def authored_physx(prim) -> dict[str, object]:
    """The prim's ``physx*:`` attributes that have an authored value."""
    found = {}
    for attr in prim.GetAttributes():
        name = attr.GetName()
        if name.startswith("physx") and attr.HasAuthoredValue():
            found[name] = attr.Get()
    return found


def apply_physx(stage, spec: mujoco.MjSpec, model: mujoco.MjModel, relative, file_name: str) -> list[str]:
    """Edit ``spec`` (names relative, ``model`` compiled from it with the prim paths as names) for
    the PhysX attributes on ``stage``; warn once naming the ones ignored, and return them."""
    from pxr import UsdGeom

    root = stage.GetDefaultPrim()
    scale = _uniform_scale(UsdGeom.XformCache().GetLocalToWorldTransform(root)) if root else 1.0
    ignored: set[str] = set()
    for prim in stage.Traverse():
        authored = authored_physx(prim)
        if not authored:
            continue
        path = str(prim.GetPath())
        done = set(_WORLD_LEVEL)
        done |= _body(spec, model, path, relative(path), authored)
        done |= _offsets(spec, relative(path), authored, scale)
        done |= _joint(spec, model, path, relative(path), authored, scale)
        if authored.get("physxArticulation:enabledSelfCollisions") is False:
            _exclude_self_collisions(spec, relative(path))
            done.add("physxArticulation:enabledSelfCollisions")
        if authored.get("physxMaterial:frictionCombineMode") == "max":
            done.add("physxMaterial:frictionCombineMode")
        ignored |= {name for name, value in authored.items()
                    if name not in done and not is_fallback(name, value)}
    if ignored:
        warnings.warn(f"{file_name}: MuJoCo has no counterpart for these PhysX attributes, so they are ignored: "
                      f"{', '.join(sorted(ignored))} (docs/isaac-compatibility.md lists the honoured ones)",
                      stacklevel=4)
    return sorted(ignored)


def _uniform_scale(matrix) -> float:
    """The mean scale of a world transform (the ``toMetres`` scale ambulo's stages add)."""
    rows = np.asarray(matrix, dtype=float)[:3, :3]
    return float(np.mean(np.linalg.norm(rows, axis=1)))


def _body(spec, model, path: str, name: str, authored: dict) -> set[str]:
    body = spec.body(name)
    if body is None:
        return set()
    done = set()
    if authored.get("physxRigidBody:disableGravity") is True:
        body.gravcomp = 1.0
        done.add("physxRigidBody:disableGravity")
    rates = [float(authored.get(key) or 0.0) for key in _DAMPING]
    if any(rate < 0 or not math.isfinite(rate) for rate in rates):
        return done
    _add_damping(spec, model, path, name, *rates)
    return done | {key for key in _DAMPING if key in authored}


def _add_damping(spec, model, path: str, name: str, linear: float, angular: float) -> None:
    """PhysX damps a body as dv/dt = -c v (c in 1/s, whatever the mass). MuJoCo's damping lives
    on joints (a free joint has one coefficient for all six dofs, in N s/m and N m s/rad), so
    it cannot give a rate independent of mass and inertia. Instead three ``site`` actuators at
    the centre of mass, along the principal axes, push with the bias -k (gear . v): force
    -c m v and torque -c I w. Their velocity term is integrated implicitly by implicitfast,
    as PhysX's v / (1 + c dt) is, and ``ensure_drives`` leaves site actuators alone."""
    if linear == 0.0 and angular == 0.0:
        return
    body_id = model.body(path).id
    site = spec.body(name).add_site(name=f"{name}/physxRigidBody:damping", pos=model.body_ipos[body_id],
                                    quat=model.body_iquat[body_id], group=5)
    coefficients = [(linear, float(model.body_mass[body_id]))] * 3
    coefficients += [(angular, float(i)) for i in model.body_inertia[body_id]]
    for axis, (rate, inertia) in enumerate(coefficients):
        if rate == 0.0:
            continue
        kind = "linear" if axis < 3 else "angular"
        act = spec.add_actuator(name=f"{name}/physxRigidBody:{kind}Damping:{'xyz'[axis % 3]}",
                                target=site.name, trntype=mujoco.mjtTrn.mjTRN_SITE)
        gear = [0.0] * 6
        gear[axis] = 1.0
        act.gear = gear
        act.gaintype, act.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_AFFINE
        act.gainprm[0] = 0.0  # no control input: the force is the bias alone
        act.biasprm[:3] = [0.0, 0.0, -rate * inertia]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE


def _offsets(spec, name: str, authored: dict, scale: float) -> set[str]:
    """PhysX finds contacts ``contactOffset`` apart and pushes bodies apart closer than
    ``restOffset``; MuJoCo (4) finds contacts ``margin + gap`` apart and pushes closer than
    ``margin``. Both add the values of the two shapes in contact, so the mapping is exact."""
    present = [key for key in _OFFSETS if key in authored]
    geom = spec.geom(name)
    if not present or geom is None:
        return set(present)  # PhysX reads them on colliders only
    contact, rest = (float(v) * scale if v is not None and math.isfinite(v) else None
                     for v in (authored.get(key) for key in _OFFSETS))
    if (rest is not None and rest < 0) or (contact is not None and contact < 0):
        return set()  # a resting penetration has no MuJoCo counterpart
    rest = 0.0 if rest is None else rest  # PhysX's automatic rest offset of a rigid body
    detect = geom.margin + geom.gap if contact is None else contact
    geom.margin, geom.gap = rest, max(detect - rest, 0.0)
    return set(present)


def _joint(spec, model, path: str, name: str, authored: dict, scale: float) -> set[str]:
    keys = {"physxJoint:armature", "physxJoint:jointFriction"} & set(authored)
    joint = spec.joint(name)
    if not keys or joint is None:
        return keys  # a fixed joint has no dof to give them to
    angular = joint.type == mujoco.mjtJoint.mjJNT_HINGE
    armature = authored.get("physxJoint:armature")
    if armature is not None:
        joint.armature = float(armature) * (scale * scale if angular else 1.0)  # mass (distance^2)
    friction = authored.get("physxJoint:jointFriction")
    if friction:
        joint_id = model.joint(path).id
        carried = float(model.body_subtreemass[model.jnt_bodyid[joint_id]])
        joint.frictionloss = float(friction) * carried * float(np.linalg.norm(model.opt.gravity))
    return keys


def _exclude_self_collisions(spec, name: str) -> None:
    """Exclude contacts between every two bodies of the articulation rooted at ``name`` (its
    body's subtree, or the subtrees of the bodies under it when the root is an Xform)."""
    root = spec.body(name)
    tops = [root] if root is not None else [b for b in spec.bodies if b.name.startswith(name + "/")]
    links = {}
    for top in tops:
        for body in [top, *top.find_all(mujoco.mjtObj.mjOBJ_BODY)]:
            links[body.name] = body
    for first, second in itertools.combinations(sorted(links), 2):
        spec.add_exclude(bodyname1=first, bodyname2=second)


__all__ = ["HONOURED", "apply_physx", "authored_physx"]
