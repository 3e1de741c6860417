"""Fixtures of the renderer tests."""

import pytest

from ambulo.render.path import NoPathTracerError, _mitsuba


@pytest.fixture(scope="module")
def needs_mitsuba():
    """Skips the tests of a module that asks for it (``pytest.mark.usefixtures("needs_mitsuba")``) where
    Mitsuba's CPU variant (``llvm_ad_rgb``) cannot run: no ``mitsuba`` wheel, or no LLVM."""
    try:
        _mitsuba("llvm_ad_rgb")
    except NoPathTracerError as e:
        pytest.skip(str(e))
