"""Replicator "getting started" in Isaac Sim's style: labelled shapes, a camera, randomized frames.

Written with Isaac Sim's module names only. Run it with
`ambulo run examples/isaac/replicator_basics.py -- --output_dir _out_basics` (or with Isaac Sim's
python.sh): it writes BasicWriter's files (rgb, tight 2D boxes, semantic segmentation, 3D boxes
and camera parameters) for every frame, each frame a new draw of the shapes' poses and colours.
"""

import argparse

from isaacsim import SimulationApp

parser = argparse.ArgumentParser()
parser.add_argument("--output_dir", default="_out_replicator_basics")
parser.add_argument("--num_frames", type=int, default=10)
parser.add_argument("--seed", type=int, default=42)
parser.add_argument("--resolution", type=int, nargs=2, default=(640, 480))
args, _ = parser.parse_known_args()

simulation_app = SimulationApp({"headless": True})

import omni.replicator.core as rep  # Replicator can be imported only after the app starts

rep.set_global_seed(args.seed)

with rep.new_layer():
    # a camera 6 m back and 4 m up, aimed at the middle of the table top
    camera = rep.create.camera(position=(0.0, -6.0, 4.0), look_at=(0.0, 0.0, 0.0))
    render_product = rep.create.render_product(camera, tuple(args.resolution))
    rep.create.light(light_type="distant", intensity=1200, rotation=(30, 0, 20))

    table = rep.create.plane(scale=(5, 5, 1), semantics=[("class", "table")])
    cube = rep.create.cube(semantics=[("class", "cube")], scale=0.6)
    sphere = rep.create.sphere(semantics=[("class", "sphere")], scale=0.7)
    cylinder = rep.create.cylinder(semantics=[("class", "cylinder")], scale=(0.5, 0.5, 0.8))

    # nothing below runs here: it adds nodes that rep.orchestrator.run() evaluates every frame
    with rep.trigger.on_frame(num_frames=args.num_frames):
        with rep.create.group([cube, sphere, cylinder]):
            rep.modify.pose(
                position=rep.distribution.uniform((-1.8, -1.8, 0.45), (1.8, 1.8, 0.45)),
                rotation=rep.distribution.uniform((0, 0, -180), (0, 0, 180)),
            )
            rep.randomizer.color(colors=rep.distribution.uniform((0.1, 0.1, 0.1), (1.0, 1.0, 1.0)))

    writer = rep.WriterRegistry.get("BasicWriter")
    writer.initialize(
        output_dir=args.output_dir,
        rgb=True,
        bounding_box_2d_tight=True,
        semantic_segmentation=True,
        bounding_box_3d=True,
        camera_params=True,
    )
    writer.attach([render_product])

    rep.orchestrator.run()

print(f"wrote {args.num_frames} frames to {args.output_dir}")
simulation_app.close()
