"""``dataset.json``: what a dataset folder's frames were made with, so a resume never mixes datasets.

It is written (atomically, flushed) before the first frame and holds a fingerprint of
everything that decides a frame's pixels, annotations and files: seed, resolution, annotators,
writer settings, camera, randomizers, the randomizers' draw scheme (``streams.DRAWS``), a hash of
the compiled scene (MuJoCo's binary model: the same bytes in every process and run of one MuJoCo
version) and the MuJoCo version. A folder is
resumed only when the fingerprint is the same; otherwise ``DatasetFolderError`` names each
difference. What changes only a file's bytes is left out (the PNG deflate and row filters: a
decoder gives the same pixels), so a dataset started with another deflate, or by an ambulo that
wrote its fingerprint with one (``_BYTES_ONLY``), is resumed. Besides the fingerprint it holds
each instance's category id (``instance_categories``), from which ``semantic_image`` makes a
frame's semantic image out of its instance image. ``open_dataset`` also refuses to write into, or delete from, a folder
that is not an ambulo dataset (a non-empty folder without an ambulo ``dataset.json``, even with
``overwrite``), and ``overwrite`` deletes only the names ambulo writes: a user's files stay.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import os
from pathlib import Path

import mujoco
import numpy as np

from ambulo.utils.atomic import atomic_write_json, fsync_dir, is_partial_file

from .config import DatasetConfig
from .records import record_lines
from .streams import DRAWS
from .writers import FRAME_FILE, SUBDIRS, check_writer_cfg, frame_stem

MANIFEST = "dataset.json"
FORMAT = "ambulo dataset"
"""The manifest's ``format``: a ``dataset.json`` without it is someone else's (nnU-Net has one)."""
TOP_FILES = (MANIFEST, "metadata.json", "annotations.json")
"""The files ambulo writes at a dataset's top level (besides the ``SUBDIRS``)."""
_FIX = ("resume with the same settings, start afresh with --overwrite (overwrite=True), "
        "or give another output folder")
_BYTES_ONLY = ("png_deflate",)
"""Keys that fingerprints written before 2026-11-29 hold, which decide only files' bytes: ignored."""
_SEMANTIC = "semantic_segmentation"


class DatasetFolderError(Exception):
    """An output folder that can't be used as asked: ``problem`` says why, ``fix`` what to do."""

    def __init__(self, problem: str, fix: str):
        self.problem, self.fix = problem, fix
        super().__init__(f"{problem}; {fix}")


def fingerprint(config: DatasetConfig, seed: int, model: mujoco.MjModel, image_source: str | None = None) -> dict:
    """Everything that decides the dataset's pixels, annotations and files, as JSON data (``num_frames``
    aside: more frames extend it; the PNG deflate aside: it changes bytes, not pixels).
    ``image_source`` names a renderer other than the CPU camera's (the batched GPU path); absent
    for CPU datasets, whose fingerprints it leaves as they were."""
    camera = describe(config.camera)
    names = [r.name or type(r).__name__ for r in config.randomizers]
    writer = describe(config.writer)
    writer.pop("fsync")  # flushing changes no byte
    return _json({
        "seed": seed, "width": camera.pop("width"), "height": camera.pop("height"),
        "annotators": camera.pop("annotators"), "visible_fraction": config.visible_fraction,
        "name": config.name, "camera": camera, "writer": writer,
        "randomizers": {name: describe(r) for name, r in zip(names, config.randomizers)}, "draws": DRAWS,
        "scene_sha256": model_sha256(model), "mujoco_version": mujoco.__version__,
        **({"image_source": image_source} if image_source else {}),
    })


def model_sha256(model: mujoco.MjModel) -> str:
    """SHA-256 of the compiled model's MJB bytes (its arrays and names, not where it was built)."""
    buffer = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return hashlib.sha256(buffer.tobytes()).hexdigest()


