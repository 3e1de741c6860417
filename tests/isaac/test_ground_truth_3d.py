"""3D ground truth in Isaac's layouts, checked against geometry worked out by hand: boxes against the
prims' sizes and poses, normals against known planes, motion vectors against known camera and
object moves (pixel motion = f * move / depth for a move parallel to the image plane)."""

import math
from pathlib import Path

import numpy as np
import pytest

from ambulo.isaac import IsaacNameError, run_script

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "isaac"
FOVY_DEG = 45.0  # MuJoCo's default visual/global fovy: the viewport camera's vertical field of view


def rot_z(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rot_x(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def corners_isaac_order(rot, pos, half):
    """World corners LDB, RDB, LUB, RUB, LDF, RDF, LUF, RUF of a box (x: L/R, y: D/U, z: B/F)."""
    local = [(x, y, z) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)]
    return np.array([rot @ (np.multiply(c, half)) + pos for c in local])


@pytest.fixture(scope="module")
def helper(tmp_path_factory):
    out = tmp_path_factory.mktemp("helper")
    run_script(EXAMPLES / "synthetic_helper_3d.py", ["--output_dir", str(out)])
    return [dict(np.load(out / f"frame_{i}.npz", allow_pickle=True)) for i in range(3)]


def test_helper_boxes_are_the_prims_extents_poses_and_corners(helper):
    boxes = {row["name"]: row for row in helper[0]["boxes"]}
    assert helper[0]["boxes"].dtype.names == (
        "uniqueId", "name", "semanticLabel", "metadata", "instanceIds", "semanticId", "x_min", "y_min", "z_min",
        "x_max", "y_max", "z_max", "transform", "corners")
    # the cube: edge 0.5 m, centre (0, 0, 0.25), turned 30 deg about z
    cube = boxes["/World/cube"]
    assert cube["semanticLabel"] == "cube"
    assert np.allclose([cube[k] for k in ("x_min", "y_min", "z_min", "x_max", "y_max", "z_max")],
                       [-0.25] * 3 + [0.25] * 3, atol=1e-6)
    # USD row vectors: row i of the transform is where the prim's axis i points in the world
    assert np.allclose(cube["transform"][:3, :3], rot_z(30).T, atol=1e-6)
    assert np.allclose(cube["transform"][3], [0, 0, 0.25, 1], atol=1e-6)
    assert np.allclose(cube["corners"], corners_isaac_order(rot_z(30), [0, 0, 0.25], [0.25] * 3), atol=1e-6)
    assert np.allclose(cube["corners"][0], [-0.25 * 0.8660254 + 0.25 * 0.5, -0.25 * 0.5 - 0.25 * 0.8660254, 0.0],
                       atol=1e-6)  # LDB by hand
    # the wall: 0.8 x 0.1 x 0.8 m at (1, 0.5, 0.5), tilted -30 deg about x
    wall = boxes["/World/wall"]
    assert np.allclose([wall[k] for k in ("x_max", "y_max", "z_max")], [0.4, 0.05, 0.4], atol=1e-6)
    assert np.allclose([wall[k] for k in ("x_min", "y_min", "z_min")], [-0.4, -0.05, -0.4], atol=1e-6)
    assert np.allclose(wall["transform"][:3, :3], rot_x(-30).T, atol=1e-6)
    assert np.allclose(wall["corners"], corners_isaac_order(rot_x(-30), [1, 0.5, 0.5], [0.4, 0.05, 0.4]), atol=1e-6)


def test_helper_normals_on_the_ground_the_tilted_wall_and_the_cube_faces(helper):
    frame = helper[0]
    normals, instances, depth = frame["normals"], frame["instances"], frame["depth"]
    assert normals.shape == depth.shape + (3,) and normals.dtype == np.float32
    ground = (instances == 0) & np.isfinite(depth)
    assert ground.sum() > 10000 and np.abs(normals[ground] - [0, 0, 1]).max() < 1e-5  # every ground pixel
    # the same normal in the camera's (OpenGL) axes, from the viewport's eye and target by hand
    eye, target = np.array([0.0, -3.5, 2.0]), np.array([0.0, 0.0, 0.3])
    back = (eye - target) / np.linalg.norm(eye - target)
    right = np.array([1.0, 0.0, 0.0])
    up = np.cross(back, right)
    expected_c = np.array([0.0, up[2], back[2]])  # (n . right, n . up, n . back) for n = +z
    assert np.allclose(expected_c, [0.0, 3.5 / math.hypot(3.5, 1.7), 1.7 / math.hypot(3.5, 1.7)])  # (0, .900, .437)
    assert np.allclose(frame["camera_pose"][:3, :3] @ [0, 0, 1], expected_c, atol=1e-5)
    # the wall's face toward the camera is its -y face, tilted back: (0, -cos 30, sin 30)
    boxes = {row["name"]: row for row in frame["boxes"]}
    wall = normals[instances == boxes["/World/wall"]["uniqueId"]]
    front = np.all(np.abs(wall - [0, -math.cos(math.radians(30)), 0.5]) < 1e-5, axis=1)
    assert front.mean() > 0.9
    faces = np.vstack([rot_x(-30).T, -rot_x(-30).T])  # the six face normals
    assert np.all(np.abs(wall[:, None] - faces[None]).max(-1).min(1) < 1e-5)  # none in between, even at edges
    # the cube shows its top and the two faces turned toward the camera, each exactly
    cube = normals[instances == boxes["/World/cube"]["uniqueId"]]
    seen = [[0, 0, 1], [math.sin(math.radians(30)), -math.cos(math.radians(30)), 0],
            [-math.cos(math.radians(30)), -math.sin(math.radians(30)), 0]]
    nearest = np.abs(cube[:, None] - np.array(seen)[None]).max(-1)
    assert nearest.min(1).max() < 1e-5 and all((nearest.argmin(1) == k).sum() > 200 for k in range(3))


def viewport_focal_px(height):
    return height / 2 / math.tan(math.radians(FOVY_DEG) / 2)


def test_helper_motion_vectors_when_the_viewport_moves_right(helper):
    assert np.all(helper[0]["motion"] == 0)  # nothing before the first frame
    frame = helper[1]
    motion, depth = frame["motion"], frame["depth"]
    assert motion.shape == depth.shape + (4,) and motion.dtype == np.float32
    f = viewport_focal_px(depth.shape[0])
    assert np.isclose(frame["intrinsics"][1, 1], f)
    # the camera moved 0.1 m along its own x: every point moved left by f * 0.1 / depth pixels
    seen = np.isfinite(depth)
    assert seen.all()
    assert np.allclose(motion[..., 0], f * 0.1 / depth, atol=1e-3)
    assert np.abs(motion[..., 1:]).max() < 1e-3


def test_helper_motion_vectors_when_the_cube_moves(helper):
    frame = helper[2]
    motion, depth, instances = frame["motion"], frame["depth"], frame["instances"]
    cube = instances == {row["name"]: row for row in frame["boxes"]}["/World/cube"]["uniqueId"]
    f = viewport_focal_px(depth.shape[0])
    # the cube moved 0.2 m along +x, the camera's right: its pixels moved right, the rest stayed
    assert cube.sum() > 1000
    assert np.allclose(motion[cube, 0], -f * 0.2 / depth[cube], atol=1e-3)
    assert np.abs(motion[cube, 1]).max() < 1e-3 and np.abs(motion[~cube]).max() < 1e-3


TOP_DOWN = """
import sys
import numpy as np
from isaacsim import SimulationApp
app = SimulationApp({"headless": True})
from omni.isaac.core import World
from omni.isaac.core.utils.viewports import set_camera_view
from omni.isaac.synthetic_utils import SyntheticDataHelper
from omni.kit.viewport.utility import get_active_viewport
world = World()
world.scene.add_default_ground_plane()
world.reset()
viewport = get_active_viewport()
viewport.set_texture_resolution((64, 48))
helper = SyntheticDataHelper()
helper.initialize(["depth", "motion-vector", "camera"], viewport)
set_camera_view(eye=np.array([0.0, 0.0, 2.0]), target=np.array([0.0, 0.0, 0.0]))
world.step(render=True)
first = helper.get_groundtruth(["camera"], viewport)
right = first["camera"]["pose"][0, :3]  # the camera's x axis in the world (USD row vectors)
set_camera_view(eye=np.array([0.0, 0.0, 2.0]) + 0.1 * right, target=0.1 * right)
world.step(render=True)
gt = helper.get_groundtruth(["depth", "motion-vector"], viewport)
np.savez(sys.argv[1], depth=gt["depth"], motion=gt["motion-vector"])
app.close()
"""


def test_motion_vectors_of_a_camera_moving_over_a_plane_at_known_depth(tmp_path):
    script = tmp_path / "top_down.py"
    script.write_text(TOP_DOWN)
    run_script(script, [str(tmp_path / "out.npz")])
    out = np.load(tmp_path / "out.npz")
    assert np.allclose(out["depth"], 2.0, atol=1e-4)  # the ground, 2 m below a camera looking straight down
    f = 24 / math.tan(math.radians(22.5))  # 57.94 px for 48 rows and 45 deg
    assert np.allclose(out["motion"][..., 0], f * 0.1 / 2.0, atol=1e-3)  # 2.897 px leftward, every pixel
    assert np.abs(out["motion"][..., 1:]).max() < 1e-3


OCCLUSION = """
import sys
import numpy as np
from isaacsim import SimulationApp
app = SimulationApp({"headless": True})
from omni.isaac.core import World
from omni.isaac.core.objects import VisualCuboid
from omni.isaac.core.utils.semantics import add_update_semantics
from omni.isaac.core.utils.viewports import set_camera_view
from omni.isaac.synthetic_utils import SyntheticDataHelper
from omni.kit.viewport.utility import get_active_viewport
world = World()
world.scene.add(VisualCuboid(prim_path="/World/tile", name="tile", position=np.array([0.0, 0.0, -0.01]),
                             scale=np.array([1.0, 1.0, 0.02])))
world.scene.add(VisualCuboid(prim_path="/World/box", name="box", position=np.array([0.0, 0.0, 0.25]),
                             scale=np.array([0.5, 0.5, 0.5])))
add_update_semantics("/World/tile", "tile")
add_update_semantics("/World/box", "box")
world.reset()
viewport = get_active_viewport()
viewport.set_texture_resolution((320, 240))
set_camera_view(eye=np.array([0.0, 0.0, 2.0]), target=np.array([0.0, 0.0, 0.0]))
world.step(render=True)
helper = SyntheticDataHelper()
rows = helper.get_groundtruth(["occlusion"], viewport)["occlusion"]
np.save(sys.argv[1], rows)
app.close()
"""


def test_helper_occlusion_of_a_tile_under_a_box_seen_from_above(tmp_path):
    script = tmp_path / "occlusion.py"
    script.write_text(OCCLUSION)
    run_script(script, [str(tmp_path / "rows.npy")])
    rows = np.load(tmp_path / "rows.npy")
    assert rows.dtype.names == ("instanceId", "semanticId", "occlusionRatio")
    ratio = dict(zip(rows["instanceId"].tolist(), rows["occlusionRatio"].tolist()))
    # straight down from 2 m: the 0.5 m box top (1.5 m away) hides a square of the 1 m tile (2 m away)
    # whose side in the image is f 0.5 / 1.5 against the tile's f 1 / 2: 0.25 (2 / 1.5)^2 = 0.444
    assert ratio[2] == pytest.approx(0.0, abs=1e-6)  # the box (instance 2: bodies in order)
    assert ratio[1] == pytest.approx(0.25 * (2.0 / 1.5) ** 2, abs=0.01)


@pytest.fixture(scope="module")
def replicator(tmp_path_factory):
    out = tmp_path_factory.mktemp("annotators")
    run_script(EXAMPLES / "replicator_annotators.py", ["--output_dir", str(out), "--num_frames", "4"])
    return [dict(np.load(out / f"frame_{i}.npz", allow_pickle=True)) for i in range(4)]


def test_replicator_bounding_box_3d_layout_and_geometry(replicator):
    for frame in replicator:
        rows = dict(zip(frame["paths"].tolist(), frame["boxes"]))
        assert frame["boxes"].dtype.names == ("semanticId", "x_min", "y_min", "z_min", "x_max", "y_max", "z_max",
                                             "transform", "occlusionRatio")
        cube, ramp, floor = (rows[f"/Replicator/{p}"] for p in ("Cube_Xform_01", "Cube_Xform", "Plane_Xform"))
        assert np.allclose([cube[k] for k in ("x_min", "y_min", "z_min", "x_max", "y_max", "z_max")],
                           [-0.25] * 3 + [0.25] * 3, atol=1e-6)
        assert np.allclose(cube["transform"][:3, :3], rot_z(30).T, atol=1e-6)
        assert np.isclose(abs(cube["transform"][3, 0]), 0.3) and np.allclose(cube["transform"][3, 1:], [0, 0.25, 1])
        assert np.allclose([ramp["x_max"], ramp["y_max"], ramp["z_max"]], [0.3, 0.3, 0.025], atol=1e-6)
        assert np.allclose(ramp["transform"][:3, :3], rot_x(25).T, atol=1e-6)
        assert np.allclose(ramp["transform"][3], [0.8, 0.6, 0.2, 1], atol=1e-6)
        # a plane's slab hangs below its prim: extents in the prim frame are uneven, as Isaac's
        assert np.allclose([floor["z_min"], floor["z_max"], floor["x_max"]], [-0.001, 0.0, 2.0], atol=1e-6)
        # the box's corners project around where the cube's pixels are
        corners = np.array([[x, y, z, 1] for x in (-.25, .25) for y in (-.25, .25) for z in (-.25, .25)])
        clip = corners @ cube["transform"] @ frame["view"] @ frame["projection"]
        width, height = frame["resolution"]
        u = (clip[:, 0] / clip[:, 3] + 1) / 2 * width - 0.5
        rows_px, cols_px = np.nonzero(frame["semantic"] == frame["classes"][2])
        assert cols_px.min() >= u.min() - 1 and cols_px.max() <= u.max() + 1


def test_replicator_normals_of_the_floor_and_the_ramp(replicator):
    frame = replicator[0]
    normals, semantic = frame["normals"], frame["semantic"]
    assert normals.shape == semantic.shape + (4,) and normals.dtype == np.float32
    floor, ramp = (semantic == c for c in frame["classes"][:2])
    assert np.abs(normals[floor, :3] - [0, 0, 1]).max() < 1e-5 and np.all(normals[..., 3] == 0)
    top = np.all(np.abs(normals[ramp, :3] - [0, -math.sin(math.radians(25)), math.cos(math.radians(25))]) < 1e-5, 1)
    assert top.mean() > 0.9  # the rest are the slab's 5 cm sides


def test_replicator_motion_vectors_follow_the_cube_between_frames(replicator):
    focal = replicator[0]["projection"][0, 0] * replicator[0]["resolution"][0] / 2  # P[0, 0] = 2 f / W
    assert np.all(replicator[0]["motion"] == 0)
    moves = 0
    for before, now in zip(replicator, replicator[1:]):
        rows = [dict(zip(frame["paths"].tolist(), frame["boxes"])) for frame in (before, now)]
        dx = rows[1]["/Replicator/Cube_Xform_01"]["transform"][3, 0] - rows[0]["/Replicator/Cube_Xform_01"]["transform"][3, 0]
        cube = now["semantic"] == now["classes"][2]
        top = cube & np.isclose(now["depth"], 2.5, atol=1e-3)  # the cube's top, 3 - 0.5 m below the camera
        # straight down, image x is world x: a move dx shows as -f dx / 2.5 px (x > 0 is leftward)
        assert np.allclose(now["motion"][top, 0], -focal * dx / 2.5, atol=1e-3)
        assert np.abs(now["motion"][top, 1]).max() < 1e-3 and np.abs(now["motion"][~cube]).max() < 1e-3
        moves += abs(dx) > 0.5
    assert moves >= 1  # at least one jump between -0.3 and +0.3 m under this seed


@pytest.mark.parametrize(("name", "expected"), [
    ("bounding_box_3d_360", "bounding_box_3d.*motion_vectors"),
    ("normal", "normals"),
])
def test_unprovided_annotators_fail_in_one_line_naming_the_ones_there_are(tmp_path, name, expected):
    script = tmp_path / "bad.py"
    script.write_text(f"import omni.replicator.core as rep\nrep.AnnotatorRegistry.get_annotator({name!r})\n")
    with pytest.raises(IsaacNameError, match=expected) as err:
        run_script(script)
    assert "\n" not in str(err.value)
