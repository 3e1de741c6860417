"""The USD stage of a World: a real in-memory ``Usd.Stage`` that Isaac scripts author with pxr.

Isaac scripts get the stage (``omni.usd.get_context().get_stage()``, ``get_current_stage()``)
and define prims with ``UsdGeom`` and ``UsdPhysics``. ambulo's model is an ``MjSpec``, so a
World keeps both:

- prims made through the ambulo API (``scene.add``, ``add_reference_to_stage``) are
  *mirrored* on the USD stage as placeholders marked ``ambulo:mirrored`` (so
  ``GetPrimAtPath`` finds them and ``IsValid`` is True); their physics lives in the MjSpec;
- every other prim was *authored* with pxr: at each ``reset()`` the authored prims are copied
  to a new layer, converted by MuJoCo's UsdPhysics importer (through
  ``ambulo.core.importers``, which adds ``DriveAPI`` drives) and attached to the compiled
  scene under the default prim ``/World``.

What of UsdPhysics is honoured (MuJoCo's importer plus ambulo): rigid bodies
(``RigidBodyAPI``), colliders (``CollisionAPI`` on Cube, Sphere, Capsule, Cylinder, Mesh),
``MassAPI`` mass, revolute/prismatic/spherical/fixed joints with limits (``jointEnabled =
false`` ones left out, their bodies then unconnected by them), ``DriveAPI`` gains
and max force, the ``PhysicsScene`` gravity, and PhysX's ``physxScene:solverType``-free
iteration counts (``physxRigidBody:solverPositionIterationCount``, the largest one sets the
solver iterations), ``physxScene:timeStepsPerSecond`` (the World's ``physics_dt``), and the
other PhysX attributes with a MuJoCo meaning (``ambulo.core.usd_physx``), and ``UsdLux`` dome lights
(``ambulo.sim.usd_lights``: image-based lighting of the pbr and path tiers). Not honoured:
materials' friction combine modes other than max, and edits made with pxr to mirrored prims
(move those through the ambulo API).
"""

from __future__ import annotations

import math
import os
import tempfile

import mujoco

from .usd_lights import add_dome_lights

MIRRORED = "ambulo:mirrored"
"""customData key on prims whose physics is in the MjSpec (made through the ambulo API)."""

ROOT = "/World"
"""The default prim of every ambulo stage, as in Isaac's stages."""

SEMANTIC_TYPE = "semantic:Semantics:params:semanticType"
"""Isaac's ``Semantics`` attribute holding a label's type (``class`` reaches the annotators)."""
SEMANTIC_DATA = "semantic:Semantics:params:semanticData"
"""Isaac's ``Semantics`` attribute holding the label itself."""


def _pxr():
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics  # USD is optional at import
    except ImportError:
        raise ImportError("the USD stage needs pxr: pip install 'mujoco[usd]'") from None
    return Gf, Sdf, Usd, UsdGeom, UsdPhysics