def describe(value):
    """``value`` as JSON data that is the same in every process and run: dataclasses by their init
    fields, functions by qualified name, other objects by type (their repr may hold an address)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, enum.Enum):
        return value.name
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: describe(getattr(value, f.name)) for f in dataclasses.fields(value) if f.init}
        return {"type": type(value).__name__, **fields}
    if isinstance(value, dict):
        return {str(k): describe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [describe(v) for v in value]
    if isinstance(value, (np.ndarray, np.generic)) or hasattr(value, "__array__"):
        return np.asarray(value).tolist()
    if callable(value):
        return f"{getattr(value, '__module__', '?')}.{getattr(value, '__qualname__', type(value).__name__)}"
    return type(value).__qualname__


def open_dataset(out: Path, config: DatasetConfig, seed: int, model: mujoco.MjModel, num_frames: int,
                 overwrite: bool = False, image_source: str | None = None) -> None:
    """Make ``out`` ready for ``num_frames`` frames of (config, seed): a new dataset in a new or empty
    folder, the same one resumed (or extended), or, with ``overwrite``, an ambulo dataset's own files
    deleted first. ``DatasetFolderError`` for anything else; nothing is written before the checks pass."""
    check_writer_cfg(config.writer)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise DatasetFolderError(f"output folder {str(out)!r} is an existing file",
                                 "give the path of a new or empty folder")
    wanted = fingerprint(config, seed, model, image_source)
    existing = read_manifest(out)
    if existing is not None and not overwrite:
        _check_resumable(out, existing, wanted, num_frames)
    elif existing is None and _has_entries(out):  # overwrite or not: it may be anyone's
        raise DatasetFolderError(
            f"output folder {str(out)!r} is not empty and is not an ambulo dataset (it has no {MANIFEST} of ambulo's)",
            "give a new or empty folder: ambulo writes into and deletes from its own datasets only")
    if overwrite and out.is_dir():
        remove_dataset_files(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(out / MANIFEST, {"format": FORMAT, "version": 1, "num_frames": num_frames,
                                           "fingerprint": wanted,
                                           "instance_categories": _instance_categories(model)},
                          indent=2, fsync=True)
        fsync_dir(out)
    except OSError as err:
        raise DatasetFolderError(f"can't write to output folder {str(out)!r}: {err.strerror or err}",
                                 "give a folder you can write to") from None


def read_manifest(out: Path) -> dict | None:
    """The manifest of dataset ``out``; None when there is none or it is not ambulo's."""
    try:
        manifest = json.loads((Path(out) / MANIFEST).read_bytes())
    except (OSError, ValueError):
        return None
    return manifest if isinstance(manifest, dict) and manifest.get("format") == FORMAT else None


def _check_resumable(out: Path, existing: dict, wanted: dict, num_frames: int) -> None:
    old = existing.get("fingerprint", {})
    old = {k: v for k, v in old.items() if k not in _BYTES_ONLY} if isinstance(old, dict) else old
    differences = _differences(old, wanted)
    if differences:
        listed = "; ".join(_OLD_DRAWS if key == "draws" and old is None else f"{key} {_short(old)} (now {_short(new)})"
                           for key, old, new in differences)
        raise DatasetFolderError(f"{str(out)!r} holds a dataset made with other settings: {listed}",
                                 _fix_for(differences))
    beyond = sorted(index for index in record_lines(out / "frames") if index >= num_frames)
    if beyond:
        raise DatasetFolderError(
            f"{str(out)!r} already holds frames {beyond[0]}-{beyond[-1]}, beyond the {num_frames} asked for",
            f"give --frames {beyond[-1] + 1} or more to resume it, or --overwrite to start afresh")


_OLD_DRAWS = ("its frames were drawn by an ambulo from before 2026-11-30 (torch draws seeded by "
              "default_rng([seed, k, block])), whose random numbers this version does not make")


