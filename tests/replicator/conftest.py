import dataclasses
import os
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest

from ambulo import replicator as rep
from ambulo.replicator import records
from ambulo.replicator.records import JOURNAL_FILE

SIZE = (160, 120)
SRC = str(Path(rep.__file__).resolve().parents[2])


def file_tree(root: Path) -> dict[str, object]:
    """Every file under ``root`` by relative path, with what a dataset promises of it: a PNG's decoded
    pixels (the deflate may give other bytes for the same pixels: ``replicator.io``), the frame records'
    values with the PNGs' sizes left out (they follow the bytes), any other file's bytes. The journals
    (``frames/records-<host>-<pid>.jsonl``: their names and the order of their lines follow the processes
    that wrote them) are one entry, ``frames/records``: each frame's record, how many complete lines the
    journals hold (one a frame when none is stale) and their torn tails."""
    tree = {str(p.relative_to(root)): _content(p, root) for p in sorted(root.rglob("*"))
            if p.is_file() and not (p.parent == root / "frames" and JOURNAL_FILE.fullmatch(p.name))}
    journals = records.journals(root / "frames")
    if journals:
        split = [records.split_journal(path.read_bytes()) for path in journals]
        tree["frames/records"] = ({i: _record_values(r) for i, r in sorted(records.read_records(root / "frames").items())},
                                  sum(len(lines) for lines, _ in split), [tail for _, tail in split if tail])
    return tree


def _record_values(record: dict) -> dict:
    record = dict(record)
    record["files"] = {k: (None if k.endswith(".png") else v) for k, v in record["files"].items()}
    return record


def _content(path: Path, root: Path):
    if path.suffix == ".png":
        from PIL import Image, UnidentifiedImageError

        try:
            pixels = np.asarray(Image.open(path))
        except UnidentifiedImageError:  # a user's file, or a damaged frame: its bytes
            return path.read_bytes()
        return "png", pixels.dtype.str, pixels.shape, pixels.tobytes()
    return path.read_bytes()


def frame_records(root: Path) -> dict[int, dict]:
    """Frame index -> record of dataset ``root`` (its journals)."""
    return records.read_records(Path(root) / "frames")


def generate_argv(out: Path, frames: int, *extra: str) -> list[str]:
    """``ambulo generate`` of the example scene at SIZE, seed 4, as a subprocess command."""
    return [sys.executable, "-m", "ambulo.cli", "generate", "--frames", str(frames), "--out", str(out),
            "--seed", "4", "--width", str(SIZE[0]), "--height", str(SIZE[1]), "--quiet", *extra]


def cli_env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}


def start_and_wait_for_records(argv: list[str], records_dir: Path, at_least: int = 5) -> subprocess.Popen:
    """Start ``argv`` and return once ``records_dir`` (a dataset's ``frames/``) holds ``at_least`` frame
    records (still running)."""
    run = subprocess.Popen(argv, env=cli_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.time() + 120
    while time.time() < deadline and run.poll() is None:
        if records_dir.is_dir() and records.count_records(records_dir) >= at_least:
            break
        time.sleep(0.02)
    assert run.poll() is None, "the run finished before it could be killed: raise the frame count"
    return run


@pytest.fixture(name="gen")
def generate_helpers():
    """Helpers of the generate tests: file_tree, generate_argv, cli_env, start_and_wait_for_records."""
    return types.SimpleNamespace(file_tree=file_tree, argv=generate_argv, env=cli_env,
                                 start=start_and_wait_for_records, records=frame_records)


def small_config(outputs=("coco", "depth", "masks")):
    """The example scene at 160x120 with the given writers (fast enough for tests)."""
    config = rep.example_config(*SIZE)
    return dataclasses.replace(config, writer=dataclasses.replace(config.writer, outputs=outputs))


@pytest.fixture(name="small_config")
def small_config_fixture():
    return small_config


@pytest.fixture(scope="session")
def dataset(tmp_path_factory):
    """12 frames of the example scene with every writer, generated once per session."""
    out = tmp_path_factory.mktemp("dataset")
    config = dataclasses.replace(small_config(("coco", "depth", "masks", "kitti", "raw")), visible_fraction=True)
    rep.generate(config, out, num_frames=12, seed=5, show_progress=False)
    return out
