"""Convert meshes MuJoCo cannot read (Collada ``.dae``, ``.ply``, glTF) into cached OBJ files.

MuJoCo decodes only OBJ, MSH and binary STL of at most 200,000 faces; yet half of the URDFs in ROS packages (``example-robot-data``: Panda, UR,
Go1, ANYmal, TIAGo, ...) use Collada meshes. ``trimesh`` (with ``pycollada`` for ``.dae``)
reads those, and the OBJ it writes is what MuJoCo loads instead.

Converted files live in a content-addressed cache: the name holds a hash of the source
file's bytes and of ``CONVERSION_VERSION``, so an edited mesh or a new converter gets a new
file, and a file is written atomically (a kill leaves it complete or absent). The cache
folder is ``$AMBULO_CACHE_DIR``, else ``$XDG_CACHE_HOME/ambulo/meshes``, else
``~/.cache/ambulo/meshes``; delete it at any time.

What a conversion keeps: the triangles of every geometry of the file, placed by the scene
graph's node transforms, scaled by the Collada ``<unit meter>``. What it drops: the Collada
``<up_axis>`` (RViz, MoveIt's geometric_shapes and Gazebo ignore it too, and ROS meshes are
authored for that: rviz issue #1045), materials and textures (the URDF's ``<material>``
colours the geom), and normals (MuJoCo computes them). The URDF's ``<mesh scale>`` is not
baked in: MuJoCo applies it per geom, so one converted file serves every scale.
"""

from __future__ import annotations

import hashlib
import io
import os
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

from ...utils.atomic import atomic_write_text
from .asset_errors import MeshConversionError

CONVERSION_VERSION = 1
"""Bump when ``convert_mesh``'s output changes: old cache entries are then not reused."""

CONVERTED_SUFFIXES = (".dae", ".ply", ".glb", ".gltf")
"""Mesh formats MuJoCo 4.0 has no decoder for and trimesh reads (checked: "no decoder found")."""

MUJOCO_STL_MAX_FACES = 200_000
"""MuJoCo's stl_decoder reads binary STL only, of at most this many faces ("number of faces
should be between 1 and 200000"); ASCII STLs and larger ones are converted too."""


def mesh_cache_dir() -> Path:
    """The folder converted meshes are cached in (created on first use)."""
    if os.environ.get("AMBULO_CACHE_DIR"):
        return Path(os.environ["AMBULO_CACHE_DIR"]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "ambulo" / "meshes"


def needs_conversion(path: Path) -> bool:
    """Whether MuJoCo cannot read ``path`` as it is, but ``convert_mesh`` can make it readable."""
    suffix = path.suffix.lower()
    return suffix in CONVERTED_SUFFIXES or (suffix == ".stl" and _stl_unreadable(path))


def convert_mesh(path: Path) -> tuple[Path, bool]:
    """The cached OBJ holding ``path``'s triangles, and whether it was already in the cache."""
    data = path.read_bytes()
    digest = hashlib.sha256(data + f"ambulo-mesh-v{CONVERSION_VERSION}".encode()).hexdigest()[:20]
    target = mesh_cache_dir() / f"{path.stem}-{digest}.obj"
    if target.is_file():
        return target, True
    target.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(target, _to_obj(path))
    return target, False


def _to_obj(path: Path) -> str:
    try:
        import trimesh  # only files with such meshes need it
    except ImportError:
        raise MeshConversionError(
            f"{path.name}: MuJoCo cannot read {path.suffix} meshes and converting them needs "
            "trimesh: pip install trimesh pycollada") from None
    unit_m = 1.0
    try:
        if path.suffix.lower() == ".dae":
            source, unit_m = _collada_geometry_only(path)
            scene = trimesh.load(source, file_type="dae", force="scene")
        else:
            scene = trimesh.load(str(path), force="scene")
        # to_mesh applies every node's transform before concatenating the geometries
        mesh = scene.to_mesh() if len(scene.geometry) else None
    except Exception as err:  # trimesh/pycollada raise many kinds (XML, KeyError, ValueError)
        raise MeshConversionError(
            f"{path}: trimesh cannot read this mesh ({type(err).__name__}: {err}); "
            "re-export it as OBJ or STL and point the robot file at that.") from None
    if mesh is None or len(mesh.faces) == 0:
        raise MeshConversionError(
            f"{path}: the mesh has no triangles (only lines or points?); re-export it with "
            "its surfaces, or remove the <mesh> that uses it.")
    if unit_m != 1.0:
        mesh.apply_scale(unit_m)
    return trimesh.exchange.obj.export_obj(mesh, include_normals=False, include_color=False,
                                           include_texture=False, write_texture=False)


_COLLADA_LOOKS = ("library_materials", "library_effects", "library_images", "bind_material")
"""Elements about appearance only. They are removed before pycollada reads the file: a broken
texture reference there makes pycollada drop the node that uses it, geometry and all (ANYmal
B's foot), and reading them costs time for nothing the OBJ keeps."""


def _collada_geometry_only(path: Path) -> tuple[io.BytesIO, float]:
    """The Collada file without its appearance elements, and its metres per unit."""
    tree = ET.parse(path)
    root = tree.getroot()
    namespace = root.tag[:root.tag.index("}") + 1] if root.tag.startswith("{") else ""
    unit = root.find(f"{namespace}asset/{namespace}unit")
    unit_m = float(unit.get("meter", 1.0)) if unit is not None else 1.0
    for parent in list(root.iter()):
        for child in list(parent):
            if child.tag[len(namespace):] in _COLLADA_LOOKS:
                parent.remove(child)
    if namespace:
        ET.register_namespace("", namespace[1:-1])
    return io.BytesIO(ET.tostring(root)), unit_m


def _stl_unreadable(path: Path) -> bool:
    """Whether MuJoCo's binary-only STL decoder rejects ``path``: an ASCII STL (its size does
    not match the binary header's face count) or a binary one over the face limit."""
    try:
        with open(path, "rb") as f:
            head = f.read(84)
        size = path.stat().st_size
    except OSError:
        return False  # MuJoCo reports the missing file
    if len(head) < 84:
        return head[:5].lower() == b"solid"
    faces = struct.unpack("<I", head[80:84])[0]
    if size != 84 + 50 * faces:
        return head[:5].lower() == b"solid"  # ASCII; anything else is broken, MuJoCo says so
    return faces > MUJOCO_STL_MAX_FACES
