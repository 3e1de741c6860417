"""``rep.get``: find prims the script created, by path or by semantic label."""

from __future__ import annotations

import re

from .errors import Namespace, unsupported
from .graph import Item, current_graph


def prim_at_path(path) -> Item:
    """The prim at ``path`` (or each of a list of paths)."""
    paths = [path] if isinstance(path, str) else list(path)
    graph = current_graph()
    for p in paths:
        graph.prim(p)
    return Item(paths)


def prims(path_pattern: str | None = None, path_match: str | None = None, semantics=None,
          prim_types=None, cache_result: bool = True, ignore_case: bool = True, **unsupported_args) -> Item:
    """Prims whose path matches the regex ``path_pattern`` (or contains ``path_match``) and that carry
    any of ``semantics`` ((type, label) pairs); ``prim_types`` filters by kind ("Cube", "Sphere", ...)."""
    if unsupported_args:
        raise unsupported(f"get.prims({next(iter(unsupported_args))}=...)",
                          "filter by path_pattern, path_match, semantics or prim_types")
    flags = re.IGNORECASE if ignore_case else 0
    wanted = None
    if semantics is not None:
        pairs = [semantics] if isinstance(semantics, tuple) and isinstance(semantics[0], str) else semantics
        wanted = {(str(k), str(v)) for k, v in pairs}
    types = None if prim_types is None else {str(t).lower() for t in ([prim_types] if isinstance(prim_types, str)
                                                                      else prim_types)}
    found = []
    for path, prim in current_graph().prims.items():
        if path_pattern is not None and not re.search(path_pattern, path, flags):
            continue
        if path_match is not None and path_match not in path:
            continue
        if wanted is not None and not wanted & set(prim.semantics):
            continue
        if types is not None and prim.kind not in types:
            continue
        found.append(path)
    return Item(found)


get = Namespace("get", {"prim_at_path": prim_at_path, "prims": prims}, {
    "camera": "keep the item rep.create.camera returned",
    "light": "use rep.get.prims(prim_types=['light'])",
})
