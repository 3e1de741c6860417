"""Exact geom geometry: normals of curved shapes against ray-traced ones, tight extents in a body frame."""

import math

import mujoco
import numpy as np

from ambulo.engine import CpuEngine
from ambulo.sensors import Camera
from ambulo.sensors.geom_shapes import geom_extents_b
from ambulo.utils.rotations import mat_to_quat

G = mujoco.mjtGeom


def rot(axis, deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


SHAPES = {  # name: (type, size, position (world), rotation (world))
    "sphere": (G.mjGEOM_SPHERE, [0.3, 0, 0], [0.0, 0.0, 0.3], rot(2, 0)),
    "ellipsoid": (G.mjGEOM_ELLIPSOID, [0.3, 0.2, 0.15], [1.0, 0.0, 0.3], rot(2, 30)),
    "cylinder": (G.mjGEOM_CYLINDER, [0.2, 0.3, 0], [-1.0, 0.0, 0.2], rot(1, 90) @ rot(0, 20)),
    "capsule": (G.mjGEOM_CAPSULE, [0.2, 0.35, 0], [0.9, 0.6, 0.5], rot(0, 60)),
}


def ray_hit_local(o, d, kind, size):
    """Nearest hit (t, normal) of rays o + t d (local frame, (N, 3)) with a shape at the origin."""
    t_best, n_best = np.full(len(o), np.inf), np.zeros_like(o)

    def keep(t, n, ok):
        better = ok & (t > 0) & (t < t_best)
        t_best[better], n_best[better] = t[better], n[better]

    def quadric(o_s, d_s):  # nearest root of |o_s + t d_s| = 1
        a, b, c = (d_s * d_s).sum(1), 2 * (o_s * d_s).sum(1), (o_s * o_s).sum(1) - 1
        disc = b * b - 4 * a * c
        return (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), disc > 0

    if kind in (G.mjGEOM_SPHERE, G.mjGEOM_ELLIPSOID):
        axes = np.array(size) if kind == G.mjGEOM_ELLIPSOID else np.full(3, size[0])
        t, ok = quadric(o / axes, d / axes)
        p = o + t[:, None] * d
        keep(t, p / axes ** 2, ok)
    else:
        r, h = size[0], size[1]
        t, ok = quadric(o[:, :2] / r, d[:, :2] / r)  # the side: x^2 + y^2 = r^2 within |z| <= h
        p = o + t[:, None] * d
        keep(t, p * [1, 1, 0], ok & (np.abs(p[:, 2]) <= h))
        for end in (-h, h):
            if kind == G.mjGEOM_CYLINDER:  # flat caps
                t = (end - o[:, 2]) / d[:, 2]
                p = o + t[:, None] * d
                keep(t, np.tile([0, 0, np.sign(end)], (len(o), 1)), np.hypot(p[:, 0], p[:, 1]) <= r)
            else:  # hemispheres
                centre = np.array([0, 0, end])
                t, ok = quadric((o - centre) / r, d / r)
                p = o + t[:, None] * d
                keep(t, p - centre, ok & (np.sign(p[:, 2] - end) == np.sign(end)))
    return t_best, n_best / np.linalg.norm(n_best, axis=1, keepdims=True).clip(1e-12)


def test_normals_of_curved_shapes_are_the_ray_traced_ones():
    spec = mujoco.MjSpec()
    # MuJoCo draws curved shapes as polygons; fine ones keep the drawn depth on the true surface
    spec.visual.quality.numslices, spec.visual.quality.numstacks = 400, 200
    spec.worldbody.add_light(pos=[0, 0, 6], dir=[0, 0, -1])
    for name, (kind, size, pos, r) in SHAPES.items():
        spec.worldbody.add_body(name=name, pos=pos, quat=mat_to_quat(r)).add_geom(type=kind, size=size)
    camera = Camera(prim_path="/World/camera", annotators=("depth", "normals"), width=320, height=240)
    camera.build(spec)
    model = spec.compile()
    engine = CpuEngine(model, 1, num_threads=1)
    camera.initialize(engine)
    camera.set_camera_view(eye=[0.3, -3.5, 2.2], target=[0.0, 0.3, 0.3])
    frame = camera.capture(0)
    k, t_cw = camera.get_intrinsics_matrix(), camera.get_extrinsics_matrix()[0]
    u, v = np.meshgrid(np.arange(320), np.arange(240))
    rays_w = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones(u.shape)], -1) @ t_cw[:3, :3]
    eye = -t_cw[:3, :3].T @ t_cw[:3, 3]
    for name, (kind, size, pos, r) in SHAPES.items():
        on = frame["geom_ids"] == model.geom(model.body(name).geomadr[0]).id
        d_local = rays_w[on] @ r  # R^T d: the ray in the shape's frame
        t, n_local = ray_hit_local(np.tile(r.T @ (eye - pos), (on.sum(), 1)), d_local, kind, size)
        facing = np.abs((n_local * d_local).sum(1)) / np.linalg.norm(d_local, axis=1) > 0.25  # not grazing
        assert np.isfinite(t).all() and facing.sum() > 0.5 * on.sum() > 100, (name, facing.sum(), on.sum())
        assert np.abs(frame["depth"][on][facing] - t[facing]).max() < 2e-3, name  # the same surface point
        error = np.abs(frame["normals"][on][facing] - n_local[facing] @ r.T).max()
        assert error < 5e-3, (name, error)


