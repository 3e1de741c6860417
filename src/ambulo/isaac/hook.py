"""The import hook that answers Isaac Sim module names with ambulo objects.

A ``sys.meta_path`` finder claims every module under ``isaacsim``, ``omni`` and ``carb``
while ``isaac_names()`` is active. A module in the table (``names.MODULES``) becomes an
``IsaacModule`` whose attributes resolve lazily to ambulo objects, and whose submodules are
attributes too (imported on first use, as Kit has them loaded); any other module under
those roots, or a name a table module lacks, fails at the import line with an
``IsaacNameError`` that says what ambulo offers instead. It also answers the modules Isaac
adds to other packages (``names.INJECTED``: ``pxr.PhysxSchema``). Leaving the context removes
the finder and the modules it made, so the names never leak into the rest of the process.
"""

from __future__ import annotations

import contextlib
import difflib
import importlib
import importlib.abc
import importlib.machinery
import os
import sys
import types
from collections.abc import Iterator

from . import names


class IsaacNameError(ImportError):
    """An Isaac Sim module or name that ambulo does not provide; the message says the alternative."""


class IsaacModule(types.ModuleType):
    """An Isaac module name whose attributes are ambulo objects, imported on first use."""

    def __getattr__(self, attr: str):
        if attr.startswith("__"):
            raise AttributeError(attr)
        module = self.__name__
        target = names.MODULES.get(module, {}).get(attr)
        if target is not None:
            ambulo_module, _, ambulo_attr = target.partition(":")
            value = getattr(importlib.import_module(ambulo_module), ambulo_attr)
            setattr(self, attr, value)  # later lookups skip __getattr__
            return value
        if names.is_known(f"{module}.{attr}"):
            # In Kit every extension's modules are loaded before a script runs, so `import omni`
            # then `omni.usd.get_context()` works; here the submodule is imported on first use
            # (the import system then sets it on this module, so later lookups skip this).
            return importlib.import_module(f"{module}.{attr}")
        raise IsaacNameError(missing_name_message(module, attr), name=module)

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(names.MODULES.get(self.__name__, {}))
                      | set(names.submodules(self.__name__)))


def missing_name_message(module: str, attr: str) -> str:
    """One line: ``module.attr`` is not provided, and what to use instead."""
    hint = names.HINTS.get(attr)
    if hint is None:
        provided = sorted(names.MODULES.get(module, {}))
        close = difflib.get_close_matches(attr, provided, n=2)
        hint = (f"did you mean {' or '.join(close)}?" if close else
                f"{module} provides {', '.join(provided)}" if provided else
                "see docs/isaac-compatibility.md for what ambulo provides")
    return f"ambulo does not provide {attr!r} from the Isaac module {module}; {hint}"


def missing_module_message(module: str) -> str:
    """One line: the Isaac module is not provided, and the closest ones that are."""
    close = difflib.get_close_matches(module, list(names.MODULES), n=2, cutoff=0.75)
    hint = (f"did you mean {' or '.join(close)}?" if close else
            "see docs/isaac-compatibility.md for the Isaac modules ambulo provides")
    return f"ambulo does not provide the Isaac module {module}; {hint}"


class _Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, fullname: str, path=None, target=None):
        if fullname in names.INJECTED:
            leaf = fullname.rsplit(".", 1)[1]
            if any(os.path.exists(os.path.join(folder, leaf)) for folder in path or ()):
                return None  # the package has its own (a USD build with PhysX's schemas)
            return importlib.machinery.ModuleSpec(fullname, self)
        if fullname.split(".")[0] not in names.ROOTS:
            return None
        if not names.is_known(fullname):
            raise IsaacNameError(missing_module_message(fullname), name=fullname)
        return importlib.machinery.ModuleSpec(fullname, self, is_package=names.is_package(fullname))

    def create_module(self, spec):
        if spec.name in names.INJECTED:
            return importlib.import_module(names.INJECTED[spec.name]).as_module(spec.name)
        return IsaacModule(spec.name)

    def exec_module(self, module) -> None:
        if module.__name__ not in names.INJECTED:
            module.__all__ = sorted(names.MODULES.get(module.__name__, {}))
        if module.__name__ == "isaacgym":
            from .gym.session import on_isaacgym_import

            on_isaacgym_import()


@contextlib.contextmanager
def isaac_names() -> Iterator[None]:
    """Make Isaac Sim's module names importable inside the block (and only there)."""
    shadowed = [m for m in sys.modules if m.split(".")[0] in names.ROOTS]
    if shadowed:
        raise RuntimeError(f"{shadowed[0]} is already imported (a real Isaac Sim install?); "
                           "run the script with Isaac Sim's python, or in a fresh process")
    finder = _Finder()
    sys.meta_path.insert(0, finder)
    try:
        yield
    finally:
        sys.meta_path.remove(finder)
        for name in [m for m in sys.modules if m.split(".")[0] in names.ROOTS]:
            del sys.modules[name]
        for name, ours in names.INJECTED.items():
            if isinstance(sys.modules.get(name), types.ModuleType) and not hasattr(sys.modules[name], "__file__"):
                del sys.modules[name]
                parent, _, leaf = name.rpartition(".")
                if parent in sys.modules and hasattr(sys.modules[parent], leaf):
                    delattr(sys.modules[parent], leaf)
            if ours in sys.modules:
                sys.modules[ours].restore()


__all__ = ["IsaacModule", "IsaacNameError", "isaac_names", "missing_module_message", "missing_name_message"]
