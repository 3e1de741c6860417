"""State records the prim API returns (Isaac's ``isaacsim.core.utils.types``).

Plain containers, as in Isaac: single prims fill the singular fields with arrays of one
prim (``position`` (3,)), views the plural ones with one row per prim (``positions``
(K, 3)). Lengths and linear velocities are in stage units (``World.stage_units_in_meters``),
quaternions (w, x, y, z), angular velocities rad/s, revolute joints rad, prismatic joints
stage units.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class XFormPrimState:
    """Pose of one prim: ``position`` (3,), ``orientation`` (4,) w x y z, world frame."""

    position: object
    orientation: object


@dataclass
class XFormPrimViewState:
    """Poses of K prims: ``positions`` (K, 3), ``orientations`` (K, 4), world frame."""

    positions: object
    orientations: object


@dataclass
class DynamicState:
    """Pose and velocities of one rigid body: (3,), (4,), (3,) stage units/s, (3,) rad/s."""

    position: object
    orientation: object
    linear_velocity: object
    angular_velocity: object


@dataclass
class DynamicsViewState:
    """Poses and velocities of K rigid bodies, one row each."""

    positions: object
    orientations: object
    linear_velocities: object
    angular_velocities: object


@dataclass
class JointsState:
    """Joint ``positions``, ``velocities`` (and ``efforts``, None where not reported), in
    ``dof_names`` order: (num_dof,) for one articulation, (K, num_dof) for a view."""

    positions: object
    velocities: object
    efforts: object = None


__all__ = ["DynamicState", "DynamicsViewState", "JointsState", "XFormPrimState", "XFormPrimViewState"]
