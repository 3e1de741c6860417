"""Turn a Replicator graph into an ``ambulo.replicator.DatasetConfig``: scene, camera, nodes in order.

The scene holds every created prim as a body named by its prim path (shapes with a free joint,
so nodes pose them through qpos; the camera on a static body), labelled with its ``class``
semantics. Nodes outside triggers come first and draw once per run; then each trigger's nodes,
redrawn every ``interval`` frames. Materials with a random diffuse colour get it once per run.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ambulo.core import add_light, new_scene, set_semantic_label
from ambulo.render.ibl import add_image_light
from ambulo.replicator import DatasetConfig
from ambulo.sensors import CameraCfg
from ambulo.sensors.frames import look_at_gl
from ambulo.sim.camera import default_renderer
from ambulo.utils.rotations import mat_to_quat

from .distribution import Choice, draw, is_random
from .graph import SHAPES, Graph, Node, PrimDecl
from .nodes import ColorNode, LightNode, PoseNode, ScatterNode, blackbody_rgb, light_level
from .shapes import cone_mesh, euler_xyz_deg_to_mat, geom_parts, geom_type

CAMERA_CHILD = "Camera"
"""The camera sensor is ``<camera prim>/Camera``, mounted on the camera prim's body."""
DEFAULT_LIGHT = "/Replicator/DefaultLight"
_MATERIAL_STREAM = 0x6D61  # rng stream of material colours, apart from nodes' (seed, index, block)


def camera_rotation(graph: Graph, prim: PrimDecl) -> np.ndarray:
    """OpenGL axes (3, 3) of a created camera: aimed at ``look_at``, else turned by ``rotation``."""
    target = prim.extra.get("look_at")
    if target is None:
        return euler_xyz_deg_to_mat(prim.rotation_deg)
    point = graph.prim(target).position if isinstance(target, str) else target
    return look_at_gl(prim.position, point)


def build_spec(graph: Graph) -> mujoco.MjSpec:
    """The scene of every prim the graph created."""
    spec = new_scene("Replicator")
    spec.visual.headlight.active = 0  # Replicator scenes are lit by their lights only
    lights = [p for p in graph.prims.values() if p.kind == "light"]
    for prim in graph.prims.values():
        if prim.kind in SHAPES:
            body = spec.worldbody.add_body(name=prim.path, pos=prim.position.tolist(),
                                           quat=mat_to_quat(euler_xyz_deg_to_mat(prim.rotation_deg)).tolist())
            body.add_freejoint()
            _add_geoms(spec, body, prim)
            if prim.label is not None:
                set_semantic_label(spec, prim.path, prim.label)
        elif prim.kind == "camera":
            spec.worldbody.add_body(name=prim.path)
        elif prim.kind == "light":
            _add_light(spec, prim)
    if not lights:  # a new Kit stage comes with a distant light
        add_light(spec, DEFAULT_LIGHT, kind="distant", direction=(0.3, 0.2, -1.0), intensity=0.7, ambient=0.25)
    return spec


def _add_geoms(spec, body, prim: PrimDecl) -> None:
    """The primitive's geoms on its body: one geom, a torus's ring of capsules, or a cone's mesh."""
    rgba = [*(prim.color or (0.7, 0.7, 0.7)), 1.0]
    name = f"{prim.path}/{prim.kind.capitalize()}"
    if prim.kind == "cone":  # a mesh per cone: its scale is baked into the vertices
        verts, faces = cone_mesh(prim.scale)
        spec.add_mesh(name=f"{name}Mesh", uservert=verts.reshape(-1).tolist(), userface=faces.reshape(-1).tolist())
        body.add_geom(name=name, type=geom_type("cone"), meshname=f"{name}Mesh", rgba=rgba)
        return
    parts = geom_parts(prim.kind, prim.scale)
    for k, part in enumerate(parts):
        body.add_geom(name=name if len(parts) == 1 else f"{name}_{k:02d}", type=geom_type(prim.kind),
                      size=part.size.tolist(), pos=part.pos_m.tolist(), quat=part.quat.tolist(), rgba=rgba)


