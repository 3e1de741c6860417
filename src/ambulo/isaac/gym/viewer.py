"""Isaac Gym's viewer calls, headless: scripts that open a viewer run unchanged without a display."""

from __future__ import annotations

from .types import CameraProperties, Vec3


class Viewer:
    """A headless viewer: Isaac's viewer calls succeed and draw nothing; the window never closes."""

    def __init__(self, props: CameraProperties):
        self.props = props


class HeadlessViewer:
    """The viewer methods of the ``Gym`` object: they succeed and draw nothing."""

    def create_viewer(self, sim, props: CameraProperties) -> Viewer:
        return Viewer(props)

    def destroy_viewer(self, viewer: Viewer) -> None:
        """Nothing to close headless."""

    def query_viewer_has_closed(self, viewer: Viewer) -> bool:
        return False

    def draw_viewer(self, viewer: Viewer, sim, render_collision: bool = False) -> None:
        """Headless: nothing is drawn."""

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
        """No camera to move headless."""

    def clear_lines(self, viewer: Viewer) -> None:
        """No lines drawn headless."""

    def add_lines(self, viewer: Viewer, env, num_lines: int, vertices, colors) -> None:
        """No lines drawn headless."""

    def draw_env_rigid_contacts(self, viewer: Viewer, env, color: Vec3, scale: float, flag: bool) -> None:
        """No contacts drawn headless."""


__all__ = ["HeadlessViewer", "Viewer"]
