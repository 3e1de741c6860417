"""ambulo's own map file: a ``Grid2D`` in one compressed ``.npz`` (what ``ambulo map`` writes as
``costmap.npz`` and ``ambulo plan --map`` reads).

Keys (``numpy.load(path)`` reads them without ambulo; no pickles)::

    format        str  "ambulo.maps.Grid2D"
    version       int  1
    occupancy     (num_y, num_x) int8   -1 unknown, 0 free .. 100 occupied; row 0 = lowest y
    origin_xy_m   (2,) float64          world (x, y) of the lower-left CORNER of cell [0, 0], m
    resolution_m  () float64            cell side, m
    cost          (num_y, num_x) uint8  Nav2 costs; only when the map has a cost layer
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from ..utils.atomic import atomic_write_bytes
from ..utils.checks import Described, InvalidValueError
from .grid import Grid2D

FORMAT = "ambulo.maps.Grid2D"
"""The ``format`` key of every map file ambulo writes."""
VERSION = 1
"""The ``version`` key this ambulo writes and the newest it reads."""


def save_npz(path: str | Path, grid: Grid2D) -> Path:
    """Write ``grid`` to ``path`` (a ``.npz``; replaced atomically) and return the path."""
    arrays = {"format": np.array(FORMAT), "version": np.array(VERSION), "occupancy": grid.occupancy,
              "origin_xy_m": np.array(grid.origin_xy_m, np.float64), "resolution_m": np.array(grid.resolution_m)}
    if grid.cost is not None:
        arrays["cost"] = grid.cost
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buffer.getvalue())
    return path


def load_npz(path: str | Path) -> Grid2D:
    """The ``Grid2D`` in a map file ``save_npz`` wrote; bad files are refused in one line."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no map file {str(path)!r}; write one with ambulo map or ambulo.maps.save_npz")
    try:
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):  # a lone .npy array under a .npz name
            raise ValueError("it holds one array")
        with data:
            arrays = {key: data[key] for key in data.files}
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as err:
        raise InvalidValueError(f"map file {str(path)!r}", Described("unreadable"), f"not a .npz archive ({err})",
                                "give a map written by ambulo map or ambulo.maps.save_npz") from None
    if "format" not in arrays:
        hint = ("it is an ambulo map from before the maps format (its origin_xy_m is a cell centre)"
                if "cost" in arrays else f"it holds {sorted(arrays)}")
        raise InvalidValueError(f"map file {str(path)!r}", Described("not an ambulo map"), hint,
                                "re-run ambulo map, or write it with ambulo.maps.save_npz")
    if str(arrays["format"]) != FORMAT:
        raise InvalidValueError(f"map file {str(path)!r} format", str(arrays["format"]), f"expected {FORMAT!r}",
                                "give a map written by ambulo.maps.save_npz")
    version = int(arrays.get("version", -1))
    if version != VERSION:
        raise InvalidValueError(f"map file {str(path)!r} version", version, f"this ambulo reads version {VERSION}",
                                "re-write the map with this ambulo, or upgrade ambulo")
    missing = [k for k in ("occupancy", "origin_xy_m", "resolution_m") if k not in arrays]
    if missing:
        raise InvalidValueError(f"map file {str(path)!r}", Described(f"missing {missing}"),
                                "a Grid2D needs occupancy, origin_xy_m and resolution_m",
                                "re-write it with ambulo.maps.save_npz")
    return Grid2D(occupancy=arrays["occupancy"], origin_xy_m=tuple(float(v) for v in arrays["origin_xy_m"]),
                  resolution_m=float(arrays["resolution_m"]), cost=arrays.get("cost"))


__all__ = ["FORMAT", "VERSION", "load_npz", "save_npz"]
