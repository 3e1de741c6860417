"""ArticulationAction(s): joint targets for an Articulation or a view (Isaac's ``utils.types``)."""

from __future__ import annotations

from dataclasses import dataclass


def _tolist(value):
    return value.tolist() if hasattr(value, "tolist") else value


@dataclass
class ArticulationAction:
    """Targets for some or all joints of one articulation; None leaves that quantity uncommanded.

    ``joint_indices`` selects the joints the arrays refer to (default: all, in
    ``dof_names`` order). Inside a list, None leaves that one joint uncommanded;
    NaN or inf is an error. Units: revolute rad, rad/s, N m; prismatic stage units,
    stage units/s, N.
    """

    joint_positions: object = None
    joint_velocities: object = None
    joint_efforts: object = None
    joint_indices: object = None

    def get_dof_action(self, index: int) -> dict:
        """The command of entry ``index``: ``{"effort": e}`` if an effort is given (efforts
        override targets, as in Isaac), else ``{"velocity": v, "position": p}`` (given ones)."""
        if self.joint_efforts is not None and self.joint_efforts[index] is not None:
            return {"effort": self.joint_efforts[index]}
        action = {}
        if self.joint_velocities is not None and self.joint_velocities[index] is not None:
            action["velocity"] = self.joint_velocities[index]
        if self.joint_positions is not None and self.joint_positions[index] is not None:
            action["position"] = self.joint_positions[index]
        return action

    def get_dict(self) -> dict:
        """``{"joint_positions": list | None, "joint_velocities": ..., "joint_efforts": ...}``."""
        return {"joint_positions": _tolist(self.joint_positions), "joint_velocities": _tolist(self.joint_velocities),
                "joint_efforts": _tolist(self.joint_efforts)}

    def get_length(self) -> int | None:
        """The longest of the given arrays (joints commanded), or None when none is given."""
        sizes = [len(v) for v in (self.joint_positions, self.joint_velocities, self.joint_efforts) if v is not None]
        return max(sizes) if sizes else None

    def __str__(self) -> str:
        return str(self.get_dict())


@dataclass
class ArticulationActions:
    """Targets for the K articulations of a view: arrays of shape (M, J) for the M prims of
    ``apply_action(indices=...)`` (default all K) and the J joints of ``joint_indices``."""

    joint_positions: object = None
    joint_velocities: object = None
    joint_efforts: object = None
    joint_indices: object = None


__all__ = ["ArticulationAction", "ArticulationActions"]
