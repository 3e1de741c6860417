"""Replicator's lights-and-materials randomization as its docs write it: a registered
``sphere_lights`` function creates lights whose temperature, intensity and position are drawn
every frame, and ``rep.randomizer.materials`` / ``scatter_2d`` give the labelled shapes a random
OmniPBR material and a place on the floor. The docs' lights also take ``scale`` (a sphere
light's radius, which softens its shadows); ambulo's lights are points and refuse it.

Written with Replicator's names only, in metres (ambulo's Replicator stage). Run it with
`ambulo run examples/isaac/replicator_lights_materials.py -- --output_dir _out_lights`:
BasicWriter writes rgb, semantic segmentation, depth (distance_to_camera) and normals.
"""

import argparse

parser = argparse.ArgumentParser()
parser.add_argument("--output_dir", default="_out_lights")
parser.add_argument("--num_frames", type=int, default=10)
parser.add_argument("--resolution", type=int, nargs=2, default=(512, 512))
args, _ = parser.parse_known_args()

import omni.replicator.core as rep

with rep.new_layer():

    def sphere_lights(num):
        lights = rep.create.light(
            light_type="Sphere",
            temperature=rep.distribution.normal(6500, 500),
            intensity=rep.distribution.normal(600, 100),
            position=rep.distribution.uniform((-3, -3, 2), (3, 3, 4)),
            count=num,
        )
        return lights.node

    rep.randomizer.register(sphere_lights)

    camera = rep.create.camera(position=(0, -7, 5), look_at=(0, 0, 0))
    render_product = rep.create.render_product(camera, tuple(args.resolution))

    floor = rep.create.plane(scale=8, semantics=[("class", "floor")])
    cubes = rep.create.cube(count=3, scale=0.6, position=(0, 0, 0.3), semantics=[("class", "cube")])
    spheres = rep.create.sphere(count=3, scale=0.6, position=(0, 0, 0.3), semantics=[("class", "sphere")])
    tori = rep.create.torus(count=2, scale=0.5, position=(0, 0, 0.125), semantics=[("class", "torus")])

    materials = rep.create.material_omnipbr(diffuse=rep.distribution.uniform((0, 0, 0), (1, 1, 1)), count=8)

    def shapes_on_floor():
        shapes = rep.get.prims(semantics=[("class", "cube"), ("class", "sphere"), ("class", "torus")])
        with shapes:
            rep.randomizer.materials(materials)
            rep.randomizer.scatter_2d(floor, check_for_collisions=True)
        return shapes.node

    rep.randomizer.register(shapes_on_floor)

    with rep.trigger.on_frame(num_frames=args.num_frames):
        rep.randomizer.sphere_lights(4)
        rep.randomizer.shapes_on_floor()

    writer = rep.WriterRegistry.get("BasicWriter")
    writer.initialize(
        output_dir=args.output_dir,
        rgb=True,
        semantic_segmentation=True,
        distance_to_camera=True,
        normals=True,
    )
    writer.attach([render_product])

    rep.orchestrator.run()
