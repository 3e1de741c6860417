"""Replicator's "Getting started / Hello World" as its docs write it: a torus, a sphere and a cube
posed and scaled anew on each of 10 frames, written by BasicWriter after ``rep.orchestrator.preview()``.

In Kit, ``preview()`` renders one frame and the user presses Run to write the frames; under
`ambulo run examples/isaac/replicator_hello_world.py` the script ends after ``preview()``, so
ambulo does what Run would: it renders the trigger's 10 frames into ``_output/`` and says so on
stderr. The options (ambulo's, for tests; the defaults are the tutorial's values) change the
output folder, the resolution and the frame count.

The docs write positions for Kit's centimetre stage; ambulo's Replicator stage is in metres (as
Isaac Sim's), so the camera is 1000 m up and the 0.1-2 m shapes are a few pixels across.
"""

import argparse

parser = argparse.ArgumentParser()
parser.add_argument("--output_dir", default="_output")
parser.add_argument("--resolution", type=int, nargs=2, default=(1024, 1024))
parser.add_argument("--num_frames", type=int, default=10)
args, _ = parser.parse_known_args()

import omni.replicator.core as rep

with rep.new_layer():

    camera = rep.create.camera(position=(0, 0, 1000))

    render_product = rep.create.render_product(camera, tuple(args.resolution))

    torus = rep.create.torus(semantics=[("class", "torus")], position=(0, -200, 100))

    sphere = rep.create.sphere(semantics=[("class", "sphere")], position=(0, 100, 100))

    cube = rep.create.cube(semantics=[("class", "cube")], position=(100, -200, 100))

    with rep.trigger.on_frame(num_frames=args.num_frames):
        with rep.create.group([torus, sphere, cube]):
            rep.modify.pose(
                position=rep.distribution.uniform((-100, -100, -100), (200, 200, 200)),
                scale=rep.distribution.uniform(0.1, 2),
            )

    # Initialize and attach writer
    writer = rep.WriterRegistry.get("BasicWriter")

    writer.initialize(output_dir=args.output_dir, rgb=True, bounding_box_2d_tight=True)

    writer.attach([render_product])

    rep.orchestrator.preview()
