"""Typed ``KEY=VALUE`` overrides of any dataclass config (``--env-cfg``, ``--ppo-cfg``).

    cfg = apply_overrides(HumanoidWalkCfg(), ["episode_length_s=10", "friction_range=0.5,1.0",
                                              "physics.solver_iterations=50"])

Each VALUE is read as the field's annotated type, not guessed from its spelling:

=====================================  ==================================================
annotation                             accepted text
=====================================  ==================================================
``int`` / ``float`` / ``str``          ``50`` / ``0.1``, ``1e-3`` / ``cuda:0`` (quotes optional)
``bool``                               ``true``, ``false``, ``1``, ``0`` (any case)
``Literal["a", "b"]``                  one of the choices
``tuple[float, float]``, ``tuple[int, ...]``, ``list[...]``
                                       ``0.1,0.2`` or ``(0.1, 0.2)`` or ``[0.1, 0.2]``
``dict[str, float]``                   a Python literal ``{'alive': 1.0}``
``X | None``, ``Optional[X]``          ``none`` (any case), or an ``X``
``Enum`` subclass                      a member name
=====================================  ==================================================

A dotted key walks into nested dataclass fields (``physics.solver_iterations=50``) and into
entries of dict fields (``reward_weights.alive=2.0``: the entry must exist). An unknown key,
or a value that does not read as its type, raises ``OverrideError`` whose one-line message
names the key, the expected type and the closest valid keys or choices.
"""

from __future__ import annotations

import ast
import dataclasses
import difflib
import enum
import functools
import sys
import types
import typing
from collections.abc import Iterable, Mapping
from typing import Any, Literal, TypeVar, Union

T = TypeVar("T")

_NONE_WORDS = ("none", "null")
_TRUE_WORDS = ("true", "1")
_FALSE_WORDS = ("false", "0")


class OverrideError(ValueError):
    """A bad ``KEY=VALUE`` override. ``str(err)`` is one line: ``"<problem>; <fix>"``."""

    def __init__(self, key: str, problem: str, fix: str = ""):
        self.key, self.problem, self.fix = key, problem, fix
        super().__init__(f"{problem}; {fix}" if fix else problem)


class _BadValue(Exception):
    """A value that does not read as a type; ``hint`` names close choices or what to give,
    followed by an example where ``example``."""

    def __init__(self, hint: str = "", example: bool = False):
        super().__init__(hint)
        self.hint, self.example = hint, example


# ---------------------------------------------------------------------------------------------
# public functions


def apply_overrides(cfg: T, overrides: Iterable[str]) -> T:
    """A copy of dataclass ``cfg`` with ``["key=value", ...]`` applied in order, each value
    read as the annotated type of its field (see the module docstring); ``cfg`` is unchanged.

    Raises ``OverrideError`` on a malformed pair, an unknown key or a value that does not read
    as its field's type."""
    return _apply(cfg, overrides)[0]


def parse_overrides(cfg: Any, overrides: Iterable[str]) -> dict[str, Any]:
    """``["key=value", ...]`` -> ``{"key": typed value}``, checked against dataclass ``cfg``
    (dotted keys kept as given, e.g. ``{"physics.solver_iterations": 50}``). Applied in order
    by ``replace_dotted`` it gives ``apply_overrides(cfg, overrides)``."""
    return _apply(cfg, overrides)[1]


def _apply(cfg: T, overrides: Iterable[str]) -> tuple[T, dict[str, Any]]:
    _require_dataclass(cfg)
    if isinstance(overrides, str):
        raise TypeError("overrides is a list of 'key=value' strings, not one string")
    values: dict[str, Any] = {}
    for pair in overrides:
        key, value = parse_override(cfg, pair)  # checked against the earlier overrides applied
        cfg = _with_checked(cfg, key, value)
        values.pop(key, None)  # a repeated key moves to its last place
        values[key] = value
    return cfg, values


def parse_override(cfg: Any, pair: str) -> tuple[str, Any]:
    """One ``"key=value"`` -> ``(key, typed value)``, checked against dataclass ``cfg``."""
    _require_dataclass(cfg)
    key, sep, text = pair.partition("=")
    key = key.strip()
    if not sep or not key:
        example = _example_key(cfg)
        raise OverrideError(pair, f"expected KEY=VALUE, got {pair!r}", f"e.g. {example}")
    tp, current = _resolve(cfg, key)
    if _admits_none(tp) and text.strip().lower() in _NONE_WORDS:
        return key, None
    if dataclasses.is_dataclass(current) and not isinstance(current, type):
        keys = [f"{key}.{name}" for name in _field_names(current)]
        raise OverrideError(
            key, f"{key} is a {type(current).__name__}, not a single value",
            f"set its fields one by one: {', '.join(keys)}")
    try:
        return key, _parse(text, tp)
    except _BadValue as err:
        example = f"e.g. {key}={_format_value(current)} (its current value)"
        fix = f"{err.hint}, {example}" if err.example else (err.hint or example)
        raise OverrideError(key, f"bad value {text!r} for {key}: expected {type_name(tp)}", fix) from None


