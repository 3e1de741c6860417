"""Procedural surface textures of the apartments, drawn by code from a seed (nothing is read or
downloaded): wood-plank and tiled floors, rugs, painted or papered walls, wood grain, fabric,
brushed metal, leaves, book spines and cardboard, and posters.

Every generator is ``f(rng, size_px) -> (size_px, size_px, 3) uint8``. The tiled ones (floors,
walls, wood, fabric, metal, leaves) wrap around: their noise lattices are periodic, so a surface
covered by repeats of one image shows no seam. Why texture at all: the navigator's visual odometry
finds its corners in these surfaces; from the head camera (320x240, 262 px focal length) a wall 1.5 m
away is 5.7 mm a pixel, so detail is drawn at 1-10 cm (plank seams, grout, grain, pattern, the edges
of pictures), not at the texel.
"""

from __future__ import annotations

import colorsys

import numpy as np


def _hsv(hue: float, sat: float, val: float) -> np.ndarray:
    return np.array(colorsys.hsv_to_rgb(hue % 1.0, float(np.clip(sat, 0, 1)), float(np.clip(val, 0, 1))))


def periodic_noise(rng: np.random.Generator, shape_px: tuple[int, int], cells: tuple[int, int]) -> np.ndarray:
    """(H, W) float64 value noise in [0, 1]: a random lattice of ``cells`` (rows, columns) values,
    smoothstep-interpolated and wrapped, so the image tiles. More columns than rows stretches its
    blobs vertically (and the other way round)."""
    lattice = rng.random(cells)

    def axis(n: int, c: int):
        t = np.arange(n) * c / n
        i0 = t.astype(int)
        f = t - i0
        return i0, (i0 + 1) % c, f * f * (3 - 2 * f)

    y0, y1, fy = axis(shape_px[0], cells[0])
    x0, x1, fx = axis(shape_px[1], cells[1])
    rows = lattice[y0] * (1 - fy)[:, None] + lattice[y1] * fy[:, None]
    return rows[:, x0] * (1 - fx) + rows[:, x1] * fx


def fbm(rng: np.random.Generator, size_px: int, cells: tuple[int, int], octaves: int, gain: float = 0.5) -> np.ndarray:
    """(size, size) float64 fractal noise: ``octaves`` periodic noises, each twice as fine and
    ``gain`` times as strong as the last, normalised to [0, 1]."""
    out = np.zeros((size_px, size_px))
    for k in range(octaves):
        c = (min(cells[0] * 2 ** k, size_px), min(cells[1] * 2 ** k, size_px))
        out += gain ** k * periodic_noise(rng, (size_px, size_px), c)
    return (out - out.min()) / max(float(np.ptp(out)), 1e-9)


