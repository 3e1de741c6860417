"""``rep.trigger.on_frame``: the block whose nodes the orchestrator runs on every frame it renders."""

from __future__ import annotations

from .errors import Namespace
from .graph import Trigger, current_graph


def on_frame(num_frames: int | None = None, interval: int = 1, rt_subframes: int = 1, max_execs: int | None = None):
    """Nodes declared inside run every ``interval`` frames; ``num_frames`` frames are rendered by
    ``rep.orchestrator.run()``. ``rt_subframes`` (extra path-tracing passes) changes nothing here:
    ambulo's rasterizer has no accumulation to wait for."""
    num_frames = max_execs if num_frames is None else num_frames
    if num_frames is not None and int(num_frames) < 1:
        raise ValueError(f"rep.trigger.on_frame: num_frames must be >= 1, got {num_frames}")
    if int(interval) < 1:
        raise ValueError(f"rep.trigger.on_frame: interval must be >= 1, got {interval}")
    trigger = Trigger(None if num_frames is None else int(num_frames), int(interval))
    current_graph().triggers.append(trigger)
    return trigger


trigger = Namespace("trigger", {"on_frame": on_frame}, {
    "on_time": "frames are not tied to simulated time; use rep.trigger.on_frame(num_frames=N)",
    "on_custom_event": "call rep.orchestrator.step() where the event would fire",
    "register": "put the nodes inside rep.trigger.on_frame",
})