def _add_light(spec, prim: PrimDecl) -> None:
    kind, level = prim.extra["light_type"], light_level(prim.extra["intensity"])
    color = np.asarray(prim.extra["color"], float)
    if prim.extra.get("temperature") is not None:
        color = color * blackbody_rgb(prim.extra["temperature"])
    direction = euler_xyz_deg_to_mat(prim.rotation_deg) @ np.array([0.0, 0.0, -1.0])  # USD lights shine along -z
    if kind == "dome":
        add_light(spec, prim.path, kind="distant", intensity=0.0, ambient=level)
        light = spec.light(prim.path)
        light.ambient = (level * color).tolist()
        if prim.extra.get("texture"):
            # the HDR's values x Replicator's nits, scaled so its default 1000 is Filament's default
            # environment intensity (30,000): the 30x that maps 1000 nits to the 0.7 sun of the rasterizer
            add_image_light(spec, prim.extra["texture"], name=f"{prim.path}/texture",
                            intensity=_IBL_PER_NIT * prim.extra["intensity"])
    elif kind == "sphere":
        # MuJoCo 4's OpenGL renderer leaves point lights dark; a spot light with a 180 deg cutoff
        # and no falloff lights every direction, as a USD sphere light does
        light = add_light(spec, prim.path, kind="spot", position=prim.position.tolist(),
                          direction=direction.tolist(), intensity=level, color=tuple(color))
        light.cutoff, light.exponent = 180.0, 0.0
    else:
        add_light(spec, prim.path, kind=kind, position=prim.position.tolist(), direction=direction.tolist(),
                  intensity=level, color=tuple(color))


_IBL_PER_NIT = 30.0
"""Filament image-light intensity per Replicator dome-light nit (see ``_add_light``)."""


def camera_cfg(graph: Graph, product, annotators) -> CameraCfg:
    prim = graph.prim(product.camera)
    focal_mm, aperture_mm = prim.extra["focal_length"], prim.extra["horizontal_aperture"]
    return CameraCfg(prim_path=f"{prim.path}/{CAMERA_CHILD}", width=product.width, height=product.height,
                     focal_length_px=focal_mm * product.width / aperture_mm, offset_pos=tuple(prim.position),
                     offset_quat=tuple(mat_to_quat(camera_rotation(graph, prim))), offset_convention="opengl",
                     clipping_range_m=prim.extra["clipping_range"], annotators=tuple(annotators),
                     renderer=default_renderer())


def dataset_config(graph: Graph, product, annotators) -> DatasetConfig:
    """The ``DatasetConfig`` whose frame ``i`` is the graph's frame ``i`` (nodes in declaration order)."""
    palette = _material_colors(graph)
    nodes = list(graph.static_nodes) + [n for t in graph.triggers for n in t.nodes]
    randomizers = [_randomizer(graph, node, k, product, palette) for k, node in enumerate(nodes)]
    return DatasetConfig(name="replicator", build_scene=lambda: build_spec(graph),
                         camera=camera_cfg(graph, product, annotators), randomizers=randomizers)


def _material_colors(graph: Graph) -> list[tuple[float, float, float]]:
    rng = np.random.default_rng([graph.seed, _MATERIAL_STREAM])
    return [tuple(float(c) for c in (draw(m.diffuse, rng, 1)[0] if is_random(m.diffuse) else m.diffuse))
            for m in graph.materials]


def _randomizer(graph: Graph, node: Node, k: int, product, palette):
    name, every = f"{node.kind}_{k}", node.every_n_frames
    p = node.params
    if node.kind == "pose":
        kinds = {t: graph.prim(t).kind for t in node.targets}
        camera_pose = {}
        for t in node.targets:
            if kinds[t] == "camera":
                if t != product.camera:
                    raise ValueError(f"rep.modify.pose on camera {t}, which no render product uses")
                prim = graph.prim(t)
                camera_pose = {"position": prim.position, "rot_gl": camera_rotation(graph, prim),
                               "look_at": prim.extra.get("look_at"), "sensor": f"{t}/{CAMERA_CHILD}"}
        return PoseNode(name=name, every_n_frames=every, targets=node.targets, kinds=kinds, camera_pose=camera_pose,
                        position=p.get("position"), rotation=p.get("rotation"), scale=p.get("scale"),
                        look_at=p.get("look_at"))
    if node.kind == "color":
        return ColorNode(name=name, every_n_frames=every, targets=node.targets, colors=p["colors"])
    if node.kind == "materials":
        return ColorNode(name=name, every_n_frames=every, targets=node.targets,
                         colors=Choice(tuple(palette[i] for i in p["materials"])))
    if node.kind == "light":
        base = {t: graph.prim(t).extra for t in node.targets}
        return LightNode(name=name, every_n_frames=every, targets=node.targets, base=base,
                         intensity=p.get("intensity"), color=p.get("color"), temperature=p.get("temperature"),
                         position=p.get("position"), rotation=p.get("rotation"))
    if node.kind == "scatter_2d":
        return ScatterNode(name=name, every_n_frames=every, targets=node.targets, surfaces=p["surfaces"],
                           offset=p["offset"], check_for_collisions=p["check_for_collisions"])
    raise ValueError(f"unknown Replicator node {node.kind!r}")
