"""Replicator's torus and cone: silhouettes, boxes and masks that match their geometry, per-frame
torus scale, and one-line refusals where MuJoCo cannot follow (examples/isaac/replicator_shapes.py)."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from ambulo.isaac import IsaacNameError, run_script
from basic_writer_files import load, project

SHAPES = Path(__file__).resolve().parents[2] / "examples" / "isaac" / "replicator_shapes.py"
FRAMES, SIZE = 3, (240, 180)
TORUS, CONE = "/Replicator/Torus_Xform", "/Replicator/Cone_Xform"


@pytest.fixture(scope="module")
def shapes(tmp_path_factory):
    out = tmp_path_factory.mktemp("shapes")
    run_script(SHAPES, ["--output_dir", str(out), "--num_frames", str(FRAMES), "--resolution", *map(str, SIZE)])
    return out




def rows(out: Path, stem: str, frame: int) -> dict:
    return dict(zip(load(out, f"{stem}_prim_paths", frame, "json"), load(out, stem, frame, "npy")))




def to_world(points_local: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """Prim-frame points (P, 3) -> world through a row-vector 4x4 local-to-world transform."""
    return np.c_[points_local, np.ones(len(points_local))] @ transform.astype(float) @ np.eye(4, 3)


def torus_surface(scale: float) -> np.ndarray:
    """(P, 3) points of the smooth torus (ring 0.5 m, tube 0.25 m, axis z) at ``scale``."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 360), np.linspace(0, 2 * np.pi, 90))
    rho = 0.5 + 0.25 * np.cos(v)
    return scale * np.c_[(rho * np.cos(u)).ravel(), (rho * np.sin(u)).ravel(), (0.25 * np.sin(v)).ravel()]


def test_torus_tight_box_is_its_projected_silhouette_at_each_frames_scale(shapes):
    scales = []
    for i in range(FRAMES):
        box3 = rows(shapes, "bounding_box_3d", i)[TORUS]
        scale = float(box3["x_max"]) / 0.75  # 3D box: 1.5 m x 1.5 m x 0.5 m at scale 1
        assert np.allclose([box3["x_min"], box3["y_max"], box3["z_max"]], [-0.75 * scale, 0.75 * scale,
                                                                           0.25 * scale], atol=1e-4)
        scales.append(scale)
        tight = rows(shapes, "bounding_box_2d_tight", i)[TORUS]
        assert tight["occlusionRatio"] < 0.01
        uv = project(to_world(torus_surface(scale), box3["transform"]), load(shapes, "camera_params", i, "json"))
        assert (uv.min(0) > 0).all() and (uv.max(0) < np.array(SIZE) - 1).all()
        # pixels whose centres the silhouette covers: ceil(min) to floor(max); a thin tip may miss
        # the next pixel centre, and the rendered capsules are tessellated: up to 1.5 px inside
        lo, hi = np.array([tight["x_min"], tight["y_min"]]), np.array([tight["x_max"], tight["y_max"]])
        assert (lo >= uv.min(0) - 0.5).all() and (lo <= uv.min(0) + 1.5).all()
        assert (hi <= uv.max(0) + 0.5).all() and (hi >= uv.max(0) - 1.5).all()
    assert all(0.5 <= s <= 1.2 for s in scales) and np.ptp(scales) > 0.05  # a new scale every frame


