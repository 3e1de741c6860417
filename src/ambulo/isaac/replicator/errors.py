"""One-line errors for Replicator names ambulo does not map, and the namespaces that raise them.

``rep.create``, ``rep.modify`` and the other Replicator sub-APIs are ``Namespace`` objects: an
attribute they lack fails at once with the hook's error (``IsaacNameError``: one line, what to
use instead), so ``ambulo run`` prints it as it prints a missing Isaac module.
"""

from __future__ import annotations

from ambulo.isaac.hook import IsaacNameError


def unsupported(what: str, hint: str) -> IsaacNameError:
    """``ambulo does not provide rep.<what> of omni.replicator.core; <hint>``."""
    return IsaacNameError(f"ambulo does not provide rep.{what} of omni.replicator.core; {hint}",
                          name="omni.replicator.core")


class Namespace:
    """A Replicator sub-API (``rep.create``): its functions, and one-line errors for the rest."""

    def __init__(self, name: str, functions: dict, hints: dict[str, str] | None = None):
        self._name, self._functions, self._hints = name, dict(functions), dict(hints or {})
        for key, value in functions.items():
            object.__setattr__(self, key, value)

    def __getattr__(self, attr: str):
        if attr.startswith("__"):
            raise AttributeError(attr)
        hint = self._hints.get(attr, f"rep.{self._name} provides {', '.join(sorted(self._functions))}")
        raise unsupported(f"{self._name}.{attr}", hint)

    def __dir__(self) -> list[str]:
        return sorted(self._functions)

    def __repr__(self) -> str:
        return f"<omni.replicator.core.{self._name} (ambulo)>"
