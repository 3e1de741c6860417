"""Isaac Gym's viewer calls, headless: scripts that open a viewer run unchanged without a display.

Under ``ambulo run --viewer web`` (``web_viewers``) a script's viewer is also a web viewer
(``ambulo.viewer``): the browser shows what Isaac Gym's window would, the sim at each
``draw_viewer`` (a script that never draws it shows nothing, in Isaac Gym as here), with
pause/step and the speed on the page (1x: what ``sync_frame_time`` does in Isaac Gym).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import numpy as np

from .types import CameraProperties, Vec3


class Viewer:
    """A headless viewer: Isaac's viewer calls succeed and the window never closes; its camera
    (``viewer_camera_look_at``) renders env 0 when a script asks for an image
    (``write_viewer_image_to_file``), with MuJoCo's offscreen renderer."""

    def __init__(self, props: CameraProperties, sim):
        self.props = props
        self.sim = sim
        self.position = np.array([3.0, 3.0, 2.0])
        self.target = np.zeros(3)
        self._renderer = None
        self.web: _WebView | None = _WebView(sim, *_WEB[-1]) if _WEB else None
        """The web viewer's side of this viewer (``ambulo run --viewer web``), else None."""

    def render_rgb(self) -> np.ndarray:
        """(height, width, 3) uint8: env 0 (its own world, so at its origin) seen from the camera."""
        import mujoco

        from ambulo.render.offscreen import OffscreenRenderer

        engine = self.sim.engine
        if engine is None:
            raise RuntimeError("isaacgym: prepare_sim before writing viewer images")
        width, height = min(self.props.width, 1280), min(self.props.height, 960)  # the scene's offscreen buffer
        if self._renderer is None:
            self._renderer = OffscreenRenderer(engine.model, width, height)
        origin = self.sim.envs[0].origin
        offset = self.position - self.target
        camera = mujoco.MjvCamera()
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        camera.lookat[:] = self.target - origin
        camera.distance = float(np.linalg.norm(offset))
        camera.azimuth = float(np.degrees(np.arctan2(offset[1], offset[0]))) + 180.0
        camera.elevation = -float(np.degrees(np.arcsin(offset[2] / max(camera.distance, 1e-9))))
        self._renderer.update_view(engine.model, engine.get_data(0), camera)
        return self._renderer.render_rgb()


class HeadlessViewer:
    """The viewer methods of the ``Gym`` object: they succeed and draw nothing."""

    def create_viewer(self, sim, props: CameraProperties) -> Viewer:
        return Viewer(props, sim)

    def destroy_viewer(self, viewer: Viewer) -> None:
        """Headless: nothing to close; a web viewer stops serving."""
        if viewer.web is not None:
            viewer.web.close()

    def query_viewer_has_closed(self, viewer: Viewer) -> bool:
        return False

    def draw_viewer(self, viewer: Viewer, sim, render_collision: bool = False) -> None:
        """Headless: nothing is drawn; a web viewer gets the sim's state (and holds it while paused)."""
        if viewer.web is not None:
            viewer.web.draw()

    def step_graphics(self, sim) -> None:
        """Headless: no graphics state to update."""

    def sync_frame_time(self, sim) -> None:
        """Headless runs as fast as it can (Isaac's viewer waits for real time here)."""

    def poll_viewer_events(self, viewer: Viewer) -> None:
        """No window, no events."""

    def query_viewer_action_events(self, viewer: Viewer) -> list:
        return []

    def subscribe_viewer_keyboard_event(self, viewer: Viewer, key: int, action: str) -> None:
        """No keyboard headless."""

    def subscribe_viewer_mouse_event(self, viewer: Viewer, button: int, action: str) -> None:
        """No mouse headless."""

    def viewer_camera_look_at(self, viewer: Viewer, env, position: Vec3, target: Vec3) -> None:
        """Aim the camera that ``write_viewer_image_to_file`` renders (sim frame; ``env`` as Isaac's:
        positions relative to that env's origin, or the sim frame for None)."""
        origin = np.zeros(3) if env is None else env.origin
        viewer.position = position.as_array() + origin
        viewer.target = target.as_array() + origin

    def write_viewer_image_to_file(self, viewer: Viewer, path: str) -> bool:
        """Render env 0 from the viewer camera to the image ``path`` (PNG, ...)."""
        import imageio.v3 as iio

        iio.imwrite(path, viewer.render_rgb())
        return True

    def clear_lines(self, viewer: Viewer) -> None:
        """No lines drawn headless."""

    def add_lines(self, viewer: Viewer, env, num_lines: int, vertices, colors) -> None:
        """No lines drawn headless."""

    def draw_env_rigid_contacts(self, viewer: Viewer, env, color: Vec3, scale: float, flag: bool) -> None:
        """No contacts drawn headless."""


_WEB: list[tuple[int, list]] = []
"""(port, web views opened) of each ``web_viewers`` block, innermost last."""


@contextlib.contextmanager
def web_viewers(port: int) -> Iterator[list]:
    """Inside the block every ``create_viewer`` also serves a web viewer (from port ``port``);
    each is closed when the block ends, however it ends."""
    opened: list[_WebView] = []
    _WEB.append((port, opened))
    try:
        yield opened
    finally:
        _WEB.pop()
        for view in opened:
            view.close()


class _WebView:
    """A gym ``Sim`` as the web viewer watches an owner of a ``Simulation`` (``.sim``: its engine,
    worlds and components). The web viewer opens at the first ``draw`` after ``prepare_sim``
    (scripts create their viewer before or after their envs and ``prepare_sim``), then each
    ``draw`` is its step: ``update`` with the simulated time since the last one."""

    def __init__(self, gym_sim, port: int, opened: list):
        self.gym_sim, self.port = gym_sim, port
        self.components: dict = {}
        self.viewer = None
        self._drawn_frames = 0
        self._closed = False
        opened.append(self)

    @property
    def sim(self):  # the web viewer reads ``owner.sim``: this object is both
        return self

    @property
    def engine(self):
        return self.gym_sim.engine

    @property
    def num_worlds(self) -> int:
        return len(self.gym_sim.envs)

    def add(self, component):
        self.components[component.name] = component
        return component

    def draw(self) -> None:
        if self._closed or self.engine is None:
            return
        if self.viewer is None:
            from ambulo.viewer import serve

            self.viewer = serve(self, port=self.port)
            self._drawn_frames = self.gym_sim.frame_count
        frames = self.gym_sim.frame_count - self._drawn_frames
        self._drawn_frames = self.gym_sim.frame_count
        for component in list(self.components.values()):
            component.update(frames * self.gym_sim.params.dt)

    def close(self) -> None:
        self._closed = True
        if self.viewer is not None:
            self.viewer.close()


__all__ = ["HeadlessViewer", "Viewer", "web_viewers"]
