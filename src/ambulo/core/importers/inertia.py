"""Repair URDF inertias MuJoCo rejects, and say which links were changed.

CAD exporters and hand-written URDFs ship inertia tensors that are not positive definite
(TIAGo's antennas, Go1's dummy base: ``ixy = ixx``) and links without mass between the axes
of a multi-axis joint (the human model's hip). Pinocchio and ROS accept them; MuJoCo stops
with "inertia must have positive eigenvalues" or "mass and inertia of moving bodies must be
larger than mjMINVAL". ambulo changes the fewest numbers that make them valid and warns.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET

import numpy as np

_MJMINVAL = 1e-15
"""MuJoCo's smallest positive value (mjMINVAL); an eigenvalue at or below it is rejected."""
_AXES = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
BOUND_MASS_KG = 1e-3
"""Least mass of a link MuJoCo moves (compiler ``boundmass``): a gram, below any real link."""
BOUND_INERTIA_KG_M2 = 1e-7
"""Least principal inertia of such a link (``boundinertia``): a 1 g ball of 1 cm radius is
0.4 * 1e-3 * 1e-4 = 4e-8 kg m^2."""


def repair_inertias(robot: ET.Element, where) -> None:
    """Make each non-positive-definite inertia valid: raise its smallest principal moment to
    the least value that meets the triangle inequality (A + B >= C), keep the axes."""
    repaired = []
    for link in robot.findall("link"):
        inertia = link.find("inertial/inertia")
        if inertia is None:
            continue
        try:
            ixx, iyy, izz, ixy, ixz, iyz = (float(inertia.get(k, 0.0)) for k in _AXES)
        except ValueError:
            continue  # MuJoCo names the bad number with its line
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        moments, axes = np.linalg.eigh(tensor)  # ascending
        if moments[0] > _MJMINVAL:
            continue
        if moments[2] > _MJMINVAL:
            moments[0] = max(moments[0], moments[2] - moments[1], moments[2] * 1e-6)
            moments[1] = max(moments[1], moments[0])
        elif _mass_kg(link) > 0:  # a point mass: MuJoCo needs some inertia
            moments[:] = BOUND_INERTIA_KG_M2
        else:
            continue  # no mass, no inertia: left to bound_massless_links
        fixed = axes @ np.diag(moments) @ axes.T
        for key, (i, j) in zip(_AXES, ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))):
            inertia.set(key, repr(float(fixed[i, j])))
        repaired.append(f"{link.get('name')} (line {where.lines.get(link)})")
    if repaired:
        warnings.warn(
            f"{where.file.name}: {len(repaired)} links have an inertia that is not positive "
            f"definite; ambulo raised their smallest principal moment to make it valid: "
            f"{', '.join(repaired)}. Fix <inertia> in the URDF to silence this.", stacklevel=5)


def bound_massless_links(robot: ET.Element, compiler: ET.Element, where) -> None:
    """Give links lighter than ``BOUND_MASS_KG`` that mass (MuJoCo's ``boundmass``/``boundinertia``)."""
    light = []
    for link in robot.findall("link"):
        if _mass_kg(link) < BOUND_MASS_KG:
            light.append(f"{link.get('name')} (line {where.lines.get(link)})")
    compiler.set("boundmass", repr(BOUND_MASS_KG))
    compiler.set("boundinertia", repr(BOUND_INERTIA_KG_M2))
    warnings.warn(
        f"{where.file.name}: MuJoCo needs mass on every link a joint moves; ambulo gave "
        f"{len(light)} links lighter than {BOUND_MASS_KG * 1e3:g} g that mass: {', '.join(light)}. "
        "Give them an <inertial> to silence this.", stacklevel=5)


def _mass_kg(link: ET.Element) -> float:
    """The mass of a URDF link, 0 without one (an unreadable one: MuJoCo names it)."""
    mass = link.find("inertial/mass")
    try:
        return float(mass.get("value", 0.0)) if mass is not None else 0.0
    except ValueError:
        return 0.0