class UsdStage:
    """An in-memory USD stage (z up, ``meters_per_unit``) with ``/World`` as its default prim."""

    def __init__(self, meters_per_unit: float = 1.0):
        _, _, Usd, UsdGeom, _ = _pxr()
        self.stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(self.stage, float(meters_per_unit))
        root = UsdGeom.Xform.Define(self.stage, ROOT).GetPrim()
        root.SetCustomDataByKey(MIRRORED, True)
        self.stage.SetDefaultPrim(root)
        self._time_steps_per_second: int | None = None
        self.on_adopt: list = []
        """Callables ``f(world)`` run when a World adopts this stage (made before any World): what a
        script put on the stage that belongs in the World's model (a URDF imported with Kit's command)."""

    @property
    def meters_per_unit(self) -> float:
        _, _, _, UsdGeom, _ = _pxr()
        return float(UsdGeom.GetStageMetersPerUnit(self.stage))

    def open(self, path: str | os.PathLike) -> None:
        """Replace the stage's content by the file ``path`` (Isaac's ``open_stage``)."""
        _, Sdf, _, _, _ = _pxr()
        layer = Sdf.Layer.FindOrOpen(str(path))
        if layer is None:
            raise FileNotFoundError(f"cannot open the USD file {str(path)!r}; check the path")
        self.stage.GetRootLayer().TransferContent(layer)
        if not self.stage.GetDefaultPrim():
            raise ValueError(f"{path}: the stage has no default prim; set one (defaultPrim = \"World\")")

    def mirror(self, prim_path: str, type_name: str = "Xform"):
        """Define a placeholder prim for an object made through the ambulo API; returns it."""
        prim = self.stage.DefinePrim(prim_path, type_name)
        prim.SetCustomDataByKey(MIRRORED, True)
        return prim

    def mirror_spec(self, spec: mujoco.MjSpec) -> None:
        """Mirror every body and frame of ``spec`` named by a prim path (``/World/...``), with its
        ancestors, so pxr sees the objects the ambulo API made."""
        paths = {e.name for group in (spec.bodies, spec.frames) for e in group
                 if e.name.startswith(ROOT + "/")}
        for path in sorted(paths):
            parts = path.split("/")
            for depth in range(3, len(parts) + 1):
                prefix = "/".join(parts[:depth])
                prim = self.stage.GetPrimAtPath(prefix)
                if not prim:
                    self.mirror(prefix)
                elif not prim.GetCustomDataByKey(MIRRORED) and depth < len(parts):
                    break  # an authored prim's subtree: leave it to pxr

    def is_mirrored(self, prim_path: str) -> bool:
        prim = self.stage.GetPrimAtPath(prim_path)
        return bool(prim) and bool(prim.GetCustomDataByKey(MIRRORED))

    def authored_paths(self) -> list[str]:
        """Prims authored with pxr (not mirrored, not under a mirrored prim other than /World)."""
        paths = []
        iterator = iter(self.stage.Traverse())
        for prim in iterator:
            if prim.GetCustomDataByKey(MIRRORED):
                if str(prim.GetPath()) != ROOT:
                    iterator.PruneChildren()
                continue
            paths.append(str(prim.GetPath()))
        return paths

    def signature(self) -> str:
        """Text that changes whenever the authored content changes (the World recompiles then)."""
        return self.stage.GetRootLayer().ExportToString()

    def scene_gravity_m_s2(self) -> tuple[float, float, float] | None:
        """Gravity of the stage's ``PhysicsScene`` in m/s² (world frame), or None without one."""
        _, _, _, _, UsdPhysics = _pxr()
        for prim in self.stage.Traverse():
            if prim.IsA(UsdPhysics.Scene):
                scene = UsdPhysics.Scene(prim)
                direction = scene.GetGravityDirectionAttr().Get()
                magnitude = scene.GetGravityMagnitudeAttr().Get()
                if direction is None or magnitude is None or magnitude < 0 or not any(direction):
                    # UsdPhysics: -inf/unset magnitude and a zero direction mean Earth gravity down the up axis
                    direction, magnitude = (0.0, 0.0, -1.0), 9.81 / self.meters_per_unit
                norm = sum(c * c for c in direction) ** 0.5
                g = [c / norm * magnitude * self.meters_per_unit for c in direction]
                return (g[0], g[1], g[2])
        return None

    def solver_iterations(self) -> int | None:
        """The largest PhysX position-iteration count authored on a body or articulation, within
        the PhysicsScene's ``physxScene:min/maxPositionIterationCount``; None if none is authored.

        PhysX iterates each island of bodies as often as its most demanding body asks; MuJoCo
        has one ``opt.iterations`` (the most its solver may take per step) for the whole model,
        so the largest count over the stage is the one that keeps every body's request."""
        counts, bounds = [], {}
        for prim in self.stage.Traverse():
            for name in ("physxRigidBody:solverPositionIterationCount",
                         "physxArticulation:solverPositionIterationCount",
                         "physxScene:minPositionIterationCount", "physxScene:maxPositionIterationCount"):
                attr = prim.GetAttribute(name)
                if attr and attr.HasAuthoredValue():
                    if name.startswith("physxScene"):
                        bounds[name.split(":")[1][:3]] = int(attr.Get())
                    else:
                        counts.append(int(attr.Get()))
        if not counts:
            return None
        return min(max(max(counts), bounds.get("min", 1)), bounds.get("max", max(counts)))

    def changed_time_steps_per_second(self) -> int | None:
        """The PhysicsScene's ``physxScene:timeStepsPerSecond`` when it was authored or changed
        since the last call (the World then steps 1/that), else None: a later
        ``set_simulation_dt`` wins until the stage's value changes again, as in Isaac, where
        both write the same attribute."""
        _, _, _, _, UsdPhysics = _pxr()
        value = None
        for prim in self.stage.Traverse():
            attr = prim.GetAttribute("physxScene:timeStepsPerSecond") if prim.IsA(UsdPhysics.Scene) else None
            if attr and attr.HasAuthoredValue():
                value = int(attr.Get())
        if value is None or value == self._time_steps_per_second:
            return None
        self._time_steps_per_second = value
        return value

    def physics_spec(self, drives=None) -> mujoco.MjSpec | None:
        """The authored prims as an ``MjSpec`` named relative to ``/World``, or None if there are none.

        The copy drops mirrored prims and scales ``/World`` by ``meters_per_unit``, so the
        importer sees metres whatever units the script authored in.
        """
        if not any(p != ROOT for p in self.authored_paths()):
            return None
        Gf, Sdf, Usd, UsdGeom, _ = _pxr()
        layer = Sdf.Layer.CreateAnonymous(".usda")
        layer.TransferContent(self.stage.GetRootLayer())
        copy = Usd.Stage.Open(layer)
        for prim in list(copy.Traverse()):
            path = str(prim.GetPath())
            if path != ROOT and prim.IsValid() and prim.GetCustomDataByKey(MIRRORED):
                copy.RemovePrim(path)
        if self.meters_per_unit != 1.0:
            scale = self.meters_per_unit
            UsdGeom.Xformable(copy.GetPrimAtPath(ROOT)).AddScaleOp(
                UsdGeom.XformOp.PrecisionDouble, "toMetres").Set(Gf.Vec3d(scale, scale, scale))
        from ambulo.core.importers import load_spec  # core imports sim lazily

        with tempfile.TemporaryDirectory(prefix="ambulo-stage-") as folder:
            file = os.path.join(folder, "authored.usda")
            layer.Export(file)
            spec = load_spec(file, drives=drives)
        _apply_display_colors(copy, spec)
        add_dome_lights(copy, spec, ROOT)  # MuJoCo's importer reads no UsdLux prims
        return spec

    def initial_velocities(self) -> dict[str, tuple[tuple[float, ...], tuple[float, ...]]]:
        """Body name (relative to ``/World``) -> (linear m/s, angular rad/s) authored with
        ``physics:velocity`` / ``physics:angularVelocity`` (UsdPhysics states degrees/s)."""
        _, _, _, _, UsdPhysics = _pxr()
        scale = self.meters_per_unit
        found = {}
        for path in self.authored_paths():
            prim = self.stage.GetPrimAtPath(path)
            if not prim.HasAPI(UsdPhysics.RigidBodyAPI):
                continue
            body = UsdPhysics.RigidBodyAPI(prim)
            lin, ang = body.GetVelocityAttr().Get(), body.GetAngularVelocityAttr().Get()
            if (lin is not None and any(lin)) or (ang is not None and any(ang)):
                lin = tuple(float(c) * scale for c in (lin or (0, 0, 0)))
                ang = tuple(math.radians(float(c)) for c in (ang or (0, 0, 0)))
                found[path[len(ROOT) + 1:]] = (lin, ang)
        return found


