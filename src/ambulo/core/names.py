"""EntityNames: one entity's bodies, joints, sites and geoms in a compiled model, by name.

The model-only half of ``Entity``: ``Entity`` (the batched state view over an engine) and code
that works on a bare ``MjModel``/``MjData`` (the walking controller's IK and stabilizer) resolve
a prim path and name patterns the same way, so neither relies on the robot being body 1 or on
unprefixed names. Names are relative to the prim path (``pelvis`` for ``/World/robot/pelvis``);
patterns are full-match regexes (``".*_knee"``).
"""

from __future__ import annotations

import re

import mujoco
import numpy as np

from .paths import resolve_body, subtree_body_ids

_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
DOF_JOINT_TYPES = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
"""The joint types with one degree of freedom (hinge, slide): the joints an entity reads and drives."""


def find_names(names, pool: list[str], kind: str, kinds: str, owner: str) -> list[int]:
    """Indices into ``pool`` of ``names`` (each an exact name or a full-match regex), in the order
    given; a KeyError naming the ``kind`` of element, its ``owner`` and the pool for a name
    matching nothing."""
    out = []
    for name in [names] if isinstance(names, str) else names:
        if name in pool:
            out.append(pool.index(name))
            continue
        try:
            matched = [i for i, have in enumerate(pool) if re.fullmatch(name, have)]
        except re.error:
            matched = []
        if not matched:
            raise KeyError(f"unknown {kind} {name!r} of {owner}; {kinds}: {pool}")
        out.extend(i for i in matched if i not in out)
    return out


class EntityNames:
    """The elements of the entity at ``prim_path`` in ``model`` (see the module docstring).

    Attributes:
      root_body_id: model id of the entity's root body.
      body_ids: (B,) int64 model ids of its bodies, in model order; ``body_names`` alike.
      joint_ids: (J,) int64 model ids of its hinge/slide joints, in model order; ``joint_names``.
      is_floating: whether the root body has a free joint.
      free_qpos_adr, free_dof_adr: ``qpos``/``qvel`` address of that free joint (None if none):
        position (3) m then orientation (4, wxyz); linear (3) m/s world frame then angular
        (3) rad/s body frame.
    """

    def __init__(self, model: mujoco.MjModel, prim_path: str):
        self.model = model
        self.prim_path = prim_path.rstrip("/")
        self._prefix = self.prim_path + "/"
        self.root_body_id = resolve_body(model, self.prim_path)
        bodies = subtree_body_ids(model, self.prim_path) or [self.root_body_id]
        self.body_ids = np.asarray(bodies, dtype=np.int64)
        self.body_names = [model.body(b).name.removeprefix(self._prefix) for b in bodies]
        body_set = set(bodies)
        joints = [j for j in range(model.njnt)
                  if int(model.jnt_bodyid[j]) in body_set and int(model.jnt_type[j]) in DOF_JOINT_TYPES]
        self.joint_ids = np.asarray(joints, dtype=np.int64)
        self.joint_names = [model.joint(j).name.removeprefix(self._prefix) for j in joints]
        jnt = int(model.body_jntadr[self.root_body_id])
        self.is_floating = bool(model.body_jntnum[self.root_body_id] >= 1 and model.jnt_type[jnt] == _FREE)
        self.free_qpos_adr = int(model.jnt_qposadr[jnt]) if self.is_floating else None
        self.free_dof_adr = int(model.jnt_dofadr[jnt]) if self.is_floating else None

    def find_joints(self, names) -> list[int]:
        """Indices (into ``joint_names``) of joints by name or full-match regex, in the order given."""
        return find_names(names, self.joint_names, "joint", "joints", self.prim_path)

    def find_bodies(self, names) -> list[int]:
        """Indices (into ``body_names``) of bodies by name or full-match regex, in the order given."""
        return find_names(names, self.body_names, "body", "bodies", self.prim_path)

    def joint_model_ids(self, names) -> np.ndarray:
        """Model ids of the joints ``names`` (as ``find_joints``)."""
        return self.joint_ids[self.find_joints(names)]

    def body_model_ids(self, names) -> np.ndarray:
        """Model ids of the bodies ``names`` (as ``find_bodies``)."""
        return self.body_ids[self.find_bodies(names)]

    def body_id(self, name: str) -> int:
        """Model id of the body ``name`` (exact, relative to the prim path)."""
        return self._element(mujoco.mjtObj.mjOBJ_BODY, "body", name)

    def site_id(self, name: str) -> int:
        """Model id of the site ``name`` (exact, relative to the prim path)."""
        return self._element(mujoco.mjtObj.mjOBJ_SITE, "site", name)

    def geom_id(self, name: str) -> int:
        """Model id of the geom ``name`` (exact, relative to the prim path)."""
        return self._element(mujoco.mjtObj.mjOBJ_GEOM, "geom", name)

    def geom_ids(self, body: str) -> np.ndarray:
        """Model ids of the geoms attached to the body ``body``."""
        return np.flatnonzero(self.model.geom_bodyid == self.body_id(body))

    def _element(self, kind, what: str, name: str) -> int:
        index = mujoco.mj_name2id(self.model, kind, self._prefix + name)
        if index < 0:
            raise KeyError(f"{self.prim_path} has no {what} {name!r} (looked for {self._prefix + name!r})")
        return int(index)


__all__ = ["EntityNames", "find_names"]
