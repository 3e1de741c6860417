"""ROS map_server maps: a YAML file naming an image (PGM, PNG, ...), read and written with Nav2's
semantics (``nav2_map_server/src/map_io.cpp``: ``loadMapYaml``, ``loadMapFromFile``,
``tryWriteMapToFile``)::

    image: room.pgm          # relative to the YAML's folder, or absolute
    resolution: 0.05         # m per pixel
    origin: [-10.0, -5.0, 0.0]   # x, y (m) of the lower-left pixel's lower-left corner; yaw (rad)
    negate: 0                # 1: white is occupied
    occupied_thresh: 0.65
    free_thresh: 0.196
    mode: trinary            # optional: trinary (default), scale or raw

Each pixel's ``shade`` is the mean of its colour channels over the image's maximum (in trinary
mode an alpha channel joins the mean); ``occ = shade`` if ``negate`` else ``1 - shade``. Then

- trinary: occ > occupied_thresh -> 100; occ < free_thresh -> 0; otherwise -1 (unknown);
- scale: a transparent pixel -> -1; then as trinary, but between the thresholds
  rint(100 (occ - free_thresh) / (occupied_thresh - free_thresh));
- raw: round(255 shade) where it lies in 0..100, else -1 (``negate`` does not apply).

The image's first row is the top of the map (the highest y), so rows are flipped into ``Grid2D``.
Written maps use ``free_thresh`` 0.196 (ROS 1's): map_server writes unknown cells as grey 205,
whose occ = 50/255 = 0.196 reads back as unknown, whereas Nav2's saver default 0.25 would read
it back as free.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ..utils.atomic import atomic_write_bytes, atomic_write_text
from ..utils.checks import Described, InvalidValueError, check_positive
from .grid import FREE, OCCUPIED, UNKNOWN, Grid2D, check_yaw_zero
from .pgm import read_pgm, write_pgm

MODES = ("trinary", "scale", "raw")
"""map_server's ``mode`` values."""
REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
"""Keys map_server refuses to load without (``mode`` defaults to trinary)."""
OCCUPIED_THRESH, FREE_THRESH = 0.65, 0.196
"""Thresholds ambulo writes (ROS 1 map_saver's; Nav2's saver uses 0.65 and 0.25)."""
UNKNOWN_GREY, FREE_GREY, OCCUPIED_GREY = 205, 254, 0
"""Grey levels map_saver writes in trinary mode."""


def load_map_yaml(path: str | Path) -> Grid2D:
    """The ``Grid2D`` a map_server YAML (and the image it names) describes."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no map YAML {str(path)!r}; give the .yaml map_server loads")
    meta = parse_flat_yaml(path.read_text(errors="replace"), str(path))
    for key in REQUIRED_KEYS:
        if key not in meta:
            raise InvalidValueError(f"{path.name} key {key!r}", Described("missing"),
                                    f"map_server needs {', '.join(REQUIRED_KEYS)}",
                                    f"add it, e.g. '{key}: {_EXAMPLES[key]}'")
    image = Path(str(meta["image"]))
    image = image if image.is_absolute() else path.parent / image
    if not image.is_file():
        raise FileNotFoundError(f"map image {str(image)!r} named by {path.name}'s 'image' does not exist; "
                                "fix the 'image:' path (relative paths start at the YAML's folder)")
    origin = meta["origin"]
    if not isinstance(origin, list) or len(origin) != 3:
        raise InvalidValueError(f"{path.name} 'origin'", origin, "expected [x, y, yaw]",
                                "write e.g. 'origin: [-10.0, -10.0, 0.0]'")
    negate = meta["negate"]
    if negate not in (0, 1, True, False):
        raise InvalidValueError(f"{path.name} 'negate'", negate, "expected 0 or 1", "write 'negate: 0'")
    check_yaw_zero(f"{path.name} origin yaw", _number(path.name, "origin", origin[2]))
    return load_map_image(image, resolution_m=_number(path.name, "resolution", meta["resolution"]),
                          origin_xy_m=(_number(path.name, "origin", origin[0]), _number(path.name, "origin", origin[1])),
                          negate=bool(negate), occupied_thresh=_number(path.name, "occupied_thresh",
                                                                       meta["occupied_thresh"]),
                          free_thresh=_number(path.name, "free_thresh", meta["free_thresh"]),
                          mode=str(meta.get("mode", "trinary")))


def load_map_image(path: str | Path, *, resolution_m: float, origin_xy_m=(0.0, 0.0), negate: bool = False,
                   occupied_thresh: float = OCCUPIED_THRESH, free_thresh: float = FREE_THRESH,
                   mode: str = "trinary") -> Grid2D:
    """A map image read as map_server does, with the YAML's settings given as arguments."""
    check_positive("map resolution", resolution_m, "give metres per pixel, e.g. 0.05")
    _check_thresholds(occupied_thresh, free_thresh)
    if mode not in MODES:
        raise InvalidValueError("map mode", mode, f"expected one of {', '.join(MODES)}", "write 'mode: trinary'")
    pixels, max_value = read_image(path)
    occupancy = pixels_to_occupancy(pixels, max_value, mode=mode, negate=negate,
                                    occupied_thresh=occupied_thresh, free_thresh=free_thresh)
    return Grid2D(occupancy=occupancy[::-1].copy(), origin_xy_m=tuple(float(v) for v in origin_xy_m),
                  resolution_m=float(resolution_m))


