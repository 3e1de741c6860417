"""One check for every config dataclass: each field is checked when the config is built, by its
annotated type and the unit its name carries, so a new field is checked without new code.

    @dataclass(kw_only=True)
    class MyCfg(Checked):
        episode_length_s: float = 20.0                  # seconds: > 0 and finite
        friction_range: tuple[float, float] = (0.4, 1.2)  # a range: finite, low <= high
        yaw_rate_rad_s: tuple[float, float] = field(default=(-1.0, 1.0), metadata=rule(pair=True))

``MyCfg(episode_length_s=-5)`` raises ``InvalidValueError`` with one line naming the field, the
value, the rule and the fix::

    MyCfg.episode_length_s is -5: a duration must be > 0; pass seconds, e.g. episode_length_s=20.0

What every field gets, from its annotation:

- ``float`` (also inside tuples, lists and dict values): a real number (not a bool, text or a
  complex number), finite (NaN and inf mean nothing in a setting; ``rule(finite=False)`` allows
  inf where it means "no limit");
- ``int``: a whole number (not a bool or a float), >= 0 (a count, size, index or port), except
  seeds (``seed``, ``*_seed``) and ``rule(signed=True)``;
- ``bool``: a bool (``"false"`` is truthy); ``Literal[...]``: one of its choices; fixed-length
  tuples: that many entries.

What the name adds (``convention``; the first that applies):

==========================================  ===============================================
name                                        rule
==========================================  ===============================================
``*_probability``, ``*_fraction``           in [0, 1]
a ``range`` word, several numbers          a (low, high) pair with low <= high
a ``std``, ``sigma`` or ``noise`` word      >= 0 (0: no noise)
``*_m_s``, ``*_rad_s``, ``*_per_s``, ...    a velocity or rate of change: any sign
``*_s``                                     a duration: > 0
``*_hz``                                    a rate: > 0
``*_m`` with a size word (``radius``...)    a length: >= 0
==========================================  ===============================================

Field metadata changes a field's rule: ``field(..., metadata=rule(pair=True))`` for a range not
named so (``lin_vel_x_m_s``), ``rule(minimum=0)`` for a duration where 0 means "none",
``rule(signed=True)`` for a coordinate, ``UNCHECKED`` for a field this module cannot judge.

A config with rules across fields (``p2 >= p1``) checks them in its own ``__post_init__`` and
then calls ``super().__post_init__()``; ``RLEnv`` calls ``check_fields`` again, for a config
edited after it was built. This checks values only: it never changes them (no patching in
``__post_init__``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import sys
import types
import typing
from collections.abc import Mapping
from typing import Any, Literal, Union

import numpy as np

from .checks import InvalidValueError


@dataclasses.dataclass(frozen=True)
class Rule:
    """What a numeric field (or each number in it) must be, and the words of its error."""

    minimum: float | None = None
    strict: bool = False
    """True: the value must exceed ``minimum`` (> rather than >=)."""
    maximum: float | None = None
    finite: bool = True
    pair: bool = False
    """A (low, high) range: two entries, low <= high."""
    noun: str = "it"
    """What the value is, in the error: ``"a duration"``."""
    unit: str = "a finite number"
    """What to pass, in the fix: ``"seconds"``."""

    def bounds(self) -> str:
        if self.minimum is not None and self.maximum is not None:
            return f"in [{self.minimum:g}, {self.maximum:g}]"
        if self.minimum is not None:
            return f"{'>' if self.strict else '>='} {self.minimum:g}"
        return f"<= {self.maximum:g}" if self.maximum is not None else "finite"

    def admits(self, x: float) -> bool:
        if self.minimum is not None and (x < self.minimum or (self.strict and x == self.minimum)):
            return False
        return self.maximum is None or x <= self.maximum


ANY = Rule()
SECONDS = Rule(minimum=0.0, strict=True, noun="a duration", unit="seconds")
HERTZ = Rule(minimum=0.0, strict=True, noun="a rate", unit="Hz")
LENGTH = Rule(minimum=0.0, noun="a length", unit="metres")
FRACTION = Rule(minimum=0.0, maximum=1.0, noun="a probability or fraction", unit="a number in [0, 1]")
SPREAD = Rule(minimum=0.0, noun="a noise level", unit="a number >= 0 (0: none)")
RANGE = Rule(pair=True, noun="a range", unit="(low, high) with low <= high")
COUNT = Rule(minimum=0, noun="a count or size", unit="a whole number")
SIGNED_INT = Rule(unit="a whole number")

_VELOCITY_SUFFIXES = ("_m_s", "_m_s2", "_rad_s", "_deg_s", "_per_s", "_mps", "_mps2")
_SIZE_WORDS = frozenset({"size", "radius", "length", "width", "height", "distance", "clearance", "tolerance",
                         "gap", "resolution", "spread", "lookahead", "bob", "sway"})
_METADATA_KEY = "ambulo.check"


def convention(name: str, *, sequence: bool = False) -> Rule:
    """The rule the name of a numeric field implies (see the module docstring's table);
    ``sequence``: the field holds several numbers (only those can be a range)."""
    words = set(name.split("_"))
    if words & {"probability", "fraction"}:
        return FRACTION
    if sequence and "range" in words:
        return RANGE
    if words & {"std", "sigma", "noise"}:
        return SPREAD
    if name.endswith(_VELOCITY_SUFFIXES):
        return ANY
    if name.endswith("_s"):
        return SECONDS
    if name.endswith("_hz"):
        return HERTZ
    if name.endswith("_m") and words & _SIZE_WORDS:
        return LENGTH
    return ANY


def rule(*, pair: bool | None = None, minimum: float | None = None, strict: bool | None = None,
         maximum: float | None = None, finite: bool | None = None, signed: bool = False) -> dict:
    """Field metadata that changes the rule its name implies: ``field(default=(-1.0, 1.0),
    metadata=rule(pair=True))``. ``minimum`` alone sets ``>=``; ``signed`` drops the bounds."""
    changes: dict[str, Any] = {}
    if signed:
        changes.update(minimum=None, maximum=None, strict=False)
    if minimum is not None:
        changes.update(minimum=minimum, strict=bool(strict))
    elif strict is not None:
        changes["strict"] = strict
    for key, value in (("pair", pair), ("maximum", maximum), ("finite", finite)):
        if value is not None:
            changes[key] = value
    return {_METADATA_KEY: changes}


UNCHECKED = {_METADATA_KEY: None}
"""Field metadata: leave this field alone (a value this module cannot judge)."""


class Checked:
    """Base of a config dataclass whose fields are checked at construction (``check_fields``).

    A subclass with its own ``__post_init__`` calls ``super().__post_init__()`` in it."""

    def __post_init__(self) -> None:
        check_fields(self)


def check_fields(cfg: Any) -> None:
    """Check every field of dataclass ``cfg`` (and of the ``Checked`` configs nested in it) by its
    type and name; ``InvalidValueError`` (one line: field, value, why, fix) on the first bad one."""
    cls = type(cfg)
    hints = _hints(cls)
    for f in dataclasses.fields(cfg):
        if not f.init:
            continue
        value = getattr(cfg, f.name)
        if isinstance(value, Checked) and value is not cfg:
            check_fields(value)
            continue
        changes = f.metadata.get(_METADATA_KEY, {})
        if changes is None:
            continue
        tp = hints.get(f.name, Any)
        base = _int_rule(f.name) if _is_int_type(tp) else convention(f.name, sequence=_is_sequence_type(tp))
        field_rule = dataclasses.replace(base, **changes) if changes else base
        _Check(cls, f, field_rule, value, _admits_none(tp)).value(value, tp)


class _Check:
    """The check of one field: ``value(v, type)`` walks the value along its annotation."""

    def __init__(self, cls: type, f: dataclasses.Field, field_rule: Rule, given, optional: bool):
        self.cls, self.field, self.rule, self.given, self.optional = cls, f, field_rule, given, optional
        self.what = f"{cls.__name__}.{f.name}"

    def fail(self, value, why: str, fix: str | None = None) -> typing.NoReturn:
        """Refuse ``value`` (the field's value, or an entry of it: the message shows the whole)."""
        raise InvalidValueError(self.what, self.given, why, fix or self.fix(self.rule))

    def fix(self, value_rule: Rule) -> str:
        example = self.example(value_rule)
        unit = value_rule.unit + (" (or None)" if self.optional else "")
        return f"pass {unit}, e.g. {self.field.name}={example}" if example is not None else f"pass {unit}"

    def example(self, value_rule: Rule):
        """The field's default, as an example, if it is a number or numbers that pass."""
        f = self.field
        default = f.default if f.default is not dataclasses.MISSING else None
        if default is None and f.default_factory is not dataclasses.MISSING:
            try:
                default = f.default_factory()
            except Exception:
                return None
        if _is_real(default):
            return default if (math.isfinite(default) and value_rule.admits(default)) else None
        if isinstance(default, tuple) and default and all(_is_real(x) for x in default):
            return default
        return None

    def value(self, value, tp) -> None:
        origin, args = typing.get_origin(tp), typing.get_args(tp)
        if tp is Any or value is None and _admits_none(tp):
            if tp is Any and _is_real(value):  # unannotated: judge the number by its name
                self.number(value)
            return
        if origin in (Union, types.UnionType):
            options = [a for a in args if a is not type(None)]
            if len(options) == 1:
                self.value(value, options[0])
            return  # a union of several types: each is read where used
        if origin is Literal:
            if value not in args:
                self.fail(value, "not one of its choices", "pass one of " + ", ".join(map(repr, args)))
            return
        if tp is bool:
            if not isinstance(value, (bool, np.bool_)):
                self.fail(value, f"expected true or false, got {type(value).__name__}", "pass True or False")
            return
        if tp is int:
            self.integer(value)
            return
        if tp is float:
            self.number(value)
            return
        if origin is tuple or origin is list:
            self.sequence(value, tp, origin, args)
            return
        if origin is dict and len(args) == 2 and isinstance(value, Mapping):
            for item in value.values():
                self.value(item, args[1])

    def integer(self, value) -> None:
        int_rule = _int_rule(self.field.name) if self.rule is ANY else self.rule  # ints in a tuple
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
            self.fail(value, f"expected a whole number, got {type(value).__name__}", self.fix(int_rule))
        if not int_rule.admits(int(value)):
            self.fail(value, f"it must be {int_rule.bounds()}", self.fix(int_rule))

    def number(self, value) -> None:
        if not _is_real(value):
            self.fail(value, f"expected a real number, got {type(value).__name__}")
        x = float(value)
        if math.isnan(x) or (self.rule.finite and math.isinf(x)):
            self.fail(value, f"{self.rule.noun} must be finite")
        if not self.rule.admits(x):
            self.fail(value, f"{self.rule.noun} must be {self.rule.bounds()}")

    def sequence(self, value, tp, origin, args) -> None:
        if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list, np.ndarray)):
            self.fail(value, f"expected {_type_words(tp)}, got {type(value).__name__}")
        items = list(value)
        if origin is tuple and args and args[-1] is not Ellipsis:
            if len(items) != len(args):
                self.fail(value, f"expected {len(args)} values, got {len(items)}")
            types_ = list(args)
        else:
            types_ = [args[0] if args else Any] * len(items)
        pair = self.rule.pair and all(t in (float, int) for t in types_)
        if pair and len(items) != 2:
            self.fail(value, f"a range is 2 values (low, high), got {len(items)}")
        for item, item_tp in zip(items, types_):
            self.value(item, item_tp)
        if pair and items[0] > items[1]:
            self.fail(value, "the low end is above the high end")


