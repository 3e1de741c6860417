"""The apartment-objects dataset: seeded apartments (``ambulo.scenes.apartment``) seen by the
navigator's head camera, their furniture labelled for COCO, so that a detector trained on it finds
what ``navigate --object`` walks to.

A ``DatasetConfig`` compiles one scene per process, and an apartment's geometry is its scene, so a
dataset is one apartment (``apartment_objects_config``): every frame stands the robot somewhere
free in it (``RobotPlacement``), most frames turned towards a piece of furniture as a robot
looking for it would be. ``generate_apartments`` makes one such dataset per apartment seed (each
by ``replicator.generate``, so resumable) and writes one COCO file over all of them whose frames
are in apartment order: the detector's held-out split (the last frames) is then whole apartments
it never saw.

The camera is the navigator's (``humanoid.head_camera_cfg``: 525 px focal at 640 px wide, pitched
18 deg down), at any resolution with the same field of view, under the robot's head lamp; head height
and aim jitter as a walking robot's do.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from ambulo.core import set_semantic_label
from ambulo.core.randomize import uniform, write_field
from ambulo.robots import humanoid
from ambulo.scenes.apartment import Apartment, apartment
from ambulo.scenes.apartment_labels import furniture_label, object_labels
from ambulo.sensors import CameraCfg

from .config import DATASET_ANNOTATORS, DatasetConfig
from .generate import generate
from .randomizers import CameraJitter, Randomizer
from .writers import WriterCfg


def labelled_solids(apt: Apartment) -> list[tuple[str, str]]:
    """(solid name, label) of the apartment's labelled furniture."""
    return [(s.name, label) for s in apt.solids if (label := furniture_label(s.name)) is not None]


def build_labelled_apartment(apt: Apartment, robot_pose=(0.0, 0.0, 0.0),
                             head_lamp: float = humanoid.HEAD_LAMP_DIFFUSE) -> mujoco.MjSpec:
    """The apartment's scene with the humanoid, its head lamp (``humanoid.add_head_lamp``: added when
    the apartments' own point lights did not light GL renders (before ``render.point_lights``, 2026-11-30)
    and frames without it were half as bright as any the detector is shown on the robot; kept, as the
    navigator's camera has it) and its furniture labelled (``scenes.apartment_labels``)."""
    spec = apt.build(robot_pose=robot_pose)
    humanoid.add_head_lamp(spec, head_lamp)
    for name, label in labelled_solids(apt):
        set_semantic_label(spec, name, label)
    return spec


def head_camera(width: int, height: int) -> CameraCfg:
    """The navigator's head camera at ``width`` x ``height`` (the same field of view at any size)."""
    return humanoid.head_camera_cfg(width, height, annotators=DATASET_ANNOTATORS)


