"""Watch a simulation live in a browser: ``serve(world_or_env)`` or ``World(viewer="web")``.

A server on 127.0.0.1 (``--viewer-port``; over SSH, ``ssh -L 8080:127.0.0.1:8080 host``) sends
the scene's shapes and colours once, then streams the watched world's body poses at a capped rate
(30 Hz); the server runs in a process of its own, fed through a pipe (``remote``). The page has pause/step/reset, the world to watch among N, a
camera that follows the robot, the walking policy's velocity command from sliders or keys
(W/S, A/D, Q/E, X), body visibility, and for an env its command and episode-return curve; a grid
of worlds side by side; live scalar curves (``WebViewer.add_scalars``); overlays (contact forces,
COM/ZMP/capture point, the model's cameras, and what features feed: the navigator's map, plan,
footsteps and walked path, point clouds, images, detections; ``overlays``; a lidar's last scan
is drawn without feeding it, ``sensor_feeds``).

Built on viser (Apache-2.0) rather than MuJoCo 4's own web viewer (``mujoco.studio``): viser's
GUI is Python-side (number inputs, buttons, sliders, hotkey commands, uPlot curves), which is
what a batched, teleoperated, training-time view needs, and its three.js client draws with
plain WebGL, which headless Chromium's SwiftShader renders, so the page is tested on a CPU-only
machine. MuJoCo Studio streams an ImGui UI into a WASM Filament renderer (WebGL2, heavy on a
software rasterizer) and is customized through its own plugin protocol; it shows one MjData,
not one world of a batch. mjlab and Isaac Lab 3 chose viser for the same reasons.

Layering: this is an app (``ambulo.viewer`` sits beside ``rl``, ``demo``, ...); it reads
``ambulo.sim`` Worlds and ``ambulo.envs`` envs through their ``Simulation`` (as a lifecycle
component) and registers ``viewer="web"`` with ``ambulo.sim.viewers`` on import.
"""

from __future__ import annotations

from ..sim.viewers import register_viewer
from .camera import CameraPose, from_mjv_camera, project_w
from .server import WebViewer
from .targets import target_of

DEFAULT_PORT = 8080


def serve(world_or_env, port: int = DEFAULT_PORT, *, rate_hz: float = 30.0, announce: bool = True,
          grid: int = 1, process: bool = True) -> WebViewer:
    """Open a web viewer on ``world_or_env`` (an ``ambulo.sim.World`` or an ``ambulo.envs`` env).

    It watches every step the simulation takes from now on, from any loop; ``close()`` it (or use
    it as a context manager) to stop the server and free a paused simulation. With ``announce`` the
    URL is printed. ``grid``: worlds drawn side by side from the start (the watched one and the
    next ones; the page's "Worlds drawn" changes it). ``process``: the page's server runs in a process
    of its own (the watched one only copies poses); False keeps it on threads of this one."""
    viewer = WebViewer(target_of(world_or_env), port=port, rate_hz=rate_hz, grid=grid, process=process)
    if announce:
        print(f"ambulo viewer: {viewer.url} (over SSH: ssh -L {viewer.port}:127.0.0.1:{viewer.port} <host>)",
              flush=True)
    return viewer


register_viewer("web", lambda world, port: serve(world, port))

__all__ = ["CameraPose", "DEFAULT_PORT", "WebViewer", "from_mjv_camera", "project_w", "serve"]
