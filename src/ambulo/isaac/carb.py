"""The parts of Kit's ``carb`` module that Isaac scripts use: settings and logging.

``carb.settings.get_settings()`` is a process-wide key/value store with Kit's path-like keys;
``carb.log_*`` go to Python's logging under ``carb``. Which settings keys ambulo honours is
listed in ``HONOURED_KEYS``; other keys are stored and read back but change nothing.
"""

from __future__ import annotations

import logging
import types
from typing import Any

_log = logging.getLogger("carb")

HONOURED_KEYS: dict[str, str] = {}
"""Settings key -> what it changes in ambulo (filled by the modules that read them)."""


class Settings:
    """Kit's settings interface over a dict."""

    def __init__(self):
        self._values: dict[str, Any] = {}

    def get(self, path: str) -> Any:
        return self._values.get(path)

    def set(self, path: str, value: Any) -> None:
        self._values[path] = value

    set_bool = set_int = set_float = set_string = set_default = set
    get_as_bool = get_as_int = get_as_float = get_as_string = get

    def destroy_item(self, path: str) -> None:
        self._values.pop(path, None)


_SETTINGS = Settings()


def get_settings() -> Settings:
    return _SETTINGS


settings = types.SimpleNamespace(get_settings=get_settings, ISettings=Settings)
"""``carb.settings``: ``carb.settings.get_settings()`` is the one store."""


def log_info(msg: str) -> None:
    _log.info(msg)


def log_warn(msg: str) -> None:
    _log.warning(msg)


def log_error(msg: str) -> None:
    _log.error(msg)


def log_verbose(msg: str) -> None:
    _log.debug(msg)


class Float3(tuple):
    """``carb.Float3(x, y, z)``: a 3-tuple."""

    def __new__(cls, x: float = 0.0, y: float = 0.0, z: float = 0.0):
        return super().__new__(cls, (float(x), float(y), float(z)))


class Float4(tuple):
    """``carb.Float4(x, y, z, w)``: a 4-tuple."""

    def __new__(cls, x: float = 0.0, y: float = 0.0, z: float = 0.0, w: float = 0.0):
        return super().__new__(cls, (float(x), float(y), float(z), float(w)))


__all__ = ["Float3", "Float4", "HONOURED_KEYS", "Settings", "get_settings", "log_error", "log_info",
           "log_verbose", "log_warn", "settings"]
