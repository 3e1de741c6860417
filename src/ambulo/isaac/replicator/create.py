"""``rep.create``: primitives, the camera, lights, render products, groups and colour materials.

Shapes are Replicator's (Kit's mesh primitives, 100 cm across on a centimetre stage) with
1 m for 100 cm, centred on their prim, axes along z:

============  =============================================  ============================
primitive     at scale 1 (m)                                 MuJoCo geoms
============  =============================================  ============================
cube          1 x 1 x 1                                      box
sphere        1 across                                       ellipsoid (exact non-uniform)
cylinder      1 across, 1 tall                               cylinder (x, y scale together)
cone          1 across the base, 1 tall, apex up             mesh (scale fixed at create)
torus         ring radius 0.5, tube radius 0.25: 1.5 x 0.5   32 capsules (uniform scale)
disk          1 across, 1 mm thick                           cylinder
plane         1 x 1, 1 mm thick, top face at its position    box
============  =============================================  ============================

``shapes.py`` says why a cone's size is fixed when the scene compiles and how a torus scales per
frame. A creation argument given a distribution is drawn once per run (Replicator evaluates
create nodes once); for a shape or light created inside a trigger, every frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .distribution import Choice, Normal, Uniform, is_random
from .errors import Namespace, unsupported
from .graph import ONCE, Item, Node, PrimDecl, current_graph, paths_of
from .shapes import FIXED_SIZE, UNIFORM_SCALE

_DEFAULT_COLOR = (0.7, 0.7, 0.7)
_NOT_A_SHAPE = "ambulo builds cube, sphere, cylinder, cone, torus, disk and plane primitives"
_LIGHTS = ("distant", "sphere", "dome")


def _vec3(value, what: str, default) -> np.ndarray | object:
    if value is None:
        return np.asarray(default, float)
    if is_random(value):
        return value
    arr = np.asarray(value, float)
    if arr.shape == ():
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise ValueError(f"rep.create: {what} must be 3 numbers (or one for all axes), got {value!r}")
    return arr


def _semantics(semantics) -> list[tuple[str, str]]:
    if semantics is None:
        return []
    pairs = [semantics] if isinstance(semantics, tuple) and len(semantics) == 2 and isinstance(semantics[0], str) \
        else list(semantics)
    for pair in pairs:
        if not (isinstance(pair, (tuple, list)) and len(pair) == 2 and all(isinstance(s, str) for s in pair)):
            raise ValueError(f"semantics are (type, label) pairs, e.g. [('class', 'cube')]; got {semantics!r}")
    return [(str(k), str(v)) for k, v in pairs]


def _shape(kind: str, position=None, scale=None, rotation=None, pivot=None, semantics=None, material=None,
           visible: bool = True, count: int = 1, parent=None, look_at=None, name: str | None = None) -> Item:
    if pivot is not None or parent is not None or look_at is not None:
        arg = "pivot" if pivot is not None else "parent" if parent is not None else "look_at"
        raise unsupported(f"create.{kind}({arg}=...)", "prims stand alone at position/rotation/scale")
    if not visible:
        raise unsupported(f"create.{kind}(visible=False)", "create only the prims the camera should see")
    if int(count) < 1:
        raise ValueError(f"rep.create.{kind}: count must be >= 1, got {count}")
    graph = current_graph()
    color = None
    if material is not None:
        if not isinstance(material, Material):
            raise unsupported(f"create.{kind}(material={material!r})",
                              "pass a material from rep.create.material_omnipbr(diffuse=...)")
        color = material.diffuse
    base = f"/Replicator/{name or kind.capitalize()}_Xform"
    paths = []
    for _ in range(int(count)):
        prim = PrimDecl(path=graph.unique_path(base), kind=kind, position=np.zeros(3), rotation_deg=np.zeros(3),
                        scale=np.ones(3), semantics=_semantics(semantics),
                        color=None if color is None or is_random(color) else tuple(color))
        _set_pose(graph, prim, position, rotation, scale)
        graph.add_prim(prim)
        if is_random(color):
            graph.static_nodes.append(_once("color", [prim.path], {"colors": color}))
        paths.append(prim.path)
    return Item(paths)


def _set_pose(graph, prim: PrimDecl, position, rotation, scale) -> None:
    """Constant pose values go into the prim; distributions become a node drawn once per run."""
    values = {"position": _vec3(position, "position", (0, 0, 0)),
              "rotation": _vec3(rotation, "rotation", (0, 0, 0)),
              "scale": _vec3(scale, "scale", (1, 1, 1))}
    prim.position = values["position"] if not is_random(values["position"]) else np.zeros(3)
    prim.rotation_deg = values["rotation"] if not is_random(values["rotation"]) else np.zeros(3)
    prim.scale = values["scale"] if not is_random(values["scale"]) else np.ones(3)
    check_scale(prim.kind, scale, "create")
    random = {k: v for k, v in values.items() if is_random(v)}
    if random:  # drawn once per run, or every frame for a prim created inside a trigger
        graph.add_node("pose", [prim.path], random)


def check_scale(kind: str, scale, where: str) -> None:
    """Refuse, in one line, a scale the shape cannot take (``shapes.py`` says why)."""
    if scale is None:
        return
    if kind in FIXED_SIZE and (where == "modify" or is_random(scale)):
        raise unsupported(f"create.{kind}(scale=<a distribution>)" if where == "create" else
                          f"modify.pose(scale=...) on a {kind}",
                          f"a {kind} is a mesh, whose size MuJoCo fixes when the scene compiles: "
                          f"give rep.create.{kind}(scale=(x, y, z)) with numbers")
    if kind in UNIFORM_SCALE and not is_uniform(scale):
        call = "modify.pose" if where == "modify" else f"create.{kind}"
        raise ValueError(f"rep.{call}: a {kind} takes one scale for all axes (its tube is round), got {scale!r}")


def is_uniform(scale) -> bool:
    """One number, three equal numbers, or a distribution whose draws are such."""
    if isinstance(scale, (Uniform, Normal)):
        return all(np.ndim(v) == 0 for v in vars(scale).values())
    if isinstance(scale, Choice):
        return all(np.ndim(c) == 0 or (np.shape(c) == (3,) and c[0] == c[1] == c[2]) for c in scale.choices)
    value = np.asarray(scale, float)
    return value.ndim == 0 or (value.shape == (3,) and value[0] == value[1] == value[2])


def _once(kind, targets, params) -> Node:
    return Node(kind, targets, params, ONCE, current_graph().layer)


def cube(**kwargs) -> Item:
    """A 1 m cube (box) per ``count``; ``semantics=[("class", "cube")]`` labels it."""
    return _shape("cube", **kwargs)


def sphere(**kwargs) -> Item:
    """A sphere of 1 m diameter (an ellipsoid under non-uniform scale)."""
    return _shape("sphere", **kwargs)


def cylinder(**kwargs) -> Item:
    """A cylinder 1 m across and 1 m tall, axis along z (scale x and y together)."""
    return _shape("cylinder", **kwargs)


def cone(**kwargs) -> Item:
    """A cone 1 m tall and 1 m across its base, apex up along z, centred on its prim: a mesh, so
    its ``scale`` is fixed when it is created (numbers, not a distribution)."""
    return _shape("cone", **kwargs)


def torus(**kwargs) -> Item:
    """A torus around z: tube radius 0.25 m on a 0.5 m ring (1.5 m across, 0.5 m tall), built
    from 32 capsules; it takes a uniform scale (one number), per frame too."""
    return _shape("torus", **kwargs)


def disk(**kwargs) -> Item:
    """A flat disk 1 m across facing +z (a 1 mm cylinder)."""
    return _shape("disk", **kwargs)


def plane(**kwargs) -> Item:
    """A 1 m x 1 m plane facing +z (a 1 mm slab whose top is at ``position``); a scatter surface."""
    return _shape("plane", **kwargs)


def camera(position=None, rotation=None, look_at=None, focal_length: float = 24.0,
           horizontal_aperture: float = 20.955, clipping_range=(1.0, 1000000.0), projection_type: str = "pinhole",
           name: str | None = None, count: int = 1, **unsupported_args) -> Item:
    """A pinhole camera: USD axes (looks along -z, y up) turned by ``rotation``, or aimed at ``look_at``.

    ``focal_length`` and ``horizontal_aperture`` are in mm (Replicator's defaults 24 and 20.955);
    pixels are square, so the vertical aperture follows from the render product's resolution.
    ``clipping_range`` is in stage units (m); the near plane is kept at 1 cm or more.
    """
    if unsupported_args:
        raise unsupported(f"create.camera({next(iter(unsupported_args))}=...)",
                          "ambulo cameras take position, rotation, look_at, focal_length, horizontal_aperture, "
                          "clipping_range")
    if projection_type != "pinhole":
        raise unsupported(f"create.camera(projection_type={projection_type!r})", "ambulo cameras are pinhole")
    if count != 1:
        raise unsupported(f"create.camera(count={count})", "create one camera per render product")
    graph = current_graph()
    prim = PrimDecl(path=graph.unique_path(f"/Replicator/{name or 'Camera'}_Xform"), kind="camera",
                    position=np.zeros(3), rotation_deg=np.zeros(3), scale=np.ones(3))
    aim = None if look_at is None else _look_at(look_at)
    prim.extra = {"focal_length": float(focal_length), "horizontal_aperture": float(horizontal_aperture),
                  "clipping_range": (max(0.01, float(clipping_range[0])), float(clipping_range[1])),
                  "look_at": None if is_random(aim) else aim}
    position, rotation = _vec3(position, "position", (0, 0, 0)), _vec3(rotation, "rotation", (0, 0, 0))
    prim.position = np.zeros(3) if is_random(position) else position
    prim.rotation_deg = np.zeros(3) if is_random(rotation) else rotation
    graph.add_prim(prim)
    random = {k: v for k, v in (("position", position), ("rotation", rotation), ("look_at", aim)) if is_random(v)}
    if random:  # one node, so a drawn position and a drawn aim belong to the same pose
        graph.static_nodes.append(_once("pose", [prim.path], random))
    return Item([prim.path])


def _look_at(target):
    """A point (3 numbers) or a prim (item/path) whose position the camera aims at."""
    if isinstance(target, (Item, str)):
        paths = paths_of(target)
        if len(paths) != 1:
            raise ValueError(f"look_at needs one prim, got {len(paths)}")
        return paths[0]
    if is_random(target):
        return target
    return np.asarray(target, float).reshape(3)


def light(light_type: str = "distant", color=(1.0, 1.0, 1.0), intensity=1000.0, position=None,
          rotation=None, scale=None, count: int = 1, name: str | None = None, texture: str | None = None,
          temperature=None, **unsupported_args) -> Item:
    """A light: "distant" (aimed along -z turned by ``rotation``), "sphere" (a point light: ``scene.py``) or "dome"
    (uniform ambient light; with ``texture``, an HDR environment: image-based lighting in the pbr
    camera tier, ``ambulo.render.ibl``, and its ambient level in the rasterizer).

    Replicator intensities are nits; ambulo's rasterizer takes a 0-1 diffuse level, so
    ``intensity`` is scaled to make Replicator's default (1000) ambulo's default sun level (0.7).
    ``temperature`` (K) tints ``color`` with the blackbody colour (``nodes.blackbody_rgb``), as
    USD's enableColorTemperature does. ``intensity``, ``color``, ``temperature``, ``position`` and
    ``rotation`` may be distributions: drawn once per run, or every frame when the light is
    created inside a trigger (a registered ``sphere_lights`` function, as Replicator's docs do).
    ambulo's lights are points, so ``scale`` (a sphere light's radius, its shadows' softness) is refused.
    """
    if unsupported_args:
        raise unsupported(f"create.light({next(iter(unsupported_args))}=...)",
                          "ambulo lights take light_type, color, intensity, temperature, position, rotation")
    kind = str(light_type).lower()
    if kind not in _LIGHTS:
        raise unsupported(f"create.light(light_type={light_type!r})", f"ambulo has {', '.join(_LIGHTS)} lights")
    if texture is not None and kind != "dome":
        raise unsupported(f"create.light(light_type={light_type!r}, texture=...)", "only a dome light takes a texture")
    if scale is not None:
        raise unsupported("create.light(scale=...)", "ambulo's lights are points (a sphere light's radius only "
                          "softens its shadows in Kit); drop scale")
    values = {"intensity": intensity, "color": color, "temperature": temperature,
              "position": _vec3(position, "position", (0, 0, 0)), "rotation": _vec3(rotation, "rotation", (0, 0, 0))}
    random = {k: v for k, v in values.items() if is_random(v)}
    graph = current_graph()
    paths = []
    for _ in range(int(count)):
        prim = PrimDecl(path=graph.unique_path(f"/Replicator/{name or kind.capitalize() + 'Light'}_Xform"),
                        kind="light", position=np.zeros(3), rotation_deg=np.zeros(3), scale=np.ones(3))
        prim.extra = {"light_type": kind, "intensity": 1000.0 if is_random(intensity) else float(intensity),
                      "color": (1.0, 1.0, 1.0) if is_random(color) else tuple(float(c) for c in color),
                      "temperature": None if temperature is None or is_random(temperature) else float(temperature),
                      "texture": None if texture is None else str(texture)}
        prim.position = np.zeros(3) if is_random(values["position"]) else values["position"]
        prim.rotation_deg = np.zeros(3) if is_random(values["rotation"]) else values["rotation"]
        graph.add_prim(prim)
        paths.append(prim.path)
    if random:  # one node over all ``count`` lights: one draw per light
        graph.add_node("light", paths, random)
    return Item(paths)


@dataclass(frozen=True)
class Material:
    """``rep.create.material_omnipbr``: ambulo's rasterizer uses its diffuse colour."""

    diffuse: object

    @property
    def node(self) -> Material:
        return self


def material_omnipbr(diffuse=None, count: int = 1, **unsupported_args):
    """A material with a ``diffuse`` colour (RGB 0-1, or a distribution drawn once per prim using it)."""
    if unsupported_args:
        raise unsupported(f"create.material_omnipbr({next(iter(unsupported_args))}=...)",
                          "ambulo's rasterizer uses only the diffuse colour; pass diffuse=(r, g, b)")
    diffuse = (0.2, 0.2, 0.2) if diffuse is None else diffuse
    made = [Material(diffuse if is_random(diffuse) else tuple(float(c) for c in diffuse)) for _ in range(int(count))]
    current_graph().materials.extend(made)
    return made[0] if count == 1 else made


def render_product(camera, resolution, force_new: bool = False, name: str | None = None):
    """What a writer is attached to: ``camera`` (an item or prim path from rep.create.camera) at
    ``resolution`` (width, height) px."""
    from .orchestrator import RenderProduct  # orchestrator imports this module

    graph = current_graph()
    paths = paths_of(camera) if not (isinstance(camera, str) and camera not in graph.prims) else [camera]
    if len(paths) != 1 or paths[0] not in graph.prims or graph.prims[paths[0]].kind != "camera":
        raise unsupported(f"create.render_product({camera!r})",
                          "render products use a camera made with rep.create.camera in this script")
    width, height = (int(v) for v in resolution)
    if width < 1 or height < 1:
        raise ValueError(f"render_product resolution must be (width, height) >= 1, got {resolution!r}")
    product = RenderProduct(camera=paths[0], width=width, height=height)
    graph.render_products.append(product)
    return product


def group(items, semantics=None) -> Item:
    """One item over several (``with rep.create.group([a, b]):`` modifies all of them)."""
    paths = paths_of(items)
    if semantics is not None:
        labels = _semantics(semantics)
        for path in paths:
            current_graph().prim(path).semantics = labels
    return Item(paths)


create = Namespace("create", {
    "cube": cube, "sphere": sphere, "cylinder": cylinder, "cone": cone, "torus": torus, "disk": disk, "plane": plane, "camera": camera,
    "light": light, "material_omnipbr": material_omnipbr, "render_product": render_product, "group": group,
}, {
    "capsule": f"not supported: {_NOT_A_SHAPE}",
    "from_usd": "USD assets are not loaded into Replicator graphs; build the scene from primitives",
    "from_dir": "USD assets are not loaded into Replicator graphs; build the scene from primitives",
    "stereo_camera": "create two cameras with rep.create.camera",
    "xform": "create the primitive itself at its pose",
})
