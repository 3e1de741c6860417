"""The Replicator module names (``omni.replicator.core``, ``omni.isaac.synthetic_utils``,
``omni.kit.viewport.utility``) and the ambulo objects that answer them; merged into
``names.MODULES``."""

from __future__ import annotations

_REP = "ambulo.isaac.replicator"

_CORE = {
    "create": f"{_REP}.create:create",
    "get": f"{_REP}.get:get",
    "modify": f"{_REP}.modify:modify",
    "randomizer": f"{_REP}.randomizer:randomizer",
    "distribution": f"{_REP}.distribution:distribution",
    "trigger": f"{_REP}.trigger:trigger",
    "orchestrator": f"{_REP}.orchestrator:orchestrator",
    "WriterRegistry": f"{_REP}.basic_writer:WriterRegistry",
    "writers": f"{_REP}.basic_writer:writers",
    "BasicWriter": f"{_REP}.basic_writer:BasicWriter",
    "AnnotatorRegistry": f"{_REP}.annotators:AnnotatorRegistry",
    "annotators": f"{_REP}.annotators:annotators",
    "new_layer": f"{_REP}.core:new_layer",
    "set_global_seed": f"{_REP}.core:set_global_seed",
}

MODULES: dict[str, dict[str, str]] = {
    "omni.replicator.core": _CORE,
    "omni.isaac.synthetic_utils": {"SyntheticDataHelper": f"{_REP}.synthetic_helper:SyntheticDataHelper"},
    "omni.kit.viewport.utility": {"get_active_viewport": f"{_REP}.viewport:get_active_viewport"},
}
"""Isaac module name -> {name it provides: "ambulo.module:attribute"}."""