@dataclass(kw_only=True)
class RobotPlacement(Randomizer):
    """Stands the humanoid at a free place of apartment ``apartment_seed`` each frame: a cell with
    ``clearance_m`` around it, any heading; with ``aim_probability`` the place is
    ``aim_distance_range_m`` from a labelled piece (a class drawn
    uniformly, then a piece of it) and the heading points at it within ``aim_spread_deg``
    (a robot looking for an object turns to it). ``head_shift_range_m`` shifts the whole robot (head height)."""

    apartment_seed: int
    clearance_m: float = humanoid.BODY_RADIUS_M
    aim_probability: float = 0.8
    aim_distance_range_m: tuple[float, float] = (0.8, 5.0)
    aim_spread_deg: float = 25.0
    head_shift_range_m: tuple[float, float] = (-0.04, 0.03)

    def initialize(self, engine):
        model = engine.model
        apt = apartment(self.apartment_seed)
        walkable = apt.paths.walkable(self.clearance_m)
        x0, y0, x1, y1 = apt.layout.extent_xy_m
        grid = apt.occupancy
        iy, ix = np.nonzero(walkable)
        xs, ys = grid.cell_center_xy_m(iy, ix)
        inside = (xs > x0) & (xs < x1) & (ys > y0) & (ys < y1)
        self._free_xy_m = np.stack([xs[inside], ys[inside]], axis=1)
        if not len(self._free_xy_m):
            raise ValueError(f"{self.name}: apartment {self.apartment_seed} has no cell with {self.clearance_m} m room")
        solids = {s.name: s for s in apt.solids}
        labelled = labelled_solids(apt)
        self._targets_xy_m = np.array([solids[n].center_m[:2] for n, _ in labelled], float).reshape(-1, 2)
        labels = sorted({label for _, label in labelled})
        # aims are class-balanced: a class first, then one of its pieces (flush furniture outnumbers chairs)
        self._targets_by_class = [np.array([k for k, (_, lab) in enumerate(labelled) if lab == label]) for label in labels]
        free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE and
                (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.jnt_bodyid[j])) or "")
                .startswith(humanoid.PRIM_PATH)]
        if not free:
            raise ValueError(f"{self.name}: no free joint under {humanoid.PRIM_PATH}")
        self._qpos_ids = np.arange(model.jnt_qposadr[free[0]], model.jnt_qposadr[free[0]] + 7)
        self._z0_m = float(model.qpos0[self._qpos_ids[2]])

    def sample(self, rng, ctx):
        u = rng.random(6)
        free = self._free_xy_m
        if u[0] < self.aim_probability and len(self._targets_xy_m):
            pieces = self._targets_by_class[min(int(u[1] * len(self._targets_by_class)), len(self._targets_by_class) - 1)]
            target = self._targets_xy_m[pieces[min(int(u[5] * len(pieces)), len(pieces) - 1)]]
            d = np.hypot(*(free - target).T)
            near = np.flatnonzero((d >= self.aim_distance_range_m[0]) & (d <= self.aim_distance_range_m[1]))
            pool = near if len(near) else np.arange(len(free))
            xy = free[pool[min(int(u[2] * len(pool)), len(pool) - 1)]]
            yaw = math.atan2(target[1] - xy[1], target[0] - xy[0]) + math.radians(self.aim_spread_deg) * (2 * u[3] - 1)
        else:
            xy = free[min(int(u[2] * len(free)), len(free) - 1)]
            yaw = math.pi * (2 * u[3] - 1)
        dz = self.head_shift_range_m[0] + (self.head_shift_range_m[1] - self.head_shift_range_m[0]) * u[4]
        return {"xy_m": [float(xy[0]), float(xy[1])], "yaw_rad": float(yaw), "dz_m": float(dz)}

    def apply(self, params, ctx):
        yaw = params["yaw_rad"]
        qpos = [*params["xy_m"], self._z0_m + params["dz_m"], math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
        write_field(ctx.engine.qpos, [qpos], rows=ctx.world, index=self._qpos_ids)


def apartment_objects_config(apartment_seed: int, width: int = 160, height: int = 120) -> DatasetConfig:
    """One apartment's dataset (module docstring): placement and aim jitter. The lighting is the
    apartment's own (seeded, varied across apartments), as the navigator sees it: a light randomizer
    that redraws every light from one range made frames darker than any apartment the robot walks in."""
    apt = apartment(apartment_seed)
    return DatasetConfig(
        name=f"ambulo_apartment_{apartment_seed}_objects",
        build_scene=lambda: build_labelled_apartment(apt),
        camera=head_camera(width, height),
        randomizers=[
            RobotPlacement(name="robot_place", apartment_seed=apartment_seed),
            CameraJitter(name="camera_jitter", camera=humanoid.HEAD_CAMERA_PRIM,
                         position_m=uniform((-0.02, -0.02, -0.02), (0.02, 0.02, 0.02)),
                         rotation_deg=uniform((-3.0, -6.0, -4.0), (3.0, 6.0, 4.0))),
        ],
        writer=WriterCfg(outputs=("coco",), fsync=False),  # a detector reads RGB and COCO; a lost frame is regenerated
    )


@dataclass(kw_only=True)
class MergedDataset:
    annotations_path: Path
    frames: int
    categories: list[str] = field(default_factory=list)


def _generate_one(task: tuple) -> str:
    seed, out, frames, width, height = task
    return str(generate(apartment_objects_config(seed, width, height), out, frames, seed=0, workers=1,
                        show_progress=False))


def generate_apartments(out: str | Path, apartment_seeds: Iterable[int], frames_per_apartment: int, *,
                        width: int = 160, height: int = 120, processes: int = 1, min_area_px: int = 20) -> MergedDataset:
    """One dataset per apartment under ``out/apartment_<seed>`` (resumable; ``processes`` apartments at a
    time, one process each) and ``out/annotations.json`` over all of them in seed order: categories by
    name (``object_labels``), image and annotation ids renumbered, file names relative to ``out``.
    Slivers under ``min_area_px`` (a piece at the frame's edge) are marked crowd: neither taught nor scored."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in apartment_seeds]
    tasks = [(seed, out / f"apartment_{seed:04d}", frames_per_apartment, width, height) for seed in seeds]
    if processes > 1:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(processes) as pool:
            paths = pool.map(_generate_one, tasks, chunksize=1)
    else:
        paths = [_generate_one(t) for t in tasks]
    categories = object_labels()
    cat_id = {name: k + 1 for k, name in enumerate(categories)}
    images, annotations = [], []
    for seed, path in zip(seeds, paths):
        sub = f"apartment_{seed:04d}"
        coco = json.loads(Path(path).read_text())
        names = {c["id"]: c["name"] for c in coco["categories"]}
        new_id = {}
        for im in sorted(coco["images"], key=lambda im: im["id"]):
            new_id[im["id"]] = len(images) + 1
            images.append({**im, "id": new_id[im["id"]], "file_name": f"{sub}/{im['file_name']}"})
        for ann in coco["annotations"]:
            crowd = int(ann.get("iscrowd", 0) or ann["area"] < min_area_px)
            annotations.append({**ann, "id": len(annotations) + 1, "image_id": new_id[ann["image_id"]],
                                "category_id": cat_id[names[ann["category_id"]]], "iscrowd": crowd})
    merged = {"info": {"description": "ambulo apartment objects", "version": "1.0"}, "images": images,
              "annotations": annotations, "categories": [{"id": cat_id[n], "name": n, "supercategory": "furniture"}
                                                         for n in categories]}
    path = out / "annotations.json"
    path.write_text(json.dumps(merged))
    return MergedDataset(annotations_path=path, frames=len(images), categories=categories)


def main(argv: list[str] | None = None) -> int:
    import argparse

    p = argparse.ArgumentParser(description="generate the apartment-objects detection dataset (module docstring)")
    p.add_argument("--out", required=True)
    p.add_argument("--apartments", default="1000-1039", help="seed range a-b (inclusive) or comma list")
    p.add_argument("--frames-per-apartment", type=int, default=60)
    p.add_argument("--width", type=int, default=160)
    p.add_argument("--height", type=int, default=120)
    p.add_argument("--processes", type=int, default=1, help="apartments rendered at a time (one process each)")
    args = p.parse_args(argv)
    text = args.apartments
    seeds = range(int(text.split("-")[0]), int(text.split("-")[1]) + 1) if "-" in text else \
        [int(s) for s in text.split(",")]
    merged = generate_apartments(args.out, seeds, args.frames_per_apartment, width=args.width, height=args.height,
                                 processes=args.processes)
    print(f"{merged.frames} frames, categories {merged.categories}: {merged.annotations_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
