"""ArticulationAction: joint targets for an Articulation (Isaac's ``ArticulationAction``)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class ArticulationAction:
    """Targets for some or all joints; None leaves that quantity uncommanded.

    ``joint_indices`` selects the joints the arrays refer to (default: all, in
    ``dof_names`` order). Inside a list, None leaves that one joint uncommanded;
    NaN or inf is an error.
    """

    joint_positions: object = None
    joint_velocities: object = None
    joint_efforts: object = None
    joint_indices: object = None


__all__ = ["ArticulationAction"]
