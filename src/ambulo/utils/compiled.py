"""numba, when installed (the ``data`` extra): kernels compiled on first use and cached on disk, for
the replicator's passes (``replicator.mask_kernel``, ``replicator.io``) and the annotators' boxes
(``sensors.box_kernel``).

``HAVE_NUMBA`` says whether the compiled paths run; every kernel keeps a NumPy path that gives the
same results without it (their tests run both). numba is imported when a kernel is first compiled,
not at import: ``import ambulo.replicator`` (the CLI, a parent that only spawns workers) does not pay
its ~0.3-0.5 s. ``cache=True`` writes the machine code next to the module in ``__pycache__``, or,
where the package is read-only, in numba's per-user cache (``NUMBA_CACHE_DIR`` moves it): the first
process on a machine compiles a kernel (~1-3 s), later ones load it (~0.1-0.2 s). AMBULO_NUMBA=0
takes the NumPy paths on purpose (comparisons, debugging).
"""

from __future__ import annotations

import importlib.util
import os

HAVE_NUMBA = os.environ.get("AMBULO_NUMBA", "1") != "0" and importlib.util.find_spec("numba") is not None


class Kernel:
    """``fn`` compiled by numba's ``njit`` (nopython, ``nogil``: the producer's writer thread runs beside
    it, ``cache=True``) on its first call."""

    def __init__(self, fn):
        self.fn = fn
        self._compiled = None

    def __call__(self, *args):
        if self._compiled is None:
            if not HAVE_NUMBA:
                raise RuntimeError("numba is not installed: pip install 'ambulo[data]' (or numba)")
            from numba import njit

            try:
                self._compiled = njit(cache=True, nogil=True)(self.fn)
            except RuntimeError:  # no writable cache folder (package, NUMBA_CACHE_DIR, ~/.cache): compile each time
                self._compiled = njit(cache=False, nogil=True)(self.fn)
        return self._compiled(*args)