def _to_uint8(rgb: np.ndarray) -> np.ndarray:
    return (np.clip(rgb, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)


def _wood_colour(rng: np.random.Generator) -> np.ndarray:
    """Oak to walnut: hue 20-40 deg, value 0.3-0.8."""
    return _hsv(rng.uniform(0.055, 0.11), rng.uniform(0.35, 0.7), rng.uniform(0.3, 0.8))


def _grain(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """(size, size) wood grain along x in [-1, 1]: streaks stretched along the board and growth rings
    bent by noise."""
    streaks = fbm(rng, size_px, (32, 2), 3) * 2 - 1
    warp = fbm(rng, size_px, (4, 2), 2)
    y = np.arange(size_px)[:, None] / size_px
    rings = np.sin(2 * np.pi * (rng.integers(6, 14) * y + 3.0 * warp))
    return 0.6 * streaks + 0.4 * rings ** 3


def floor_wood(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """Planks along x: 4-8 rows a tile, each cut into 1-3 boards at staggered joints, each board's
    tone jittered, grain along it, a dark seam between boards."""
    base = _wood_colour(rng)
    rows = int(rng.integers(4, 9))
    grain = _grain(rng, size_px)
    shade = np.ones((size_px, size_px))
    seam = np.zeros((size_px, size_px), bool)
    edges = np.linspace(0, size_px, rows + 1).astype(int)
    seam_px = max(1, size_px // 256)
    for r in range(rows):
        y0, y1 = edges[r], edges[r + 1]
        seam[y0:y0 + seam_px] = True
        cuts = np.sort(rng.integers(0, size_px, int(rng.integers(1, 4))))
        bounds = [0, *cuts.tolist(), size_px]
        for a, b in zip(bounds[:-1], bounds[1:]):
            shade[y0:y1, a:b] = rng.uniform(0.8, 1.2)
        for c in cuts:
            seam[y0:y1, c:c + seam_px] = True
    amount = rng.uniform(0.12, 0.22)
    rgb = base * (shade * (1 + amount * grain))[..., None]
    rgb[seam] *= 0.45
    return _to_uint8(rgb)


def floor_tiles(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """2-4 square tiles a side with grout lines, each tile's tone jittered, marble veins or speckle."""
    n = int(rng.integers(2, 5))
    light = rng.random() < 0.6
    base = _hsv(rng.uniform(0, 1), rng.uniform(0.0, 0.3), rng.uniform(0.6, 0.8) if light else rng.uniform(0.3, 0.5))
    grout = _hsv(rng.uniform(0, 1), rng.uniform(0, 0.1), rng.uniform(0.25, 0.45) if light else rng.uniform(0.7, 0.85))
    px = size_px // n
    tone = rng.uniform(0.9, 1.1, (n, n)).repeat(px, 0).repeat(px, 1)
    tone = np.pad(tone, ((0, size_px - tone.shape[0]), (0, size_px - tone.shape[1])), mode="edge")
    if rng.random() < 0.5:  # marble: thin veins where a warped sine crosses zero
        warp = fbm(rng, size_px, (3, 3), 4)
        u = np.add.outer(np.arange(size_px), np.arange(size_px)) / size_px
        pattern = 1 - 0.35 * np.abs(np.sin(np.pi * (2 * u + 5 * warp))) ** 0.2
    else:  # speckled
        pattern = 1 + 0.18 * (fbm(rng, size_px, (size_px // 8, size_px // 8), 2) - 0.5)
    rgb = base * (tone * pattern)[..., None]
    g = max(2, size_px // 128)
    lines = (np.arange(size_px) % px) < g
    rgb[lines] = grout
    rgb[:, lines] = grout
    return _to_uint8(rgb)


def rug(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """A whole rug (not tiled): 1-3 border bands around a field of diamonds or stripes, with a
    woollen fibre noise."""
    hue = rng.uniform(0, 1)
    palette = [_hsv(hue + rng.uniform(-0.1, 0.1) + 0.5 * (k % 2), rng.uniform(0.3, 0.8), rng.uniform(0.25, 0.85))
               for k in range(4)]
    v, u = np.mgrid[0:size_px, 0:size_px] / size_px
    edge = np.minimum(np.minimum(u, 1 - u), np.minimum(v, 1 - v))
    rgb = np.empty((size_px, size_px, 3))
    n = int(rng.integers(3, 8))
    if rng.random() < 0.5:
        field = ((np.abs((u * n) % 1 - 0.5) + np.abs((v * n) % 1 - 0.5)) < 0.3).astype(int)
    else:
        field = ((u * n * 2).astype(int) % 2)
    rgb[:] = np.where(field[..., None] == 1, palette[0], palette[1])
    bands = np.cumsum(rng.uniform(0.03, 0.08, int(rng.integers(1, 4))))
    for k, width in enumerate(bands[::-1]):
        rgb[edge < width] = palette[2 + k % 2]
    fibre = 1 + 0.15 * (periodic_noise(rng, (size_px, size_px), (size_px // 2, size_px // 2)) - 0.5)
    return _to_uint8(rgb * fibre[..., None])


def wall_paint(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """A tile of wall: knockdown-textured paint, vertical stripes, or a printed wallpaper motif
    (dots or diamonds in offset rows). Every kind carries the paint's texture: a soft mottle and
    flat-topped splats with sharp edges at two scales (1-2 cm and 4-8 cm at a 1.2 m tile), 4-8 %
    darker than the paint around them: what a knockdown or sponged finish looks like, and corners
    the odometry finds from 0.3 m (a wall filling the view) to 4 m away. Values stay below 0.8 so
    the head lamp does not blow them out."""
    base = _hsv(rng.uniform(0, 1), rng.uniform(0.03, 0.3), rng.uniform(0.55, 0.8))
    shade = 1 + rng.uniform(0.05, 0.1) * (fbm(rng, size_px, (8, 8), 4) - 0.5)
    for cells in (20, 56):
        splats = fbm(rng, size_px, (cells, cells), 2) > rng.uniform(0.5, 0.62)
        shade = shade * (1 - rng.uniform(0.04, 0.08) * splats)
    kind = rng.choice(["paint", "stripes", "motif"], p=[0.4, 0.3, 0.3])
    rgb = base * shade[..., None]
    u = np.arange(size_px) / size_px
    second = _hsv(rng.uniform(0, 1), rng.uniform(0.1, 0.5), rng.uniform(0.4, 0.75))
    if kind == "stripes":
        n = int(rng.integers(6, 16))
        stripe = ((u * n) % 1) < rng.uniform(0.2, 0.6)
        rgb[:, stripe] = second * shade[:, stripe, None]
    elif kind == "motif":
        n = int(rng.integers(6, 12))
        v, x = np.mgrid[0:size_px, 0:size_px] / size_px * n
        x = x + 0.5 * (v.astype(int) % 2)  # every other row offset by half a motif
        fu, fv = x % 1 - 0.5, v % 1 - 0.5
        radius = rng.uniform(0.12, 0.3)
        motif = (np.abs(fu) + np.abs(fv) < radius) if rng.random() < 0.5 else (fu ** 2 + fv ** 2 < radius ** 2)
        rgb[motif] = second * shade[motif, None]
    return _to_uint8(rgb)


def wood(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """Furniture wood: 2-4 boards along x with their own tone, grain, thin joints."""
    base = _wood_colour(rng)
    boards = int(rng.integers(2, 5))
    edges = np.linspace(0, size_px, boards + 1).astype(int)
    shade = np.ones(size_px)
    for a, b in zip(edges[:-1], edges[1:]):
        shade[a:b] = rng.uniform(0.85, 1.15)
    rgb = base * (shade[:, None] * (1 + rng.uniform(0.12, 0.22) * _grain(rng, size_px)))[..., None]
    rgb[edges[:-1]] *= 0.6
    return _to_uint8(rgb)


def fabric(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """Upholstery: a plain weave (1-texel checks) over plain, striped or plaid cloth, with creases."""
    c1 = _hsv(rng.uniform(0, 1), rng.uniform(0.15, 0.7), rng.uniform(0.25, 0.8))
    c2 = c1 * rng.uniform(0.6, 0.85)
    u = np.arange(size_px) / size_px
    kind = rng.choice(["plain", "stripes", "plaid"])
    n = int(rng.integers(4, 12))
    band = ((u * n) % 1) < rng.uniform(0.2, 0.5)
    mix = np.zeros((size_px, size_px))
    if kind in ("stripes", "plaid"):
        mix[:, band] = 1.0
    if kind == "plaid":
        mix[band, :] = np.maximum(mix[band, :], 0.6)
    weave = 1 + 0.06 * ((np.add.outer(np.arange(size_px), np.arange(size_px)) % 2) - 0.5)
    crease = 1 + 0.2 * (fbm(rng, size_px, (4, 4), 3) - 0.5)
    rgb = (c1 * (1 - mix[..., None]) + c2 * mix[..., None]) * (weave * crease)[..., None]
    return _to_uint8(rgb)


def metal(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """Brushed steel or painted metal: streaks along x."""
    base = _hsv(rng.uniform(0.5, 0.7), rng.uniform(0.0, 0.15), rng.uniform(0.35, 0.8))
    streaks = fbm(rng, size_px, (64, 2), 3)
    return _to_uint8(base * (1 + 0.2 * (streaks - 0.5))[..., None])


def plant(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """Leaves: overlapping ellipses in greens on a dark ground (wrapped at the borders)."""
    rgb = np.tile(_hsv(rng.uniform(0.22, 0.4), 0.6, 0.15), (size_px, size_px, 1))
    for _ in range(int(rng.integers(60, 120))):
        cx, cy = rng.uniform(0, size_px, 2)
        a, b = rng.uniform(0.03, 0.09) * size_px, rng.uniform(0.01, 0.03) * size_px
        th = rng.uniform(0, np.pi)
        reach = int(a) + 1  # the leaf's bounding square, wrapped at the borders
        dy, dx = np.mgrid[-reach:reach + 1, -reach:reach + 1]
        u, v = dx * np.cos(th) + dy * np.sin(th), -dx * np.sin(th) + dy * np.cos(th)
        inside = (u / a) ** 2 + (v / b) ** 2 < 1
        rows, cols = (dy[inside] + int(cy)) % size_px, (dx[inside] + int(cx)) % size_px
        rgb[rows, cols] = _hsv(rng.uniform(0.2, 0.42), rng.uniform(0.4, 0.9), rng.uniform(0.25, 0.75))
    return _to_uint8(rgb)


def boxes(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """Clutter: a row of book spines (coloured strips with title bands) or cardboard with tape."""
    if rng.random() < 0.5:
        rgb = np.zeros((size_px, size_px, 3))
        x = 0
        while x < size_px:
            w = int(rng.integers(size_px // 24, size_px // 8))
            rgb[:, x:x + w] = _hsv(rng.uniform(0, 1), rng.uniform(0.2, 0.8), rng.uniform(0.2, 0.85))
            for _ in range(int(rng.integers(1, 3))):
                y = int(rng.integers(0, size_px - size_px // 10))
                rgb[y:y + size_px // 20, x + 2:x + w - 2] = _hsv(rng.uniform(0, 1), 0.2, rng.choice([0.1, 0.9]))
            x += w
            rgb[:, max(0, x - 1):x] *= 0.4
        return _to_uint8(rgb)
    card = _hsv(rng.uniform(0.07, 0.1), rng.uniform(0.35, 0.55), rng.uniform(0.5, 0.75))
    rgb = card * (1 + 0.15 * (fbm(rng, size_px, (16, 16), 3) - 0.5))[..., None]
    tape = slice(int(size_px * 0.45), int(size_px * 0.55))
    rgb[tape] = card * 1.25
    label = rng.integers(size_px // 8, size_px // 2, 2)
    rgb[label[0]:label[0] + size_px // 6, label[1]:label[1] + size_px // 4] = 0.85
    return _to_uint8(rgb)


def poster(rng: np.random.Generator, size_px: int) -> np.ndarray:
    """A picture for a frame: an abstract of shapes, a landscape, or a print of title and text
    lines, on a white mount."""
    yy, xx = np.mgrid[0:size_px, 0:size_px] / size_px
    hue = rng.uniform(0, 1)
    kind = rng.choice(["shapes", "landscape", "print"])
    if kind == "landscape":
        sky = _hsv(rng.uniform(0.5, 0.65), rng.uniform(0.2, 0.6), rng.uniform(0.6, 0.95))
        rgb = sky * (1.1 - 0.4 * yy)[..., None]
        for k in range(3):  # ridges, nearer ones lower and darker
            ridge = 0.35 + 0.15 * k + 0.15 * periodic_noise(rng, (1, size_px), (1, 4 + 3 * k))[0]
            rgb[yy > ridge] = _hsv(rng.uniform(0.2, 0.45), rng.uniform(0.3, 0.7), 0.7 - 0.18 * k)
        cx, cy, r = rng.uniform(0.2, 0.8), rng.uniform(0.1, 0.3), rng.uniform(0.05, 0.1)
        rgb[(xx - cx) ** 2 + (yy - cy) ** 2 < r * r] = _hsv(rng.uniform(0.08, 0.15), 0.6, 1.0)
    else:
        rgb = np.tile(_hsv(hue, rng.uniform(0, 0.6), rng.uniform(0.2, 0.95)), (size_px, size_px, 1))
        if kind == "shapes":
            for _ in range(int(rng.integers(5, 14))):
                colour = _hsv(hue + rng.choice([0.0, 0.33, 0.5, 0.66]) + rng.uniform(-0.05, 0.05),
                              rng.uniform(0.3, 1.0), rng.uniform(0.1, 1.0))
                cx, cy, a, b = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0.05, 0.3), rng.uniform(0.05, 0.3)
                shape = (np.abs(xx - cx) < a) & (np.abs(yy - cy) < b) if rng.random() < 0.5 else \
                    ((xx - cx) / a) ** 2 + ((yy - cy) / b) ** 2 < 1
                rgb[shape] = colour
        else:
            ink = np.zeros(3) if rgb[0, 0].mean() > 0.5 else np.ones(3)
            rgb[(yy > 0.12) & (yy < 0.24) & (xx > 0.15) & (xx < rng.uniform(0.5, 0.85))] = \
                _hsv(hue + 0.5, 0.8, 0.6)
            for line in np.arange(0.32, 0.85, rng.uniform(0.04, 0.07)):
                rgb[(yy > line) & (yy < line + 0.018) & (xx > 0.15) & (xx < rng.uniform(0.45, 0.85))] = ink
    mount = rng.uniform(0.03, 0.08)
    rgb[(xx < mount) | (xx > 1 - mount) | (yy < mount) | (yy > 1 - mount)] = 0.85
    return _to_uint8(rgb)


GENERATORS = {"floor_wood": floor_wood, "floor_tiles": floor_tiles, "rug": rug, "wall": wall_paint,
              "wood": wood, "fabric": fabric, "metal": metal, "plant": plant, "furniture": boxes, "poster": poster}
"""Texture generator of each look (``apartment_build.LOOKS``) and of the posters."""

__all__ = ["GENERATORS", "boxes", "fabric", "fbm", "floor_tiles", "floor_wood", "metal", "periodic_noise", "plant",
           "poster", "rug", "wall_paint", "wood"]