def replace_dotted(cfg: T, values: Mapping[str, Any], *, check_types: bool = False) -> T:
    """A copy of dataclass ``cfg`` with ``{"key": value}`` set, where a dotted key reaches a
    nested dataclass field or dict entry (``dataclasses.replace`` level by level).

    Values are taken as given (``parse_overrides`` makes them typed) unless ``check_types``:
    then each is checked against its field's annotation and widened where lossless (int to
    float, a JSON list to a tuple), raising ``OverrideError`` if it does not fit."""
    _require_dataclass(cfg)
    for key, value in values.items():
        tp, _ = _resolve(cfg, key)  # unknown keys fail with the same message as in parse_override
        if check_types:
            try:
                value = _coerce(value, tp)
            except _BadValue:
                raise OverrideError(key, f"bad value {value!r} for {key}: expected {type_name(tp)}",
                                    "pass a value of that type") from None
        cfg = _with_checked(cfg, key, value)
    return cfg


def _with_checked(cfg: T, key: str, value: Any) -> T:
    """``_with`` where a config's own check (its ``__post_init__``) refusing ``value`` becomes an
    ``OverrideError`` naming ``key``: ``physics.timestep_s=-1`` fails here, not later in a run."""
    try:
        return _with(cfg, key.split("."), value)
    except ValueError as err:
        why, fix = getattr(err, "why", None), getattr(err, "fix", None)
        if why is None or fix is None:  # a check without the (why, fix) split: keep its whole line
            why, fix = str(err).replace("\n", " "), f"give {key} another value"
        raise OverrideError(key, f"bad value {_format_value(value)} for {key}: {why}", fix) from None


def type_name(tp: Any) -> str:
    """``tuple[float, float]``, ``int | None``, ``one of 'a', 'b'``: a type as a user reads it."""
    if tp is Any or tp is _UNTYPED:
        return "a Python literal or text"
    if tp is type(None):
        return "none"
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is Literal:
        return "one of " + ", ".join(_format_value(a) for a in args)
    if origin is Union or origin is types.UnionType:
        return " | ".join(type_name(a) for a in args)
    if tp is bool:
        return "bool (true/false/1/0)"
    if origin is not None:
        name = getattr(origin, "__name__", str(origin))
        if not args:
            return name
        return f"{name}[{', '.join('...' if a is Ellipsis else _short_name(a) for a in args)}]"
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return "one of " + ", ".join(tp.__members__)
    return getattr(tp, "__name__", str(tp))


# ---------------------------------------------------------------------------------------------
# keys


_UNTYPED = object()
"""Stands for a field whose annotation could not be resolved: read as a Python literal."""


def _require_dataclass(cfg: Any) -> None:
    if not dataclasses.is_dataclass(cfg) or isinstance(cfg, type):
        raise TypeError(f"overrides apply to a dataclass instance, not {type(cfg).__name__}")


def _settable_fields(obj: Any) -> dict[str, dataclasses.Field]:
    return {f.name: f for f in dataclasses.fields(obj) if f.init}


def _field_names(obj: Any) -> list[str]:
    return list(_settable_fields(obj))


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    try:
        return typing.get_type_hints(cls)
    except Exception:  # some annotation names what is not importable at run time
        return {}


def _field_type(obj: Any, name: str) -> Any:
    """The resolved annotation of field ``name``; ``_UNTYPED`` if it cannot be resolved."""
    hints = _hints(type(obj))
    if name in hints:
        return hints[name]
    declared = _settable_fields(obj)[name].type
    if not isinstance(declared, str):
        return declared
    for klass in type(obj).__mro__:  # resolve this one annotation where it was written
        if name in vars(klass).get("__annotations__", {}):
            module = sys.modules.get(klass.__module__)
            try:
                return eval(declared, vars(module) if module else {}, dict(vars(klass)))
            except Exception:
                break
    return _UNTYPED