def test_cone_mask_area_is_its_projected_silhouette(shapes):
    from PIL import Image

    angles = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    # scale (1, 1, 1.5): base radius 0.5 m at z = -0.75, apex at z = +0.75
    surface = np.vstack([np.c_[0.5 * np.cos(angles), 0.5 * np.sin(angles), np.full(720, -0.75)], [[0, 0, 0.75]]])
    checked = 0
    for i in range(FRAMES):
        boxes3 = rows(shapes, "bounding_box_3d", i)
        tight = rows(shapes, "bounding_box_2d_tight", i)
        if CONE not in tight or tight[CONE]["occlusionRatio"] > 0:
            continue
        box3 = boxes3[CONE]
        assert np.allclose([box3["x_min"], box3["y_min"], box3["z_min"], box3["x_max"], box3["y_max"],
                            box3["z_max"]], [-0.5, -0.5, -0.75, 0.5, 0.5, 0.75], atol=1e-5)
        uv = project(to_world(surface, box3["transform"]), load(shapes, "camera_params", i, "json"))
        if not ((uv.min(0) > 0).all() and (uv.max(0) < np.array(SIZE) - 1).all()):
            continue
        hull = ConvexHull(uv)  # a cone's silhouette is the convex hull of its base circle and apex
        grid = np.stack(np.meshgrid(np.arange(SIZE[0]), np.arange(SIZE[1])), -1).reshape(-1, 2)
        inside = (grid @ hull.equations[:, :2].T + hull.equations[:, 2] <= 0).all(1)
        seg = np.array(Image.open(shapes / f"semantic_segmentation_{i:04d}.png"))[..., :4]
        colour = next(k for k, v in load(shapes, "semantic_segmentation_labels", i, "json").items()
                      if v["class"] == "cone")
        mask = (seg == np.array(colour.strip("()").split(", "), int)).all(-1)
        assert abs(mask.sum() - inside.sum()) <= 0.04 * inside.sum()
        assert (mask.reshape(-1) & inside).sum() >= 0.95 * inside.sum()  # the same pixels, not just as many
        checked += 1
    assert checked >= 1


def write_script(tmp_path: Path, body: str) -> Path:
    script = tmp_path / "script.py"
    script.write_text("import omni.replicator.core as rep\n"
                      "cam = rep.create.camera(position=(0, -5, 3), look_at=(0, 0, 0))\n" + body)
    return script


def test_a_cone_refuses_a_per_frame_or_drawn_scale_in_one_line(tmp_path):
    for line in ("cone = rep.create.cone()\nwith rep.trigger.on_frame(num_frames=2):\n"
                 "    with cone:\n        rep.modify.pose(scale=rep.distribution.uniform(0.5, 2))\n",
                 "rep.create.cone(scale=rep.distribution.uniform(0.5, 2))\n"):
        with pytest.raises(IsaacNameError, match=r"cone.*mesh.*rep.create.cone\(scale=") as err:
            run_script(write_script(tmp_path, line))
        assert "\n" not in str(err.value)


def test_a_torus_refuses_a_non_uniform_scale(tmp_path):
    for line in ("rep.create.torus(scale=(1, 1, 0.5))\n",
                 "t = rep.create.torus()\nwith t:\n    rep.modify.pose(scale=rep.distribution.uniform((1, 1, 1), (2, 2, 2)))\n"):
        with pytest.raises(ValueError, match="torus takes one scale"):
            run_script(write_script(tmp_path, line))


@pytest.mark.parametrize("where", ["inside", "outside"])
def test_a_shape_created_in_a_trigger_draws_its_pose_every_frame(tmp_path, where):
    create = "rep.create.torus(semantics=[('class', 'torus')], position=rep.distribution.uniform((-1, -1, 0), (1, 1, 0)))"
    body = ("rp = rep.create.render_product(cam, (16, 16))\n"
            + (f"{create}\n" if where == "outside" else "")
            + "with rep.trigger.on_frame(num_frames=3):\n"
            + (f"    {create}\n" if where == "inside" else "    pass\n")
            + "w = rep.WriterRegistry.get('BasicWriter')\n"
            "import sys\nw.initialize(output_dir=sys.argv[1], bounding_box_3d=True)\nw.attach([rp])\n"
            "rep.orchestrator.run()\n")
    run_script(write_script(tmp_path, body), [str(tmp_path / "out")])
    centres = np.array([rows(tmp_path / "out", "bounding_box_3d", i)[TORUS]["transform"][3, :3] for i in range(3)])
    assert (np.abs(centres[:, :2]) <= 1).all() and np.allclose(centres[:, 2], 0)
    spread = np.ptp(centres[:, :2], axis=0).max()
    assert spread > 0.05 if where == "inside" else spread == 0  # created once, drawn every frame / once per run