def pixels_to_occupancy(pixels: np.ndarray, max_value: float, *, mode: str, negate: bool,
                        occupied_thresh: float, free_thresh: float) -> np.ndarray:
    """(H, W) int8 occupancy of (H, W) or (H, W, C) pixels (C: 2 grey+alpha, 3 RGB, 4 RGBA) in image
    row order (top row first), by map_server's rule for ``mode``."""
    px = np.asarray(pixels, np.float64)
    px = px[..., None] if px.ndim == 2 else px
    colour = px[..., :3] if px.shape[-1] >= 3 else np.repeat(px[..., :1], 3, axis=-1)
    alpha = px[..., -1] if px.shape[-1] in (2, 4) else None
    channels = [colour] if mode != "trinary" or alpha is None else [colour, alpha[..., None]]
    shade = np.concatenate(channels, axis=-1).mean(axis=-1) / max_value
    occ = shade if negate else 1.0 - shade
    if mode == "raw":
        value = np.round(shade * 255.0)
        return np.where((value >= FREE) & (value <= OCCUPIED), value, UNKNOWN).astype(np.int8)
    out = np.full(occ.shape, UNKNOWN, np.int8)
    if mode == "scale":
        scaled = np.rint((occ - free_thresh) / (occupied_thresh - free_thresh) * 100.0)
        out = np.clip(scaled, FREE, OCCUPIED).astype(np.int8)
    out[occ < free_thresh] = FREE
    out[occ > occupied_thresh] = OCCUPIED
    if mode == "scale" and alpha is not None:
        out[alpha < max_value] = UNKNOWN
    return out


def save_map_yaml(path: str | Path, grid: Grid2D, *, image_format: str = "pgm", mode: str = "trinary",
                  occupied_thresh: float = OCCUPIED_THRESH, free_thresh: float = FREE_THRESH) -> Path:
    """Write ``grid`` as map_server's YAML at ``path`` and its image beside it (same stem,
    ``image_format`` pgm or png; scale mode needs png for its alpha). Returns the YAML's path."""
    path = Path(path)
    _check_thresholds(occupied_thresh, free_thresh)
    if mode not in MODES:
        raise InvalidValueError("map mode", mode, f"expected one of {', '.join(MODES)}", "pass mode='trinary'")
    if image_format not in ("pgm", "png") or (mode == "scale" and image_format == "pgm"):
        raise InvalidValueError("image_format", image_format, f"{mode} maps are written as "
                                + ("png (their alpha marks unknown cells)" if mode == "scale" else "pgm or png"),
                                "pass image_format='png'")
    image = occupancy_to_pixels(grid.occupancy, mode=mode, occupied_thresh=occupied_thresh,
                                free_thresh=free_thresh)[::-1]  # the image's top row is the map's highest y
    image_path = path.with_suffix("." + image_format)
    path.parent.mkdir(parents=True, exist_ok=True)
    if image_format == "pgm":
        write_pgm(image_path, image, comment=f"CREATOR: ambulo.maps {grid.resolution_m:.3f} m/pix")
    else:
        import imageio.v3 as iio  # only for PNG maps

        atomic_write_bytes(image_path, iio.imwrite("<bytes>", np.ascontiguousarray(image), extension=".png"))
    (ox, oy) = grid.origin_xy_m
    atomic_write_text(path, f"image: {image_path.name}\nmode: {mode}\nresolution: {float(grid.resolution_m)!r}\n"
                            f"origin: [{float(ox)!r}, {float(oy)!r}, 0.0]\nnegate: 0\n"
                            f"occupied_thresh: {occupied_thresh!r}\nfree_thresh: {free_thresh!r}\n")
    return path


