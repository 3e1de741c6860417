"""Checks of user-given values at the boundary (constructors, public setters, config dataclasses).

Each check returns the value in its canonical type (a ``float``, an ``int``, a tuple) or raises
``InvalidValueError``, whose message is one line that names the value, what is wrong and how to
fix it::

    physics_dt is -0.01: a time step must be positive and finite; pass seconds, e.g. 0.005

These checks run on Python scalars and short sequences when objects are built or set up. They
are not for per-step batched tensors: reading a CUDA tensor's values forces a GPU->CPU sync, so
hot paths check shapes and dtypes only (``check_real_dtype``).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

import numpy as np
import torch


class InvalidValueError(ValueError):
    """A bad user value. ``str(err)`` is one line ``"<what> is <value>: <why>; <fix>"``."""

    def __init__(self, what: str, value, why: str, fix: str):
        self.what, self.value, self.why, self.fix = what, value, why, fix
        super().__init__(f"{what} is {_show(value)}: {why}; {fix}")


class Described(str):
    """A description that stands for the value in a message (``"of shape (3,)"``), not quoted."""


def _show(value) -> str:
    """``value`` as the message shows it: short, with strings quoted (but not ``Described``)."""
    text = repr(value) if isinstance(value, (str, bytes)) and not isinstance(value, Described) else str(value)
    text = " ".join(text.split())
    return text if len(text) <= 60 else text[:57] + "..."


def _is_real_number(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def check_real(what: str, value, fix: str) -> float:
    """``value`` as a finite float; refuses text, bools, complex numbers, NaN and inf."""
    if isinstance(value, (np.ndarray, torch.Tensor)) and value.ndim == 0:
        value = value.item()
    if not _is_real_number(value):
        raise InvalidValueError(what, value, f"expected a real number, got {type(value).__name__}", fix)
    value = float(value)
    if not math.isfinite(value):
        raise InvalidValueError(what, value, "it must be finite", fix)
    return value


def check_positive(what: str, value, fix: str, *, allow_zero: bool = False) -> float:
    """``value`` as a finite float > 0 (>= 0 with ``allow_zero``)."""
    value = check_real(what, value, fix)
    if value < 0 or (value == 0 and not allow_zero):
        raise InvalidValueError(what, value, "it must be " + (">= 0" if allow_zero else "> 0"), fix)
    return value


def check_int(what: str, value, fix: str, *, minimum: int | None = None) -> int:
    """``value`` as an int (Python or numpy integer, not a bool, a float or text), >= ``minimum``."""
    if isinstance(value, (np.ndarray, torch.Tensor)) and value.ndim == 0:
        value = value.item()  # a 0-d integer array reads as its int; a float one is refused below
    if not isinstance(value, numbers.Integral) or isinstance(value, bool):
        raise InvalidValueError(what, value, f"expected a whole number, got {type(value).__name__}", fix)
    value = int(value)
    if minimum is not None and value < minimum:
        raise InvalidValueError(what, value, f"it must be >= {minimum}", fix)
    return value


def check_vector(what: str, value, length: int, fix: str) -> tuple[float, ...]:
    """``value`` as a tuple of ``length`` finite floats."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray, torch.Tensor)):
        raise InvalidValueError(what, value, f"expected {length} numbers, got {type(value).__name__}", fix)
    items = list(np.asarray(value.detach().cpu() if isinstance(value, torch.Tensor) else value,
                            dtype=object).reshape(-1))
    if len(items) != length:
        raise InvalidValueError(what, value, f"expected {length} numbers, got {len(items)}", fix)
    out = []
    for item in items:
        if not _is_real_number(item) or not math.isfinite(float(item)):
            raise InvalidValueError(what, value, f"every entry must be a finite real number, not {item!r}",
                                    fix)
        out.append(float(item))
    return tuple(out)


def check_quat(what: str, value) -> tuple[float, float, float, float]:
    """``value`` as a finite (w, x, y, z) tuple of non-zero norm (not normalized here)."""
    fix = "pass a (w, x, y, z) quaternion such as (1, 0, 0, 0)"
    quat = check_vector(what, value, 4, fix)
    if math.hypot(*quat) < 1e-9:
        raise InvalidValueError(what, value, "a zero quaternion is no rotation", fix)
    return quat


def check_range(what: str, value, fix: str, *, minimum: float = 0.0) -> tuple[float, float]:
    """``value`` as a (low, high) pair of finite floats with ``minimum <= low < high``."""
    low, high = check_vector(what, value, 2, fix)
    if low < minimum:
        raise InvalidValueError(what, value, f"the low end must be >= {minimum:g}", fix)
    if not low < high:
        raise InvalidValueError(what, value, "the low end must be below the high end", fix)
    return low, high


def check_real_dtype(what: str, value, fix: str, *, allow_bool: bool = True):
    """Refuse text and complex arrays/tensors (and bools unless ``allow_bool``) by their dtype
    alone (no value is read, so a CUDA tensor is not synced); returns ``value`` unchanged."""
    bad_scalars = (str, bytes, complex, np.complexfloating) + (() if allow_bool else (bool, np.bool_))
    if isinstance(value, (str, bytes)):
        raise InvalidValueError(what, value, "expected numbers, got text", fix)
    if isinstance(value, torch.Tensor):
        if value.is_complex() or (not allow_bool and value.dtype == torch.bool):
            raise InvalidValueError(what, Described(f"a {value.dtype} tensor"), "expected real numbers", fix)
        return value
    if isinstance(value, (list, tuple)):
        bad = next((v for v in value if isinstance(v, bad_scalars)), None)
        if bad is not None:
            raise InvalidValueError(what, value, f"expected real numbers, got {type(bad).__name__} {bad!r}", fix)
        return value
    if isinstance(value, bad_scalars):
        raise InvalidValueError(what, value, f"expected real numbers, got {type(value).__name__}", fix)
    if isinstance(value, np.ndarray) and value.dtype.kind not in ("biuf" if allow_bool else "iuf"):
        raise InvalidValueError(what, Described(f"a {value.dtype} array"), "expected real numbers", fix)
    return value


def check_all_finite(what: str, tensor: torch.Tensor, fix: str) -> torch.Tensor:
    """Refuse NaN or inf in ``tensor`` when it lives on the CPU (reading it is free there); a
    CUDA tensor is passed through unread, to keep the step free of a GPU->CPU sync."""
    if tensor.device.type == "cpu" and tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
        bad = tensor[~torch.isfinite(tensor)].reshape(-1)[0].item()
        shown = "NaN" if math.isnan(bad) else str(bad)
        raise InvalidValueError(what, Described(f"{shown} at some entries"), "every entry must be finite", fix)
    return tensor


__all__ = ["Described", "InvalidValueError", "check_all_finite", "check_int", "check_positive", "check_quat",
           "check_range", "check_real", "check_real_dtype", "check_vector"]
