"""What the apartments' furniture is called: the object classes a detector learns and an object goal
names (``navigate --object chair``), and each labelled piece's ground-truth footprint.

Labels come from the piece's kind in its solid's name (``apartment_layout``:
``/World/apartment/<room>/<kind>_<n>[/<part>]``). A piece built of several solids (a table: top and
legs) carries its label on one (the top, whose footprint is the table's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .apartment import Apartment
from .apartment_geometry import Footprints, point_clearance_m

OBJECT_CLASSES: dict[str, str] = {"armchair": "armchair", "bed": "bed", "cabinet": "cabinet", "desk": "desk",
                                  "pot": "plant", "shelf": "shelf", "sofa": "sofa", "table": "table",
                                  "round_table": "table"}
"""Furniture kind -> label. Lamps (a 2 cm pole), low boxes and piles stay unlabelled: clutter a
detector must learn to ignore."""
LABELLED_PART = {"table": "top", "round_table": "top"}
"""Pieces built of several solids: the part that carries the label."""
ALIASES = {"chair": "armchair", "couch": "sofa", "potted plant": "plant", "pot": "plant", "bookshelf": "shelf",
           "dining table": "table", "cupboard": "cabinet"}
"""Everyday names of the labels (COCO's among them), for object goals."""


def object_labels() -> list[str]:
    """The labels, sorted (COCO category ids 1..C in this order)."""
    return sorted(set(OBJECT_CLASSES.values()))


def canonical_label(name: str) -> str:
    """The label an object goal means (``chair`` -> ``armchair``); ValueError for an unknown name."""
    key = name.strip().lower().replace("_", " ")
    label = ALIASES.get(key, key)
    if label not in object_labels():
        raise ValueError(f"no apartment object is called {name!r}; known: {', '.join(object_labels())} "
                         f"(or {', '.join(sorted(ALIASES))})")
    return label


def furniture_label(solid_name: str) -> str | None:
    """The label of an apartment solid, or None (module docstring)."""
    parts = solid_name.split("/")
    if len(parts) < 5 or parts[1:3] != ["World", "apartment"]:
        return None
    kind = parts[4].rsplit("_", 1)[0]
    label = OBJECT_CLASSES.get(kind)
    if label is None:
        return None
    part = parts[5] if len(parts) > 5 else None
    return label if part == LABELLED_PART.get(kind) else None


@dataclass(frozen=True)
class ObjectInstance:
    name: str
    """The labelled solid's name (its MuJoCo body)."""
    label: str
    footprint: Footprints
    """Its footprint alone (a rectangle or a disc), for distances."""
    center_xyz_m: tuple[float, float, float]

    def distance_m(self, xy_m) -> np.ndarray:
        """Distance from points ``xy_m`` (..., 2) to the footprint (0 inside), m."""
        return point_clearance_m(self.footprint, np.asarray(xy_m, float))


def object_instances(apt: Apartment, label: str | None = None) -> list[ObjectInstance]:
    """The apartment's labelled pieces (of ``label`` only, if given)."""
    out = []
    for s in apt.solids:
        lab = furniture_label(s.name)
        if lab is None or (label is not None and lab != label):
            continue
        empty = np.zeros((0, 2))
        if s.shape == "box":
            fp = Footprints(np.array([s.center_m[:2]]), np.array([s.half_m[:2]]), np.array([s.yaw_rad]), empty,
                            np.zeros(0))
        else:
            fp = Footprints(empty, empty, np.zeros(0), np.array([s.center_m[:2]]), np.array([s.half_m[0]]))
        out.append(ObjectInstance(s.name, lab, fp, tuple(s.center_m)))
    return out


__all__ = ["ALIASES", "LABELLED_PART", "OBJECT_CLASSES", "ObjectInstance", "canonical_label", "furniture_label",
           "object_instances", "object_labels"]