def _apply_display_colors(stage, spec: mujoco.MjSpec) -> None:
    """``primvars:displayColor`` of authored shapes as their geoms' colour (MuJoCo's importer skips it)."""
    _, _, _, UsdGeom, _ = _pxr()
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Gprim):
            continue
        colors = UsdGeom.Gprim(prim).GetDisplayColorAttr().Get()
        geom = spec.geom(str(prim.GetPath())[len(ROOT) + 1:])
        if colors and geom is not None:
            geom.rgba = [*map(float, colors[0]), 1.0]


_pending: UsdStage | None = None
"""A stage made before any World (Isaac's stage exists before its World); the next World adopts it."""


def authored_labels(stage) -> dict[str, str]:
    """Prim path -> class label of the prims of the ``Usd.Stage`` ``stage`` authored with Isaac's
    Semantics attributes (``SEMANTIC_TYPE`` ``class``, ``SEMANTIC_DATA`` the label)."""
    labels = {}
    for prim in stage.Traverse():
        kind, data = prim.GetAttribute(SEMANTIC_TYPE), prim.GetAttribute(SEMANTIC_DATA)
        if kind and data and kind.Get() == "class" and data.Get():
            labels[str(prim.GetPath())] = str(data.Get())
    return labels


def current_usd_stage() -> UsdStage:
    """The stage scripts author on: the current World's, else one waiting for the next World."""
    from .current import current_world_or_none  # leaf module, kept lazy for pxr-less use

    global _pending
    world = current_world_or_none()
    if world is not None:
        return world.usd
    if _pending is None:
        _pending = UsdStage()
    return _pending


def stage_for_new_world(meters_per_unit: float) -> UsdStage:
    """The stage a new World uses: the waiting one if a script authored before creating the
    World (its units set to ``meters_per_unit``), else a new one."""
    global _pending
    stage, _pending = _pending, None
    if stage is None:
        return UsdStage(meters_per_unit)
    _, _, _, UsdGeom, _ = _pxr()
    UsdGeom.SetStageMetersPerUnit(stage.stage, float(meters_per_unit))
    return stage


def new_usd_stage() -> UsdStage:
    """Isaac's ``create_new_stage``: an empty stage; the current World is dropped with the old one."""
    from .current import set_current_world

    global _pending
    set_current_world(None)
    _pending = UsdStage()
    return _pending


def forget_stages() -> None:
    """No current World and no stage waiting for one (a new script run starts empty): the next
    ``current_usd_stage()`` or ``World()`` makes a new stage. Needs no pxr."""
    from .current import set_current_world

    global _pending
    set_current_world(None)
    _pending = None


__all__ = ["MIRRORED", "ROOT", "SEMANTIC_DATA", "SEMANTIC_TYPE", "UsdStage", "authored_labels", "current_usd_stage",
           "forget_stages", "new_usd_stage", "stage_for_new_world"]
