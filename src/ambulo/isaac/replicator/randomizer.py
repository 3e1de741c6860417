"""``rep.randomizer``: colour, material and 2D-scatter randomizers, and ``register`` for user functions.

Like ``rep.modify``, each call adds a node to the open trigger (or one that runs once outside
it); the node's draws happen per frame when the orchestrator renders (``nodes.py``).
"""

from __future__ import annotations

from .create import Material
from .distribution import choice, is_random
from .errors import Namespace, unsupported
from .graph import current_graph, paths_of


def _shapes(targets: list[str], what: str) -> list[str]:
    graph = current_graph()
    for path in targets:
        if graph.prim(path).kind in ("camera", "light"):
            raise unsupported(f"randomizer.{what} on {graph.prim(path).kind}s", "randomize shapes' colours and places")
    return targets


def color(colors, per_sub_mesh: bool = False, seed: int | None = None, input_prims=None):
    """A colour per prim per frame: ``colors`` is a distribution of RGB or a list of RGB to choose from."""
    if seed not in (None, -1):
        raise unsupported("randomizer.color(seed=...)", "draws come from rep.set_global_seed")
    graph = current_graph()
    targets = _shapes(graph.current_targets(input_prims, "randomizer.color"), "color")
    if not is_random(colors):
        colors = choice([tuple(float(v) for v in c) for c in colors])
    return graph.add_node("color", targets, {"colors": colors})


def materials(materials, seed: int | None = None, input_prims=None):
    """Give each prim one of ``materials`` (from rep.create.material_omnipbr) per frame."""
    if seed not in (None, -1):
        raise unsupported("randomizer.materials(seed=...)", "draws come from rep.set_global_seed")
    mats = [materials] if isinstance(materials, Material) else list(materials)
    if not mats or not all(isinstance(m, Material) for m in mats):
        raise unsupported("randomizer.materials with material paths",
                          "pass materials made with rep.create.material_omnipbr(diffuse=...)")
    graph = current_graph()
    targets = _shapes(graph.current_targets(input_prims, "randomizer.materials"), "materials")
    indices = [next(i for i, m in enumerate(graph.materials) if m is mat) for mat in mats]
    return graph.add_node("materials", targets, {"materials": indices})


def scatter_2d(surface_prims, seed: int | None = None, offset: float = 0.0, check_for_collisions: bool = False,
               no_coll_prims=None, min_samp=None, max_samp=None, input_prims=None):
    """Place each prim at a uniform random point of the surface planes (area-weighted), its origin
    ``offset`` m above the surface, rotation kept; ``check_for_collisions`` redraws prims that
    overlap another (MuJoCo's collision test), and parks those that still do after 30 tries out
    of view."""
    if seed not in (None, -1):
        raise unsupported("randomizer.scatter_2d(seed=...)", "draws come from rep.set_global_seed")
    if no_coll_prims is not None or min_samp is not None or max_samp is not None:
        raise unsupported("randomizer.scatter_2d(no_coll_prims/min_samp/max_samp=...)",
                          "scatter over whole planes; every scattered prim avoids every other one")
    graph = current_graph()
    surfaces = paths_of(surface_prims)
    for path in surfaces:
        if graph.prim(path).kind != "plane":
            raise unsupported(f"randomizer.scatter_2d on {graph.prim(path).kind} surfaces",
                              "scatter onto planes made with rep.create.plane")
    targets = _shapes(graph.current_targets(input_prims, "randomizer.scatter_2d"), "scatter_2d")
    if set(targets) & set(surfaces):
        raise ValueError("rep.randomizer.scatter_2d: a surface cannot be scattered onto itself")
    return graph.add_node("scatter_2d", targets, {"surfaces": surfaces, "offset": float(offset),
                                                  "check_for_collisions": bool(check_for_collisions)})


class _Randomizers(Namespace):
    """``rep.randomizer``, plus the functions this run registered (``rep.randomizer.<name>(...)``)."""

    def __getattr__(self, attr: str):
        if not attr.startswith("__"):
            registered = current_graph().registered.get(attr)
            if registered is not None:
                return registered
        return super().__getattr__(attr)


def register(fn, override: bool = True):
    """Make ``fn`` callable as ``rep.randomizer.<fn.__name__>`` (it runs when called, e.g. in a trigger)."""
    graph = current_graph()
    if not override and fn.__name__ in graph.registered:
        raise ValueError(f"rep.randomizer.{fn.__name__} is already registered; pass override=True")
    graph.registered[fn.__name__] = fn
    return fn


randomizer = _Randomizers("randomizer", {
    "color": color, "materials": materials, "scatter_2d": scatter_2d, "register": register,
}, {
    "scatter_3d": "scatter onto planes with rep.randomizer.scatter_2d",
    "texture": "use rep.randomizer.color or rep.randomizer.materials",
    "instantiate": "create the prims once with rep.create and scatter them",
    "rotation": "use rep.modify.pose(rotation=rep.distribution.uniform(...))",
})
