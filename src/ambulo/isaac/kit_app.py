"""The parts of Kit's ``omni.kit.app`` that Isaac scripts use: ``get_app().update()`` and extensions."""

from __future__ import annotations

import logging

from .app import advance_playing_world

_log = logging.getLogger("ambulo.isaac")


class ExtensionManager:
    """Kit extensions do not exist in ambulo: enabling one is recorded and logged, nothing more."""

    def __init__(self):
        self.enabled: set[str] = set()

    def set_extension_enabled_immediate(self, name: str, enabled: bool) -> bool:
        (self.enabled.add if enabled else self.enabled.discard)(name)
        _log.info("Kit extension %s %s: ambulo has no Kit extensions; its features are built in",
                  name, "enabled" if enabled else "disabled")
        return True

    set_extension_enabled = set_extension_enabled_immediate

    def is_extension_enabled(self, name: str) -> bool:
        return name in self.enabled


class App:
    def __init__(self):
        self._extensions = ExtensionManager()
        self._updates = 0

    def update(self) -> None:
        """One app frame: a playing World advances by one rendering step."""
        self._updates += 1
        advance_playing_world()

    def get_update_number(self) -> int:
        return self._updates

    def get_extension_manager(self) -> ExtensionManager:
        return self._extensions

    def is_running(self) -> bool:
        return True


_APP = App()


def get_app() -> App:
    return _APP


__all__ = ["App", "ExtensionManager", "get_app"]
