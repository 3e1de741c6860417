"""Replicator scripts run unchanged: BasicWriter's files, boxes where the shapes project, seeded frames."""

import json
from pathlib import Path

import numpy as np
import pytest

from ambulo.isaac import IsaacNameError, run_script
from basic_writer_files import load, project

ISAAC_EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "isaac"
BASICS = ISAAC_EXAMPLES / "replicator_basics.py"
FRAMES, SIZE = 3, (96, 72)
SHAPES = {"/Replicator/Cube_Xform": "cube", "/Replicator/Sphere_Xform": "sphere",
          "/Replicator/Cylinder_Xform": "cylinder", "/Replicator/Plane_Xform": "table"}


def run_basics(out: Path, seed: int, frames: int = FRAMES) -> Path:
    run_script(BASICS, ["--output_dir", str(out), "--num_frames", str(frames), "--seed", str(seed),
                        "--resolution", *map(str, SIZE)])
    return out


def tree(root: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(root.iterdir())}


@pytest.fixture(scope="module")
def basics(tmp_path_factory):
    return run_basics(tmp_path_factory.mktemp("basics"), seed=7)






def test_frames_are_written_in_basicwriter_layout(basics):
    stems = ["rgb", "bounding_box_2d_tight", "bounding_box_2d_tight_labels", "bounding_box_2d_tight_prim_paths",
             "semantic_segmentation", "semantic_segmentation_labels", "bounding_box_3d", "bounding_box_3d_labels",
             "bounding_box_3d_prim_paths", "camera_params"]
    ext = {"rgb": "png", "semantic_segmentation": "png", "bounding_box_2d_tight": "npy", "bounding_box_3d": "npy"}
    assert sorted(tree(basics)) == sorted(f"{s}_{i:04d}.{ext.get(s, 'json')}" for s in stems for i in range(FRAMES))
    from PIL import Image

    for i in range(FRAMES):
        rgb = np.array(Image.open(basics / f"rgb_{i:04d}.png"))
        assert rgb.shape == (SIZE[1], SIZE[0], 4) and (rgb[..., 3] == 255).all()
        boxes = load(basics, "bounding_box_2d_tight", i, "npy")
        assert boxes.dtype.names == ("semanticId", "x_min", "y_min", "x_max", "y_max", "occlusionRatio")
        labels = load(basics, "bounding_box_2d_tight_labels", i, "json")
        paths = load(basics, "bounding_box_2d_tight_prim_paths", i, "json")
        assert len(paths) == len(boxes) and set(paths) <= set(SHAPES)
        for row, path in zip(boxes, paths):
            assert labels[str(row["semanticId"])] == {"class": SHAPES[path]}
        # the colourised segmentation: its label map names each colour in the image
        seg = np.array(Image.open(basics / f"semantic_segmentation_{i:04d}.png"))
        seg_labels = load(basics, "semantic_segmentation_labels", i, "json")
        colours = {"(" + ", ".join(map(str, c)) + ")" for c in np.unique(seg.reshape(-1, 4), axis=0)}
        assert colours == set(seg_labels)
        assert {v["class"] for v in seg_labels.values()} >= {"BACKGROUND", "table"}


def test_boxes_match_where_the_shapes_project(basics):
    checked_centres = 0
    for i in range(FRAMES):
        params = load(basics, "camera_params", i, "json")
        tight = dict(zip(load(basics, "bounding_box_2d_tight_prim_paths", i, "json"),
                         load(basics, "bounding_box_2d_tight", i, "npy")))
        boxes_3d = dict(zip(load(basics, "bounding_box_3d_prim_paths", i, "json"),
                            load(basics, "bounding_box_3d", i, "npy")))
        for path in set(SHAPES) - {"/Replicator/Plane_Xform"}:
            if path not in tight:
                continue
            b3, b2 = boxes_3d[path], tight[path]
            corners = np.array([[x, y, z] for x in (b3["x_min"], b3["x_max"]) for y in (b3["y_min"], b3["y_max"])
                                for z in (b3["z_min"], b3["z_max"])])
            uv = project(np.c_[corners, np.ones(8)] @ b3["transform"].astype(float) @ np.eye(4, 3), params)
            # the visible silhouette lies inside the projected 3D box
            assert b2["x_min"] >= uv[:, 0].min() - 1 and b2["x_max"] <= uv[:, 0].max() + 1
            assert b2["y_min"] >= uv[:, 1].min() - 1 and b2["y_max"] <= uv[:, 1].max() + 1
            if b2["occlusionRatio"] < 0.01 and (uv >= 0).all() and (uv[:, 0] < SIZE[0]).all() \
                    and (uv[:, 1] < SIZE[1]).all():
                # unoccluded and in the image: the projected box hugs the silhouette, centre included
                u, v = project(b3["transform"][3:, :3].astype(float), params)[0]
                assert b2["x_min"] <= u <= b2["x_max"] and b2["y_min"] <= v <= b2["y_max"]
                checked_centres += 1
                if path == "/Replicator/Cube_Xform":  # a box's silhouette is its projected corners
                    assert np.allclose([b2["x_min"], b2["y_min"]], uv.min(0), atol=1.5)
                    assert np.allclose([b2["x_max"], b2["y_max"]], uv.max(0), atol=1.5)
    assert checked_centres >= FRAMES