def _fix_for(differences: list[tuple[str, object, object]]) -> str:
    """``_FIX``, naming the annotator to add when the dataset had semantic images and this config not
    (ambulo's default annotators had semantic_segmentation until 2026-11-29), or the ambulo version to
    use when the dataset's draws are another scheme's."""
    for key, old, new in differences:
        if key == "draws":
            return ("finish it with the ambulo version that started it, start afresh with --overwrite "
                    "(overwrite=True), or give another output folder")
        if (key == "annotators" and isinstance(old, list) and isinstance(new, list)
                and set(old) - set(new) == {_SEMANTIC}):
            return (f"add {_SEMANTIC!r} to the camera's annotators (CameraCfg.annotators in a config file) to "
                    "resume it with its semantic images, start afresh with --overwrite (overwrite=True), or give "
                    "another output folder")
    return _FIX


def _instance_categories(model: mujoco.MjModel) -> list[int]:
    """Category id (COCO's, 0 = background) of each instance id 0..K of ``model``'s labelled bodies."""
    from ambulo.sensors.annotators import instance_table

    return instance_table(model).semantic_ids.tolist()


def semantic_image(out: Path, index: int) -> np.ndarray:
    """Frame ``index``'s semantic image (H, W) uint16 category ids of dataset ``out``: its
    ``semantic/`` PNG when it was written, else its instance image looked up in the dataset's
    ``instance_categories`` (the same pixels: both come from the id pass)."""
    from PIL import Image

    out, stem = Path(out), frame_stem(index)
    written = out / "semantic" / f"{stem}.png"
    if written.is_file():
        return np.asarray(Image.open(written)).astype(np.uint16)
    manifest = read_manifest(out)
    if manifest is None or "instance_categories" not in manifest:
        raise DatasetFolderError(f"{str(out)!r} has no semantic/{stem}.png and no instance categories in its "
                                 f"{MANIFEST}", "generate it with 'semantic_segmentation' among the annotators")
    categories = np.asarray(manifest["instance_categories"], np.uint16)
    return categories[np.asarray(Image.open(out / "instance" / f"{stem}.png"))]


def _differences(old, new, key: str = "") -> list[tuple[str, object, object]]:
    """(dotted key, old, new) of every leaf that differs (values compared as JSON text: NaN == NaN)."""
    if isinstance(old, dict) and isinstance(new, dict):
        out = []
        for k in list(old) + [k for k in new if k not in old]:
            out += _differences(old.get(k), new.get(k), f"{key}.{k}" if key else k)
        return out
    same = json.dumps(old, sort_keys=True) == json.dumps(new, sort_keys=True)
    return [] if same else [(key, old, new)]


def _short(value, limit: int = 60) -> str:
    text = json.dumps(value, separators=(",", ":"))
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _json(value):
    """``value`` as it reads back from JSON (tuples become lists), to compare with a manifest."""
    return json.loads(json.dumps(value))


def _has_entries(out: Path) -> bool:
    return out.is_dir() and any(os.scandir(out))


def _is_own_file(name: str) -> bool:
    return FRAME_FILE.fullmatch(name) is not None or is_partial_file(name)


def remove_dataset_files(out: Path) -> int:
    """Delete the files of the ambulo dataset in ``out`` (frame records first, manifest last) and its
    emptied subfolders; any other file (a user's notes in ``rgb/``, say) stays. Returns the count."""
    count = 0
    for sub in ("frames", *[s for s in SUBDIRS if s != "frames"]):
        folder = out / sub
        if not folder.is_dir() or folder.is_symlink():
            continue
        for entry in os.scandir(folder):
            if entry.is_file(follow_symlinks=False) and _is_own_file(entry.name):
                os.unlink(entry.path)
                count += 1
        if not any(os.scandir(folder)):
            folder.rmdir()
    for entry in os.scandir(out):
        if entry.is_file(follow_symlinks=False) and is_partial_file(entry.name):
            os.unlink(entry.path)
            count += 1
    for name in TOP_FILES:
        if (out / name).is_file():
            (out / name).unlink()
            count += 1
    return count
