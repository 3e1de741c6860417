"""Replicator annotators: 3D boxes, normals and motion vectors of a cube that jumps between frames.

Written as Isaac Sim's Replicator tutorials write it (``omni.replicator.core`` only). Run it with
`ambulo run examples/isaac/replicator_annotators.py` (or Isaac Sim's python.sh). A camera looks
straight down from 3 m at a floor, a ramp tilted 25 degrees and a cube turned 30 degrees that a
randomizer puts at x = -0.3 or +0.3 m each frame. Each frame prints the 3D boxes, the normals seen on
the floor and the ramp, and the cube's motion in pixels. `--output_dir DIR` also saves each frame's
annotator outputs as DIR/frame_N.npz.
"""

import argparse

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import numpy as np  # Isaac modules can be imported only after the app starts
import omni.replicator.core as rep

parser = argparse.ArgumentParser()
parser.add_argument("--num_frames", type=int, default=4)
parser.add_argument("--seed", type=int, default=3)
parser.add_argument("--output_dir", default=None, help="save each frame's annotator outputs as frame_N.npz")
args, _ = parser.parse_known_args()

rep.set_global_seed(args.seed)
with rep.new_layer():
    camera = rep.create.camera(position=(0, 0, 3), rotation=(0, 0, 0))  # a USD camera looks down its -z
    render_product = rep.create.render_product(camera, (320, 240))
    rep.create.plane(semantics=[("class", "floor")], scale=(4, 4, 1))
    rep.create.cube(semantics=[("class", "ramp")], position=(0.8, 0.6, 0.2), rotation=(25, 0, 0),
                    scale=(0.6, 0.6, 0.05))
    cube = rep.create.cube(semantics=[("class", "cube")], position=(0, 0, 0.25), rotation=(0, 0, 30), scale=0.5)
    with rep.trigger.on_frame(num_frames=args.num_frames):
        with cube:
            rep.modify.pose(position=rep.distribution.choice([(-0.3, 0, 0.25), (0.3, 0, 0.25)]))

bbox_3d = rep.AnnotatorRegistry.get_annotator("bounding_box_3d")
normals = rep.AnnotatorRegistry.get_annotator("normals")
motion_vectors = rep.AnnotatorRegistry.get_annotator("motion_vectors")
semantics = rep.AnnotatorRegistry.get_annotator("semantic_segmentation")
depth = rep.AnnotatorRegistry.get_annotator("distance_to_image_plane")
camera_params = rep.AnnotatorRegistry.get_annotator("camera_params")
for annotator in (bbox_3d, normals, motion_vectors, semantics, depth, camera_params):
    annotator.attach(render_product)

for frame in range(args.num_frames):
    rep.orchestrator.step(rt_subframes=4)
    boxes, seg = bbox_3d.get_data(), semantics.get_data()
    classes = {label["class"]: int(key) for key, label in seg["info"]["idToLabels"].items()}
    print(f"frame {frame}")
    for row, path in zip(boxes["data"], boxes["info"]["primPaths"]):
        label = boxes["info"]["idToLabels"][str(row["semanticId"])]["class"]
        lo = np.round([float(row[k]) for k in ("x_min", "y_min", "z_min")], 4).tolist()
        hi = np.round([float(row[k]) for k in ("x_max", "y_max", "z_max")], 4).tolist()
        print(f"  {path} ({label}): extents {lo} to {hi} m at {np.round(row['transform'][3, :3].astype(float), 3).tolist()}")
    for name in ("floor", "ramp"):
        faces, counts = np.unique(np.round(normals.get_data()[seg["data"] == classes[name], :3].astype(float), 3),
                                  axis=0, return_counts=True)
        print(f"  {name} normal {faces[counts.argmax()].tolist()} on {counts.max()} of {counts.sum()} px")
    on_cube = seg["data"] == classes["cube"]
    motion = motion_vectors.get_data()[on_cube, :2]
    print(f"  cube motion (x, y) {(np.round(motion.mean(0).astype(float), 2) + 0.0).tolist()} px "
          f"(x > 0: moved left in the image)")
    if args.output_dir:
        from pathlib import Path

        Path(args.output_dir).mkdir(parents=True, exist_ok=True)
        np.savez(Path(args.output_dir) / f"frame_{frame}.npz", boxes=boxes["data"],
                 paths=np.array(boxes["info"]["primPaths"]), normals=normals.get_data(),
                 motion=motion_vectors.get_data(), semantic=seg["data"], depth=depth.get_data(),
                 classes=np.array([classes[c] for c in ("floor", "ramp", "cube")]),
                 view=np.reshape(camera_params.get_data()["cameraViewTransform"], (4, 4)),
                 resolution=np.array(camera_params.get_data()["renderProductResolution"]),
                 projection=np.reshape(camera_params.get_data()["cameraProjection"], (4, 4)))
simulation_app.close()