def test_poses_are_new_draws_every_frame_on_the_table(basics):
    for path in ("/Replicator/Cube_Xform", "/Replicator/Sphere_Xform", "/Replicator/Cylinder_Xform"):
        centres = []
        for i in range(FRAMES):
            rows = dict(zip(load(basics, "bounding_box_3d_prim_paths", i, "json"),
                            load(basics, "bounding_box_3d", i, "npy")))
            if path in rows:
                centres.append(rows[path]["transform"][3, :3])
        assert len(centres) >= 2
        centres = np.array(centres)
        assert np.allclose(centres[:, 2], 0.45, atol=1e-5)  # z drawn from uniform(0.45, 0.45)
        assert (np.abs(centres[:, :2]) <= 1.8 + 1e-5).all()
        assert min(np.linalg.norm(a - b) for k, a in enumerate(centres) for b in centres[k + 1:]) > 1e-3


def test_the_same_seed_writes_the_same_files_and_another_seed_does_not(basics, tmp_path):
    assert tree(run_basics(tmp_path / "again", seed=7)) == tree(basics)
    other = tree(run_basics(tmp_path / "other", seed=8, frames=1))
    assert other["rgb_0000.png"] != tree(basics)["rgb_0000.png"]


STEP_SCRIPT = """
import sys
from pathlib import Path
from isaacsim import SimulationApp
app = SimulationApp({"headless": True})
import omni.replicator.core as rep
out, mode = Path(sys.argv[1]), sys.argv[2]
rep.set_global_seed(7)
cam = rep.create.camera(position=(0, -6, 4), look_at=(0, 0, 0))
rp = rep.create.render_product(cam, (48, 36))
cubes = rep.create.cube(semantics=[("class", "cube")], scale=0.5, count=2)
with rep.trigger.on_frame(num_frames=2):
    with cubes:
        rep.modify.pose(position=rep.distribution.uniform((-1, -1, 0), (1, 1, 0)))
        rep.randomizer.color(colors=[(1, 0, 0), (0, 0, 1)])
writer = rep.WriterRegistry.get("BasicWriter")
writer.initialize(output_dir=str(out), rgb=True, instance_segmentation=True, colorize_instance_segmentation=False)
writer.attach(rp)
assert not out.exists(), "declaring the graph must not render"
if mode == "step":
    for _ in range(2):
        rep.orchestrator.step(rt_subframes=4)
else:
    rep.orchestrator.run()
app.close()
"""


def test_a_step_loop_writes_the_frames_run_writes(tmp_path):
    script = tmp_path / "steps.py"
    script.write_text(STEP_SCRIPT)
    run_script(script, [str(tmp_path / "step"), "step"])
    run_script(script, [str(tmp_path / "run"), "run"])
    stepped = tree(tmp_path / "step")
    assert sorted(stepped) == sorted(f"{s}_{i:04d}.{e}" for i in range(2) for s, e in (
        ("rgb", "png"), ("instance_segmentation", "png"), ("instance_segmentation_mapping", "json"),
        ("instance_segmentation_semantics_mapping", "json")))
    assert stepped == tree(tmp_path / "run")
    from PIL import Image

    for i in range(2):
        mapping = json.loads(stepped[f"instance_segmentation_mapping_{i:04d}.json"])
        assert set(mapping.values()) <= {"BACKGROUND", "/Replicator/Cube_Xform", "/Replicator/Cube_Xform_01"}
        ids = np.array(Image.open(tmp_path / "step" / f"instance_segmentation_{i:04d}.png"))
        rgb = np.array(Image.open(tmp_path / "step" / f"rgb_{i:04d}.png"))[..., :3].astype(float)
        cubes = [int(k) for k, v in mapping.items() if v.startswith("/Replicator/Cube")]
        assert cubes
        for k in cubes:  # each cube drew red or blue from the colour list
            r, g, b = rgb[ids == k].mean(0)
            assert g < 0.2 * max(r, b) and (r > 3 * b or b > 3 * r)