def test_extents_are_tight_for_shapes_turned_in_their_body():
    spec = mujoco.MjSpec()
    spec.add_mesh(name="tetra", uservert=[0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1])
    body = spec.worldbody.add_body(name="b")
    q = mat_to_quat(rot(2, 45))
    body.add_geom(type=G.mjGEOM_SPHERE, size=[0.3, 0, 0], quat=q)
    body.add_geom(type=G.mjGEOM_BOX, size=[0.3, 0.1, 0.2], quat=mat_to_quat(rot(2, 30)))
    body.add_geom(type=G.mjGEOM_CYLINDER, size=[0.2, 0.3, 0], quat=mat_to_quat(rot(1, 90)))
    body.add_geom(type=G.mjGEOM_CAPSULE, size=[0.1, 0.25, 0], quat=mat_to_quat(rot(1, 90)))
    body.add_geom(type=G.mjGEOM_ELLIPSOID, size=[0.3, 0.2, 0.1], quat=mat_to_quat(rot(2, 90)))
    body.add_geom(type=G.mjGEOM_MESH, meshname="tetra", pos=[1, 0, 0])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geoms = np.arange(model.ngeom)
    lo, hi = geom_extents_b(geoms, model, data.geom_xpos[geoms], data.geom_xmat.reshape(-1, 3, 3))
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    expected_half = [
        [0.3, 0.3, 0.3],  # a turned sphere is still r (its turned AABB would reach r sqrt 2)
        [0.3 * c + 0.1 * s, 0.3 * s + 0.1 * c, 0.2],
        [0.3, 0.2, 0.2],  # a cylinder lying along x: half length along x, radius across
        [0.35, 0.1, 0.1],  # a capsule along x: half length plus the radius
        [0.2, 0.3, 0.1],  # an ellipsoid turned 90 degrees about z swaps x and y
    ]
    assert np.allclose((hi - lo)[:5] / 2, expected_half, atol=1e-9)
    assert np.allclose((hi + lo)[:5] / 2, 0, atol=1e-9)
    # the tetrahedron's own vertices, wherever MuJoCo put its frame: (1, 0, 0) .. (2, 1, 1)
    assert np.allclose(lo[5], [1, 0, 0], atol=1e-6) and np.allclose(hi[5], [2, 1, 1], atol=1e-6)  # float32 verts


def test_mesh_normals_come_from_depth_differences_on_the_same_mesh():
    spec = mujoco.MjSpec()
    spec.worldbody.add_light(pos=[0, 0, 6], dir=[0, 0, -1])
    spec.worldbody.add_geom(type=G.mjGEOM_PLANE, size=[5, 5, 0.1])
    cube = [[x, y, z] for x in (-0.3, 0.3) for y in (-0.3, 0.3) for z in (0.0, 0.6)]
    spec.add_mesh(name="cube", uservert=np.ravel(cube).tolist())
    spec.worldbody.add_body(name="m", quat=mat_to_quat(rot(2, 25))).add_geom(type=G.mjGEOM_MESH, meshname="cube")
    camera = Camera(prim_path="/World/camera", annotators=("depth", "normals"), width=320, height=240)
    camera.build(spec)
    model = spec.compile()
    camera.initialize(CpuEngine(model, 1, num_threads=1))
    camera.set_camera_view(eye=[0.5, -3.0, 2.0], target=[0.0, 0.0, 0.3])
    frame = camera.capture(0)
    on = frame["geom_ids"] == 1
    faces = np.vstack([np.eye(3), -np.eye(3)]) @ rot(2, 25).T  # the cube's six face normals in the world
    nearest = np.abs(frame["normals"][on][:, None] - faces[None]).max(-1).min(1)
    assert on.sum() > 2000 and np.mean(nearest < 1e-2) > 0.9  # 94%: pixels on a crease mix its two faces
    assert np.allclose(np.linalg.norm(frame["normals"][on], axis=1), 1, atol=1e-5)