def _resolve(cfg: Any, key: str) -> tuple[Any, Any]:
    """(annotated type, current value) of dotted ``key`` in ``cfg``; ``OverrideError`` if
    some part of it does not exist."""
    obj, tp, done = cfg, type(cfg), []
    for part in key.split("."):
        where = ".".join(done)
        prefix = f"{where}." if where else ""
        owner = f"{type(obj).__name__} ({where})" if where else type(obj).__name__
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            fields = _field_names(obj)
            if part not in fields:
                raise OverrideError(key, f"unknown key {key!r} in {owner}",
                                    _close_or_all(part, fields, prefix))
            tp, obj = _field_type(obj, part), getattr(obj, part)
        elif isinstance(obj, dict):
            entry = _dict_entry(obj, part)
            if entry is _MISSING:
                entries = [str(k) for k in obj]
                fix = (_close_or_all(part, entries, prefix, "its entries: ") if entries else
                       f"{where} is empty: set it whole, e.g. {where}={{'name': 1.0}}")
                raise OverrideError(key, f"unknown key {key!r}: dict {where} has no entry {part!r}", fix)
            tp, obj = _dict_types(tp)[1], obj[entry]
        elif obj is None and done:
            raise OverrideError(key, f"{where} is none, so {key} cannot be set",
                                f"set {where} first, or edit the config in Python")
        else:
            raise OverrideError(key, f"{where} is a single value ({type_name(tp)}), not a config "
                                "with fields", f"use {where}=VALUE")
        done.append(part)
    return tp, obj


_MISSING = object()


def _dict_entry(mapping: dict, text: str) -> Any:
    """The key of ``mapping`` spelled ``text`` (keys compared as text), or ``_MISSING``."""
    return next((k for k in mapping if str(k) == text), _MISSING)


def _admits_none(tp: Any) -> bool:
    return tp is type(None) or (typing.get_origin(tp) in (Union, types.UnionType)
                                and type(None) in typing.get_args(tp))


def _dict_types(tp: Any) -> tuple[Any, Any]:
    args = typing.get_args(_strip_optional(tp))
    return (args[0], args[1]) if len(args) == 2 else (_UNTYPED, _UNTYPED)


def _strip_optional(tp: Any) -> Any:
    if typing.get_origin(tp) in (Union, types.UnionType):
        rest = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(rest) == 1:
            return rest[0]
    return tp


def _with(obj: Any, parts: list[str], value: Any) -> Any:
    head, rest = parts[0], parts[1:]
    if isinstance(obj, dict):
        entry = _dict_entry(obj, head)
        new = dict(obj)
        new[entry] = _with(obj[entry], rest, value) if rest else value
        return new
    new_value = _with(getattr(obj, head), rest, value) if rest else value
    return dataclasses.replace(obj, **{head: new_value})


def _close_or_all(word: str, choices: list[str], prefix: str = "", all_label: str = "valid keys: ") -> str:
    close = difflib.get_close_matches(word, choices, n=3, cutoff=0.6)
    if close:
        return "did you mean " + " or ".join(repr(prefix + c) for c in close) + "?"
    if all_label == "valid keys: ":
        return all_label + ", ".join(prefix + c for c in choices)
    return all_label + ", ".join(choices)


def _example_key(cfg: Any) -> str:
    for name in _field_names(cfg):
        value = getattr(cfg, name)
        if isinstance(value, (int, float, str)):
            return f"{name}={_format_value(value)}"
    return "key=value"


# ---------------------------------------------------------------------------------------------
# values


def _format_value(value: Any) -> str:
    """How a value is written on the command line."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple):
        return ",".join(_format_value(v) for v in value) if value else "()"
    if isinstance(value, enum.Enum):
        return value.name
    return repr(value)


def _short_name(tp: Any) -> str:
    return type_name(tp) if tp is not bool else "bool"


def _unquote(text: str) -> str:
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
        return text[1:-1]
    return text


def _parse(text: str, tp: Any) -> Any:
    """``text`` read as type ``tp``; ``_BadValue`` if it does not read as one."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    stripped = text.strip()
    if tp is Any or tp is _UNTYPED:
        try:
            return ast.literal_eval(stripped)
        except (ValueError, SyntaxError):
            return text
    if tp is type(None):
        if stripped.lower() in _NONE_WORDS:
            return None
        raise _BadValue()
    if origin is Union or origin is types.UnionType:
        if type(None) in args and stripped.lower() in _NONE_WORDS:
            return None
        errors = []
        for option in args:
            if option is type(None):
                continue
            try:
                return _parse(text, option)
            except _BadValue as err:
                errors.append(err)
        raise next((err for err in errors if err.hint), _BadValue())
    if origin is Literal:
        for choice in args:
            try:
                if _parse(text, type(choice)) == choice:
                    return choice
            except _BadValue:
                pass
        raise _BadValue(_did_you_mean(_unquote(stripped), [str(a) for a in args]))
    if tp is bool:
        word = stripped.lower()
        if word in _TRUE_WORDS:
            return True
        if word in _FALSE_WORDS:
            return False
        raise _BadValue(_did_you_mean(word, ["true", "false"]))
    if tp is int:
        try:
            return int(stripped)
        except ValueError:
            raise _BadValue() from None
    if tp is float:
        try:
            value = float(stripped)
        except ValueError:
            raise _BadValue() from None
        return _not_nan(value)
    if tp is str:
        return _unquote(stripped)
    if origin in (tuple, list) or tp in (tuple, list):
        return _parse_sequence(stripped, tp)
    if origin is dict or tp is dict:
        try:
            value = ast.literal_eval(stripped)
        except (ValueError, SyntaxError):
            raise _BadValue() from None
        return _coerce(value, tp)
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        name = _unquote(stripped)
        if name in tp.__members__:
            return tp.__members__[name]
        raise _BadValue(_did_you_mean(name, list(tp.__members__)))
    if dataclasses.is_dataclass(tp):
        raise _BadValue()
    if isinstance(tp, type):  # pathlib.Path and other types built from their text
        try:
            return tp(_unquote(stripped))
        except Exception:
            raise _BadValue() from None
    raise _BadValue()