def test_created_rotation_and_scale_reach_the_3d_boxes(tmp_path):
    script = tmp_path / "rotated.py"
    script.write_text(
        "import sys\nimport omni.replicator.core as rep\n"
        "cam = rep.create.camera(position=(0, -5, 3), look_at=(0, 0, 0))\n"
        "rep.create.cube(semantics=[('class', 'cube')], rotation=(0, 0, 30), scale=(0.4, 0.6, 0.8))\n"
        "w = rep.WriterRegistry.get('BasicWriter')\n"
        "w.initialize(output_dir=sys.argv[1], bounding_box_3d=True)\n"
        "w.attach([rep.create.render_product(cam, (32, 24))])\n"
        "rep.orchestrator.run(num_frames=1)\n")
    run_script(script, [str(tmp_path / "out")])
    (box,) = np.load(tmp_path / "out" / "bounding_box_3d_0000.npy")
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    # USD row-vector transform: row 0 is where the box's x axis points in the world
    assert np.allclose(box["transform"][:3, :3], [[c, s, 0], [-s, c, 0], [0, 0, 1]], atol=1e-5)
    assert np.allclose([box["x_max"], box["y_max"], box["z_max"]], [0.2, 0.3, 0.4], atol=1e-5)
    assert np.allclose([box["x_min"], box["y_min"], box["z_min"]], [-0.2, -0.3, -0.4], atol=1e-5)


@pytest.mark.parametrize(("line", "expected"), [
    ("rep.create.capsule()", "capsule.*cube, sphere, cylinder, cone, torus, disk and plane"),
    ("rep.trigger.on_time(interval=1)", "on_time.*on_frame"),
    ("rep.WriterRegistry.get('KittiWriter')", "KittiWriter.*BasicWriter"),
])
def test_unmapped_replicator_names_fail_in_one_line_with_the_alternative(tmp_path, line, expected):
    script = tmp_path / "bad.py"
    script.write_text(f"import omni.replicator.core as rep\n{line}\n")
    with pytest.raises(IsaacNameError, match=expected) as err:  # what `ambulo run` prints as one line
        run_script(script)
    assert "\n" not in str(err.value)


def test_synthetic_data_helper_boxes_and_depth_of_three_cubes(capsys):
    run_script(ISAAC_EXAMPLES / "synthetic_helper.py")
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == "rgb (192, 256, 4) labels {1: 'cube'}"
    boxes = [line for line in lines if line.startswith("/World/")]
    assert [b.split()[0] for b in boxes] == ["/World/left_cube", "/World/middle_cube", "/World/right_cube"]
    x_min = [int(b.split("box (")[1].split(",")[0]) for b in boxes]
    x_max = [int(b.split(")-(")[1].split(",")[0]) for b in boxes]
    # the viewport looks straight down +y at the middle cube: it is centred, the others mirror each other
    assert (x_min[1] + x_max[1]) / 2 == pytest.approx(127.5, abs=1.0)
    assert x_min[0] + x_max[2] == pytest.approx(255, abs=2) and x_max[0] + x_min[2] == pytest.approx(255, abs=2)
    # the front faces (y = -0.25) are 3.95 m from the eye (0, -4, 1.5) along the view axis to (0, 0, 0.25)
    axis = np.array([0.0, 4.0, -1.25]) / np.linalg.norm([0.0, 4.0, -1.25])
    expected = np.dot(np.array([0.0, -0.25, 0.25]) - [0.0, -4.0, 1.5], axis)
    for b in boxes:
        assert float(b.split("depth at centre ")[1].split(" m")[0]) == pytest.approx(expected, abs=0.05)