def occupancy_to_pixels(occupancy: np.ndarray, *, mode: str, occupied_thresh: float,
                        free_thresh: float) -> np.ndarray:
    """uint8 pixels (H, W), or (H, W, 4) RGBA in scale mode, of (H, W) occupancy in map row order, as
    map_saver writes them (``negate`` 0)."""
    c = occupancy.astype(np.int16)
    unknown = (c < FREE) | (c > OCCUPIED)
    if mode == "trinary":
        grey = np.full(c.shape, UNKNOWN_GREY, np.uint8)
        grey[c <= round(free_thresh * 100)] = FREE_GREY
        grey[c >= round(occupied_thresh * 100)] = OCCUPIED_GREY
        grey[unknown] = UNKNOWN_GREY
        return grey
    if mode == "raw":
        return np.where(unknown, 255, c).astype(np.uint8)
    grey = np.where(unknown, 128, np.rint((100 - c) * 255 / 100.0)).astype(np.uint8)
    return np.stack([grey, grey, grey, np.where(unknown, 0, 255).astype(np.uint8)], axis=-1)


def read_image(path: str | Path) -> tuple[np.ndarray, float]:
    """(pixels, max_value): an image's (H, W) or (H, W, C) values, top row first, and the value of white."""
    path = Path(path)
    if path.suffix.lower() in (".pgm", ".pnm"):
        return read_pgm(path)
    import imageio.v3 as iio  # PNG/BMP decoding only when asked

    try:
        pixels = iio.imread(path)
    except Exception as err:  # any decoder failure is bad input here
        raise InvalidValueError(f"map image {str(path)!r}", Described("unreadable"), f"{type(err).__name__}: {err}",
                                "give a PGM or PNG occupancy image") from None
    if pixels.dtype == bool:
        return pixels.astype(np.uint8), 1.0
    if pixels.dtype.kind != "u" or pixels.ndim not in (2, 3):
        raise InvalidValueError(f"map image {str(path)!r}", Described(f"{pixels.dtype} of shape {pixels.shape}"),
                                "expected 8- or 16-bit grey or colour pixels", "save it as an 8-bit PNG or PGM")
    return pixels, float(np.iinfo(pixels.dtype).max)


def parse_flat_yaml(text: str, name: str = "map YAML") -> dict:
    """The flat ``key: value`` mapping of a map_server YAML (numbers, booleans, strings, ``[a, b]``
    lists and ``- item`` block lists; comments ignored): all map_server reads, with no YAML package."""
    out: dict = {}
    key = None
    for number, raw in enumerate(text.splitlines(), 1):
        line = re.sub(r"\s+#.*$|^#.*$", "", raw).rstrip()
        if not line.strip() or line.strip() == "---":
            continue
        item = re.fullmatch(r"\s*-\s+(.*)", line)
        if item and key is not None and isinstance(out[key], list):
            out[key].append(_scalar(item.group(1)))
            continue
        match = re.fullmatch(r"([A-Za-z_][\w]*)\s*:\s*(.*)", line)
        if match is None:
            raise InvalidValueError(f"{name} line {number}", raw.strip(), "expected 'key: value'",
                                    "write one map_server key per line, e.g. 'resolution: 0.05'")
        key, value = match.group(1), match.group(2).strip()
        if value.startswith("["):
            if not value.endswith("]"):
                raise InvalidValueError(f"{name} line {number}", raw.strip(), "a '[' list must close on its line",
                                        "write e.g. 'origin: [0.0, 0.0, 0.0]'")
            out[key] = [_scalar(v) for v in value[1:-1].split(",") if v.strip()]
        else:
            out[key] = _scalar(value) if value else []  # an empty value opens a '- item' block list
    return out


_EXAMPLES = {"image": "map.pgm", "resolution": "0.05", "origin": "[0.0, 0.0, 0.0]", "negate": "0",
             "occupied_thresh": "0.65", "free_thresh": "0.196"}


def _scalar(text: str):
    text = text.strip()
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
        return text[1:-1]
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def _number(name: str, key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InvalidValueError(f"{name} {key!r}", value, "expected a finite number", f"write e.g. '{key}: "
                                f"{_EXAMPLES.get(key, '0.0')}'")
    return float(value)


def _check_thresholds(occupied_thresh: float, free_thresh: float) -> None:
    if not 0.0 <= free_thresh < occupied_thresh <= 1.0:
        raise InvalidValueError("map thresholds", Described(f"free_thresh {free_thresh}, occupied_thresh "
                                                            f"{occupied_thresh}"),
                                "map_server needs 0 <= free_thresh < occupied_thresh <= 1",
                                "use e.g. free_thresh 0.196 and occupied_thresh 0.65")


__all__ = ["FREE_THRESH", "MODES", "OCCUPIED_THRESH", "load_map_image", "load_map_yaml", "occupancy_to_pixels",
           "parse_flat_yaml", "pixels_to_occupancy", "read_image", "save_map_yaml"]