def _int_rule(name: str) -> Rule:
    return SIGNED_INT if name == "seed" or name.endswith("_seed") else COUNT


def _is_int_type(tp) -> bool:
    if typing.get_origin(tp) in (Union, types.UnionType):
        options = [a for a in typing.get_args(tp) if a is not type(None)]
        return len(options) == 1 and options[0] is int
    return tp is int


def _is_sequence_type(tp) -> bool:
    if typing.get_origin(tp) in (Union, types.UnionType):
        return any(_is_sequence_type(a) for a in typing.get_args(tp))
    return typing.get_origin(tp) in (tuple, list) or tp in (tuple, list)


def _is_real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _admits_none(tp) -> bool:
    return typing.get_origin(tp) in (Union, types.UnionType) and type(None) in typing.get_args(tp)


def _type_words(tp) -> str:
    args = typing.get_args(tp)
    if args and args[-1] is not Ellipsis and typing.get_origin(tp) is tuple:
        return f"{len(args)} values"
    return "a sequence of values"


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    """Resolved field annotations of ``cls``; a field whose annotation names what is not
    importable at run time resolves to ``Any`` (judged by its value)."""
    try:
        return typing.get_type_hints(cls)
    except Exception:
        pass
    hints: dict[str, Any] = {}
    for klass in reversed(cls.__mro__):
        module = vars(sys.modules.get(klass.__module__, types.ModuleType("_")))
        for name, annotation in vars(klass).get("__annotations__", {}).items():
            try:
                hints[name] = eval(annotation, module, dict(vars(klass))) if isinstance(annotation, str) \
                    else annotation
            except Exception:
                hints[name] = Any
    return hints


__all__ = ["ANY", "COUNT", "FRACTION", "HERTZ", "LENGTH", "RANGE", "SECONDS", "SPREAD", "UNCHECKED", "Checked",
           "Rule", "check_fields", "convention", "rule"]
