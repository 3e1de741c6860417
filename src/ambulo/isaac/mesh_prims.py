"""The meshes of Kit's ``CreateMeshPrimWithDefaultXform`` (``omni.kit.primitive.mesh``): Cube, Sphere,
Cylinder, Cone, Torus, Plane and Disk as ``UsdGeom.Mesh`` points and faces.

Kit's shapes have a half size of 50 cm by default (``half_scale``, centimetres), their axis
along the stage's up axis (z here) and their origin at the centre of their bounding box.
Kit tessellates curved shapes more finely; the extents are the same, and MuJoCo collides a
mesh by its convex hull.
"""

from __future__ import annotations

import math

import numpy as np

SEGMENTS = 32
"""Facets around a curved shape (Kit's default u_patches x u_verts_scale is 32 too)."""

DEFAULT_HALF_SCALE_CM = 50.0
"""Kit's ``/persistent/app/mesh_generator/half_scale`` default: a 1 m cube."""


def _ring(radius: float, z: float) -> np.ndarray:
    angles = np.linspace(0.0, 2.0 * math.pi, SEGMENTS, endpoint=False)
    return np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(SEGMENTS, z)], axis=1)


def _cube(h: float):
    corners = np.array([[x, y, z] for z in (-h, h) for y in (-h, h) for x in (-h, h)])
    faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return corners, faces


def _sphere(h: float, rings: int = SEGMENTS // 2):
    points = [[0.0, 0.0, -h]]
    for k in range(1, rings):
        polar = math.pi * k / rings
        points.extend(_ring(h * math.sin(polar), -h * math.cos(polar)))
    points.append([0.0, 0.0, h])
    n, top = SEGMENTS, 1 + (rings - 1) * SEGMENTS
    faces = [[0, 1 + (i + 1) % n, 1 + i] for i in range(n)]
    for k in range(rings - 2):
        a, b = 1 + k * n, 1 + (k + 1) * n
        faces.extend([a + i, a + (i + 1) % n, b + (i + 1) % n, b + i] for i in range(n))
    last = 1 + (rings - 2) * n
    faces.extend([last + i, last + (i + 1) % n, top] for i in range(n))
    return np.asarray(points), faces


def _cylinder(h: float, top_radius: float | None = None):
    n = SEGMENTS
    if top_radius == 0.0:  # a cone: apex on the axis
        points = np.vstack([_ring(h, -h), [[0.0, 0.0, h]]])
        faces = [[i, (i + 1) % n, n] for i in range(n)] + [list(range(n - 1, -1, -1))]
        return points, faces
    points = np.vstack([_ring(h, -h), _ring(h, h)])
    faces = [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    faces += [list(range(n - 1, -1, -1)), list(range(n, 2 * n))]
    return points, faces


def _torus(h: float):
    n, m = SEGMENTS, SEGMENTS // 2
    major, minor = h * 0.75, h * 0.25  # outer radius h, tube radius h / 4
    points = []
    for i in range(n):
        u = 2.0 * math.pi * i / n
        for j in range(m):
            v = 2.0 * math.pi * j / m
            r = major + minor * math.cos(v)
            points.append([r * math.cos(u), r * math.sin(u), minor * math.sin(v)])
    faces = [[i * m + j, ((i + 1) % n) * m + j, ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m]
             for i in range(n) for j in range(m)]
    return np.asarray(points), faces


def _plane(h: float):
    return np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]]), [[0, 1, 2, 3]]


def _disk(h: float):
    return _ring(h, 0.0), [list(range(SEGMENTS))]


SHAPES = {"Cube": _cube, "Sphere": _sphere, "Cylinder": _cylinder, "Cone": lambda h: _cylinder(h, 0.0),
          "Torus": _torus, "Plane": _plane, "Disk": _disk}
"""Kit's mesh prim types -> (points (P, 3), faces as lists of point indices, counter-clockwise seen from outside)."""


def define_mesh(stage, path: str, prim_type: str, half_scale_cm: float | None, origin) -> object:
    """Define the ``UsdGeom.Mesh`` of ``prim_type`` at ``path``, its half size ``half_scale_cm``
    centimetres in stage units, centred at ``origin`` (stage units), with Kit's default xform ops."""
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    if prim_type not in SHAPES:
        raise ValueError(f"CreateMeshPrimWithDefaultXform: no mesh type {prim_type!r}; Kit's are "
                         f"{', '.join(SHAPES)}")
    half = (half_scale_cm if half_scale_cm and half_scale_cm > 0 else DEFAULT_HALF_SCALE_CM)
    half *= 0.01 / UsdGeom.GetStageMetersPerUnit(stage)  # Kit's points are in centimetres, scaled to units
    points, faces = SHAPES[prim_type](half)
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.GetPointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in points]))
    mesh.GetFaceVertexCountsAttr().Set([len(f) for f in faces])
    mesh.GetFaceVertexIndicesAttr().Set([int(i) for f in faces for i in f])
    mesh.CreateSubdivisionSchemeAttr("none")
    mesh.GetExtentAttr().Set(UsdGeom.Boundable.ComputeExtentFromPlugins(mesh, Usd.TimeCode.Default()))
    prim = mesh.GetPrim()
    translate = Gf.Vec3d(*map(float, origin)) if origin is not None else Gf.Vec3d(0.0)
    prim.CreateAttribute("xformOp:translate", Sdf.ValueTypeNames.Double3, False).Set(translate)
    prim.CreateAttribute("xformOp:orient", Sdf.ValueTypeNames.Quatd, False).Set(Gf.Quatd(1.0))
    prim.CreateAttribute("xformOp:scale", Sdf.ValueTypeNames.Double3, False).Set(Gf.Vec3d(1.0))
    prim.CreateAttribute("xformOpOrder", Sdf.ValueTypeNames.TokenArray, False).Set(
        ["xformOp:translate", "xformOp:orient", "xformOp:scale"])
    return prim


__all__ = ["DEFAULT_HALF_SCALE_CM", "SHAPES", "define_mesh"]
