"""Kit's ``omni.kit.commands`` and ``omni.kit.undo``: the command registry Isaac scripts execute by name.

``omni.kit.commands.execute("CreatePrim", prim_type="Cube", prim_path="/World/Cube")`` looks the
command class up by name (with or without the ``Command`` suffix, as Kit does), builds it with
the keyword arguments, runs its ``do()`` and returns Kit's ``(True, result)`` tuple. Commands
with an ``undo()`` go on the undo stack (``omni.kit.undo.undo()``/``redo()``); commands executed
inside another command's ``do()`` are part of it, as in Kit.

The built-in commands author the World's USD stage as Kit's do (``usd_commands``,
``physics_commands``, ``urdf_importer``); scripts register their own ``Command`` subclasses
with ``register`` or ``register_all_commands_in_module``. An unknown name fails in one line
that lists the commands ambulo has (Kit logs it and returns ``(False, None)``, which a script
never checks).
"""

from __future__ import annotations

import contextlib
import importlib
import inspect
import sys
from typing import Any

from .hook import IsaacNameError

_BUILTINS = ("ambulo.isaac.usd_commands", "ambulo.isaac.physics_commands", "ambulo.isaac.urdf_importer")
"""Modules whose Command subclasses are registered before the first lookup (Kit's loaded extensions)."""


class UnknownCommandError(IsaacNameError):
    """A Kit command name that no registered command answers."""


class Command:
    """Base class of Kit commands: ``__init__`` takes the keyword arguments of ``execute``, ``do()``
    performs the command and returns its result; define ``undo()`` to make it undoable."""

    def do(self):
        raise NotImplementedError(f"{type(self).__name__} has no do()")

    def modify_callback_info(self, cb_type: str, cmd_args: dict[str, Any]) -> dict[str, Any]:
        return cmd_args


_registry: dict[str, type] = {}
_builtins_loaded = False
_undo_stack: list[Command] = []
_redo_stack: list[Command] = []
_depth = 0
"""How many commands are running: a command executed inside another's do() is part of it."""


def _key(name: str) -> str:
    name = name.rsplit(".", 1)[-1]
    return name[: -len("Command")] if name.endswith("Command") and name != "Command" else name


def _commands() -> dict[str, type]:
    global _builtins_loaded
    if not _builtins_loaded:
        _builtins_loaded = True
        for module in _BUILTINS:
            register_all_commands_in_module(importlib.import_module(module))
    return _registry


def register(command_class: type) -> type:
    """Register ``command_class`` under its name without the ``Command`` suffix (a later class of
    the same name replaces it, as reloading an extension does)."""
    if not (isinstance(command_class, type) and issubclass(command_class, Command)):
        raise TypeError(f"{command_class!r} is not a subclass of omni.kit.commands.Command; derive it from Command")
    _commands()[_key(command_class.__name__)] = command_class
    return command_class


def unregister(command_class: type) -> None:
    if _commands().get(_key(command_class.__name__)) is command_class:
        del _registry[_key(command_class.__name__)]


def _classes_of(module) -> list[type]:
    module = sys.modules[module] if isinstance(module, str) else module
    return [value for value in vars(module).values() if isinstance(value, type) and issubclass(value, Command)
            and value is not Command and value.__module__ == module.__name__]


def register_all_commands_in_module(module) -> None:
    """Register every Command subclass defined in ``module`` (a module or its name)."""
    for command_class in _classes_of(module):
        _registry[_key(command_class.__name__)] = command_class


def unregister_module_commands(module) -> None:
    for command_class in _classes_of(module):
        unregister(command_class)


def get_command_class(name: str) -> type | None:
    """The command class registered under ``name`` (``"CreatePrim"`` or ``"CreatePrimCommand"``), or None."""
    return _commands().get(_key(name))


def get_commands() -> dict[str, dict[str, type]]:
    """Command name -> {module name: class}, as Kit lists them."""
    return {name: {cls.__module__: cls} for name, cls in sorted(_commands().items())}


def get_commands_list() -> list[type]:
    return [cls for _, cls in sorted(_commands().items())]


def get_command_doc(name: str) -> str:
    return inspect.getdoc(_command_class(name)) or ""


def get_command_parameters(name: str) -> list[tuple[str, Any]]:
    """(name, default) of each constructor parameter of the command (``inspect.Parameter.empty``: none)."""
    params = list(inspect.signature(_command_class(name).__init__).parameters.values())[1:]
    return [(p.name, p.default) for p in params if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def _command_class(name: str) -> type:
    command_class = get_command_class(str(name))
    if command_class is None:
        raise UnknownCommandError(
            f"ambulo has no Kit command {name!r}; it provides {', '.join(sorted(_commands()))} "
            "(or register your own omni.kit.commands.Command subclass)", name=str(name))
    return command_class


def create(name: str, **kwargs) -> Command:
    """The command ``name`` built with ``kwargs``, not executed."""
    command_class = _command_class(name)
    try:
        inspect.signature(command_class).bind(**kwargs)
    except TypeError as err:
        params = ", ".join(p for p, _ in get_command_parameters(name))
        raise TypeError(f"command {name!r}: {err}; it takes {params}") from None
    return command_class(**kwargs)


def execute(name: str, **kwargs) -> tuple[bool, Any]:
    """Build the command ``name`` with ``kwargs``, run its ``do()``; returns ``(True, result)``.

    Errors raised by the command propagate (Kit logs them and returns ``(False, None)``)."""
    global _depth
    command = create(name, **kwargs)
    _depth += 1
    try:
        result = command.do()
    finally:
        _depth -= 1
    if _depth == 0 and callable(getattr(command, "undo", None)):
        _undo_stack.append(command)
        _redo_stack.clear()
    return True, result


def set_logging_enabled(enabled: bool) -> None:
    """Kit prints every executed command when enabled; ambulo never does."""


# -- omni.kit.undo ------------------------------------------------------------
def undo() -> bool:
    """Undo the last executed command; False if there is none."""
    if not _undo_stack:
        return False
    command = _undo_stack.pop()
    command.undo()
    _redo_stack.append(command)
    return True


def redo() -> bool:
    """Do again the last undone command; False if there is none."""
    if not _redo_stack:
        return False
    command = _redo_stack.pop()
    command.do()
    _undo_stack.append(command)
    return True


def can_undo() -> bool:
    return bool(_undo_stack)


def can_redo() -> bool:
    return bool(_redo_stack)


def get_undo_stack() -> list[Command]:
    return list(_undo_stack)


def get_redo_stack() -> list[Command]:
    return list(_redo_stack)


def clear_stack() -> None:
    _undo_stack.clear()
    _redo_stack.clear()


clear_history = clear_stack


@contextlib.contextmanager
def group():
    """Commands executed in the block undo together (here each stays its own entry)."""
    yield


__all__ = ["Command", "create", "execute", "get_command_class", "get_command_doc", "get_command_parameters",
           "get_commands", "get_commands_list", "register", "register_all_commands_in_module",
           "set_logging_enabled", "unregister", "unregister_module_commands"]