def _not_nan(value: float) -> float:
    """``value`` unless NaN: no config field means anything by NaN, and it passes every ``<``
    check a config makes (``nan <= 0`` is false), to surface steps later as a crash."""
    if value != value:
        raise _BadValue("nan is not a number any setting can use: give a finite one", example=True)
    return value


def _did_you_mean(word: str, choices: list[str]) -> str:
    close = difflib.get_close_matches(word, choices, n=3, cutoff=0.5)
    if close:
        return "did you mean " + " or ".join(repr(c) for c in close) + "?"
    return "choose from " + ", ".join(repr(c) for c in choices)


def _element_types(tp: Any, n: int) -> list[Any]:
    """Types of the ``n`` elements of a tuple/list type; ``_BadValue`` on a wrong count."""
    origin, args = typing.get_origin(tp) or tp, typing.get_args(tp)
    if not args:
        return [_UNTYPED] * n
    if origin is list or (len(args) == 2 and args[1] is Ellipsis):
        return [args[0]] * n
    if args == ((),):  # tuple[()]
        args = ()
    if len(args) != n:
        raise _BadValue(f"give {len(args)} value{'s' if len(args) != 1 else ''}", example=True)
    return list(args)


def _parse_sequence(text: str, tp: Any) -> Any:
    """``0.1,0.2`` / ``(0.1, 0.2)`` / ``[0.1, 0.2]`` -> tuple or list of the element types."""
    container = tuple if (typing.get_origin(tp) or tp) is tuple else list
    try:  # a Python literal: nested sequences and quoted strings holding commas
        value = ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError):
        value = None
    if isinstance(value, (tuple, list)):
        try:
            return _coerce(value, tp)
        except _BadValue as err:
            if err.hint:
                raise
    # plain comma-separated text: each part read as its element type
    inner = text
    if len(inner) >= 2 and (inner[0], inner[-1]) in (("(", ")"), ("[", "]")):
        inner = inner[1:-1]
    parts = [p.strip() for p in inner.split(",")] if inner.strip() else []
    if len(parts) > 1 and parts[-1] == "":
        parts.pop()  # "0.1," is a one-element tuple
    types_ = _element_types(tp, len(parts))
    return container(_parse(p, t) for p, t in zip(parts, types_))


def _coerce(value: Any, tp: Any) -> Any:
    """A parsed Python literal checked (and widened: int -> float) against type ``tp``."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is Any or tp is _UNTYPED:
        return value
    if origin is Union or origin is types.UnionType:
        if value is None and type(None) in args:
            return None
        for option in args:
            if option is type(None):
                continue
            try:
                return _coerce(value, option)
            except _BadValue:
                pass
        raise _BadValue()
    if origin is Literal:
        for choice in args:
            if type(value) is type(choice) and value == choice:
                return choice
        raise _BadValue()
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise _BadValue()
    if tp is str:
        if isinstance(value, str):
            return value
        raise _BadValue()
    if tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise _BadValue()
    if tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return _not_nan(float(value))
        raise _BadValue()
    if origin in (tuple, list) or tp in (tuple, list):
        if not isinstance(value, (tuple, list)):
            raise _BadValue()
        container = tuple if (origin or tp) is tuple else list
        types_ = _element_types(tp, len(value))
        return container(_coerce(v, t) for v, t in zip(value, types_))
    if origin is dict or tp is dict:
        if not isinstance(value, dict):
            raise _BadValue()
        key_tp, value_tp = (args[0], args[1]) if len(args) == 2 else (_UNTYPED, _UNTYPED)
        return {_coerce(k, key_tp): _coerce(v, value_tp) for k, v in value.items()}
    if isinstance(value, str):
        return _parse(value, tp)
    if isinstance(tp, type) and isinstance(value, tp):
        return value
    raise _BadValue()


__all__ = ["OverrideError", "apply_overrides", "parse_override", "parse_overrides",
           "replace_dotted", "type_name"]
