"""Replicator's randomizer pattern on a torus and a cone: functions registered with
``rep.randomizer.register`` find the shapes by their semantics (``rep.get.prims``) and turn,
scale, colour and scatter them on every frame.

Written with Replicator's names only, in metres (ambulo's Replicator stage). Run it with
`ambulo run examples/isaac/replicator_shapes.py -- --output_dir _out_shapes`: BasicWriter writes
rgb, tight 2D boxes, semantic segmentation, 3D boxes, depth (distance_to_camera), normals and the
camera parameters of each frame.
"""

import argparse

parser = argparse.ArgumentParser()
parser.add_argument("--output_dir", default="_out_shapes")
parser.add_argument("--num_frames", type=int, default=5)
parser.add_argument("--resolution", type=int, nargs=2, default=(640, 480))
parser.add_argument("--seed", type=int, default=0)
args, _ = parser.parse_known_args()

import omni.replicator.core as rep

rep.set_global_seed(args.seed)

with rep.new_layer():
    camera = rep.create.camera(position=(0, -6, 4), look_at=(0, 0, 0))
    render_product = rep.create.render_product(camera, tuple(args.resolution))
    rep.create.light(light_type="distant", intensity=1000, rotation=(40, 0, 30))
    rep.create.light(light_type="dome", intensity=400)

    floor = rep.create.plane(scale=8, semantics=[("class", "floor")])
    torus = rep.create.torus(semantics=[("class", "torus")], position=(-1.2, 0, 0.6))
    cone = rep.create.cone(semantics=[("class", "cone")], scale=(1.0, 1.0, 1.5))

    def tumble_tori():
        tori = rep.get.prims(semantics=[("class", "torus")])
        with tori:
            rep.modify.pose(
                rotation=rep.distribution.uniform((-60, -60, -180), (60, 60, 180)),
                scale=rep.distribution.uniform(0.5, 1.2),
            )
        return tori.node

    def scatter_cones():
        cones = rep.get.prims(semantics=[("class", "cone")])
        with cones:
            rep.randomizer.scatter_2d(floor, offset=0.75)  # the base of a 1.5 m cone on the floor
        return cones.node

    def paint_shapes():
        shapes = rep.get.prims(semantics=[("class", "torus"), ("class", "cone")])
        with shapes:
            rep.randomizer.color(colors=rep.distribution.uniform((0.2, 0.2, 0.2), (1.0, 1.0, 1.0)))
        return shapes.node

    rep.randomizer.register(tumble_tori)
    rep.randomizer.register(scatter_cones)
    rep.randomizer.register(paint_shapes)

    with rep.trigger.on_frame(num_frames=args.num_frames):
        rep.randomizer.tumble_tori()
        rep.randomizer.scatter_cones()
        rep.randomizer.paint_shapes()

    writer = rep.WriterRegistry.get("BasicWriter")
    writer.initialize(
        output_dir=args.output_dir,
        rgb=True,
        bounding_box_2d_tight=True,
        semantic_segmentation=True,
        bounding_box_3d=True,
        distance_to_camera=True,
        normals=True,
        camera_params=True,
    )
    writer.attach([render_product])

    rep.orchestrator.run()
