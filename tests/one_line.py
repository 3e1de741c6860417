"""The one-line error contract, for tests: ``call`` raises ``kind`` with a message of one line
that holds every given part (the problem and the fix)."""

from __future__ import annotations

import pytest

from ambulo.utils.checks import InvalidValueError


def raises_one_line(call, *parts: str, kind: type[Exception] = InvalidValueError) -> str:
    """Run ``call``; it must raise ``kind`` with a one-line message holding every part; the message."""
    with pytest.raises(kind) as info:
        call()
    message = str(info.value)
    assert "\n" not in message, message
    for part in parts:
        assert part in message, f"{part!r} not in {message!r}"
    return message
