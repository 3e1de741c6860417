"""`ambulo generate` touches only its own files and never mixes datasets (issue 8, item 3).

Temporaries only ambulo names are deleted; a folder made with other settings is refused with
the difference named; damaged frames are made again; files are flushed before their record;
bad --out, bad numbers and SIGINT/SIGTERM/SIGKILL each leave the disk as it was, or resumable.
"""

import contextlib
import dataclasses
import errno
import json
import os
import shutil
import signal
import sys
from pathlib import Path

import pytest

from ambulo import replicator as rep
from ambulo.cli import main
from ambulo.replicator import records
from ambulo.replicator.manifest import MANIFEST, DatasetFolderError
from ambulo.utils.atomic import TMP_MARK, temporary_name

SEED = 1
FRAMES = 4
LONG_RUN = 100  # frames of the interrupted runs: enough to still be running when they are stopped


def config() -> rep.DatasetConfig:
    """The example scene at 160x120: what ``ambulo generate --width 160 --height 120`` makes."""
    return rep.example_config(160, 120)


def make(config, out: Path, frames: int, seed: int = SEED, **kwargs) -> Path:
    rep.generate(config, out, num_frames=frames, seed=seed, show_progress=False, **kwargs)
    return out


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> Path:
    """A dataset of FRAMES frames of the test config, made in one clean run (never modified)."""
    return make(config(), tmp_path_factory.mktemp("clean"), FRAMES)


@pytest.fixture(scope="module")
def clean_long(tmp_path_factory) -> Path:
    """LONG_RUN frames in one clean run: what every interrupted run must resume to."""
    return make(config(), tmp_path_factory.mktemp("clean_long"), LONG_RUN)


def copy_of(dataset: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(dataset, tmp_path / "out"))


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    """``ambulo generate`` in this process at the test size: (exit status, stdout, stderr)."""
    status = main(["generate", "--width", "160", "--height", "120", "--quiet", *argv])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ambulo generate: error: "), err
    return lines[0]


# -- only ambulo's own files are deleted -------------------------------------------------------------

def test_user_files_with_tmp_in_their_names_survive_and_ambulo_temporaries_go(tmp_path, clean, gen):
    out = copy_of(clean, tmp_path)
    users = {"rgb/000001.png.tmp-42": b"a user's backup", "rgb/notes.tmp-draft.txt": b"notes",
             "my.tmp-file": b"top level", f"depth/x{TMP_MARK}7-deadbeef": b"not hidden: not ours"}
    for name, data in users.items():
        (out / name).write_bytes(data)
    leftovers = [out / "rgb" / temporary_name("000003.png"), out / temporary_name("metadata.json")]
    for path in leftovers:
        path.write_bytes(b"half a file from a killed run")
    make(config(), out, FRAMES)
    tree = gen.file_tree(out)
    assert {name: tree.get(name) for name in users} == users
    assert not any(path.exists() for path in leftovers)
    assert {k: v for k, v in tree.items() if k not in users} == gen.file_tree(clean)


def test_overwrite_deletes_only_the_datasets_own_files(tmp_path, clean, gen):
    out = copy_of(clean, tmp_path)
    users = {"rgb/keep.png": b"my picture", "README.md": b"my notes", "frames/notes.json": b"{}"}
    for name, data in users.items():
        (out / name).write_bytes(data)
    (out / "rgb" / "000007.jpg").write_bytes(b"\xff\xd8")  # a JPEG frame of the GPU writer's: the dataset's own
    make(config(), out, 2, seed=2, overwrite=True)
    assert not (out / "rgb" / "000007.jpg").exists()
    fresh = make(config(), tmp_path / "fresh", 2, seed=2)
    tree = gen.file_tree(out)
    assert {name: tree.get(name) for name in users} == users
    assert {k: v for k, v in tree.items() if k not in users} == gen.file_tree(fresh)  # frames 2, 3 are gone


# -- a resume never mixes datasets ---------------------------------------------------------------------

def test_a_folder_made_with_seed_1_refuses_seed_2_and_names_it(tmp_path, clean, capsys, gen):
    out = copy_of(clean, tmp_path)
    before = gen.file_tree(out)
    status, stdout, err = cli(capsys, "--frames", str(FRAMES), "--out", str(out), "--seed", "2")
    line = one_error_line(err)
    assert status == 2 and "wrote" not in stdout
    assert "seed 1 (now 2)" in line and "--overwrite" in line and "another output folder" in line
    assert gen.file_tree(out) == before


def test_another_resolution_is_refused_naming_width_and_height(tmp_path, clean, capsys, gen):
    out = copy_of(clean, tmp_path)
    before = gen.file_tree(out)
    status, _, err = cli(capsys, "--frames", str(FRAMES), "--out", str(out), "--seed", "1",
                         "--width", "200", "--height", "100")
    line = one_error_line(err)
    assert status == 2 and "width 160 (now 200)" in line and "height 120 (now 100)" in line
    assert gen.file_tree(out) == before


def test_a_dataset_of_the_old_draws_is_refused_in_one_line_naming_the_cause_and_the_fix(tmp_path, clean, capsys,
                                                                                         gen):
    """Before 2026-11-30 the fingerprint had no draw scheme (torch draws seeded by default_rng): such a
    dataset's frames have other numbers, so resuming it would mix two datasets."""
    out = copy_of(clean, tmp_path)
    manifest = json.loads((out / MANIFEST).read_text())
    del manifest["fingerprint"]["draws"]
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2))
    before = gen.file_tree(out)
    status, stdout, err = cli(capsys, "--frames", str(FRAMES + 1), "--out", str(out), "--seed", str(SEED))
    line = one_error_line(err)
    assert status == 2 and "wrote" not in stdout
    assert "drawn by an ambulo from before 2026-11-30" in line
    assert "the ambulo version that started it" in line and "--overwrite" in line
    assert gen.file_tree(out) == before
    # another scheme's name (a later change) is named as the difference, with the same fix
    manifest["fingerprint"]["draws"] = "some other scheme"
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2))
    with pytest.raises(DatasetFolderError, match=r"draws \"some other scheme\".*the ambulo version that started it"):
        make(config(), out, FRAMES + 1)


@pytest.mark.parametrize("change, key", [
    (lambda c: dataclasses.replace(c, randomizers=[
        dataclasses.replace(r, intensity=rep.uniform(0.1, 0.2)) if r.name == "lights" else r
        for r in c.randomizers]), "randomizers.lights.intensity"),
    (lambda c: dataclasses.replace(c, writer=dataclasses.replace(c.writer, outputs=("coco", "kitti"))),
     "writer.outputs"),
    (lambda c: dataclasses.replace(c, build_scene=lambda: _scene_with_a_box(c.build_scene)), "scene_sha256"),
], ids=["randomizer", "writer", "scene"])
def test_a_config_change_is_refused_naming_the_key(tmp_path, clean, gen, change, key):
    out = copy_of(clean, tmp_path)
    before = gen.file_tree(out)
    with pytest.raises(DatasetFolderError, match=key.replace(".", r"\.")):
        make(change(config()), out, FRAMES)
    assert gen.file_tree(out) == before


def _scene_with_a_box(build):
    spec = build()
    spec.worldbody.add_geom(size=[0.1, 0.1, 0.1], pos=[2.0, 0.0, 0.1])
    return spec


def test_more_frames_extend_a_dataset_and_fewer_are_refused(tmp_path, clean, gen):
    out = make(config(), tmp_path / "short", 2)
    make(config(), out, FRAMES)
    assert gen.file_tree(out) == gen.file_tree(clean)
    with pytest.raises(DatasetFolderError, match=r"frames 2-3, beyond the 2 asked for.*--frames 4 or more"):
        make(config(), out, 2)
    assert gen.file_tree(out) == gen.file_tree(clean)


# -- damaged frames are detected and made again -----------------------------------------------------

def test_truncated_images_and_torn_records_are_made_again_byte_identical(tmp_path, clean, gen):
    """A record line that does not parse (frame 2's, cut in half but for its newline) is dropped and its
    frame made again, as the frames whose files lost bytes."""
    out = copy_of(clean, tmp_path)
    png = out / "rgb" / "000001.png"
    png.write_bytes(png.read_bytes()[: png.stat().st_size // 2])
    (journal,) = records.journals(out / "frames")
    lines = journal.read_bytes().split(b"\n")
    torn = [i for i, line in enumerate(lines) if records.frame_of_line(line) == 2]
    assert len(torn) == 1
    lines[torn[0]] = lines[torn[0]][: len(lines[torn[0]]) // 2]
    journal.write_bytes(b"\n".join(lines))
    assert sorted(records.complete_records(out)) == [0, 3]  # frame 1: its rgb image; frame 2: its record
    (out / "depth" / "000003.png").write_bytes(b"")
    (out / "instance" / "000000.png").unlink()
    make(config(), out, FRAMES)
    assert gen.file_tree(out) == gen.file_tree(clean)


def test_a_frame_made_again_loses_its_record_before_its_files_are_rewritten(tmp_path, clean, gen, monkeypatch):
    """Files are written in place (no temporary and rename): a run cut short while it rewrites a
    damaged frame must leave that frame without a record, never its old record over files half
    rewritten; the next run then makes it whole."""
    from ambulo.replicator import writers

    out = copy_of(clean, tmp_path)
    png = out / "rgb" / "000001.png"
    png.write_bytes(png.read_bytes()[:100])
    write_file = writers.write_file

    def cut_short(path, data, fsync=False):
        if path.endswith(os.path.join("depth", "000001.png")):
            raise OSError(errno.EIO, "cut short")
        return write_file(path, data, fsync)

    monkeypatch.setattr(writers, "write_file", cut_short)
    with pytest.raises(OSError, match="cut short"):
        make(config(), out, FRAMES)
    assert 1 not in records.record_lines(out / "frames")  # no line of it at all, not its old one
    assert not writers.frame_is_complete(out, 1)
    monkeypatch.setattr(writers, "write_file", write_file)
    make(config(), out, FRAMES)
    assert gen.file_tree(out) == gen.file_tree(clean)


@pytest.mark.parametrize("flush", ["syncfs", "fsync"])
def test_frame_files_reach_the_disk_before_their_record(tmp_path, monkeypatch, flush):
    """Every data file is written and flushed to disk before its record is appended to the journal:
    with ``syncfs`` (Linux) one flush of the file system after the batch's files; else each file
    before it is closed and its folder after it; and the journal is flushed before it is closed.
    A file counts as written when it is closed."""
    from ambulo.utils import atomic

    events = []
    fsync, close, syncfs = os.fsync, os.close, atomic._syncfs

    def logged_fsync(fd):
        events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}")))
        fsync(fd)

    def logged_close(fd):
        with contextlib.suppress(OSError):
            events.append(("close", os.readlink(f"/proc/self/fd/{fd}")))
        close(fd)

    def logged_syncfs(fd):
        events.append(("syncfs", os.readlink(f"/proc/self/fd/{fd}")))
        return syncfs(fd)

    if not sys.platform.startswith("linux"):
        pytest.skip("reads /proc/self/fd")
    if flush == "syncfs" and syncfs is None:
        pytest.skip("no syncfs in this C library")
    monkeypatch.setattr(os, "fsync", logged_fsync)
    monkeypatch.setattr(os, "close", logged_close)
    monkeypatch.setattr(atomic, "_syncfs", logged_syncfs if flush == "syncfs" else None)
    out = make(config(), tmp_path / "d", 2).resolve()
    (journal,) = records.journals(out / "frames")
    record_at = min(i for i, e in enumerate(events) if e == ("close", str(journal)))  # one append: 2 frames
    assert ("fsync", str(journal)) in events[:record_at]
    assert list(records.read_records(out / "frames")) == [0, 1]
    for index in range(2):
        files = records.read_records(out / "frames")[index]["files"]
        assert len(files) == 3  # rgb, depth, instance (no semantic image unless asked)
        for relpath in files:
            path = out / relpath
            written = max(i for i, e in enumerate(events) if e == ("close", str(path)))
            assert written < record_at, relpath
            if flush == "syncfs":  # the whole file system, after the file and before the record
                assert any(written < i < record_at for i, (kind, p) in enumerate(events)
                           if kind == "syncfs" and out.is_relative_to(p)), relpath
                continue
            flushed = [i for i, e in enumerate(events) if e == ("fsync", str(path))]
            folder = [i for i, e in enumerate(events) if e == ("fsync", str(path.parent))]
            assert flushed and flushed[-1] < written, relpath
            assert any(written < i < record_at for i in folder), relpath


# -- the command line: bad --out, bad numbers, the success line ------------------------------------

def test_out_that_is_an_existing_file_is_refused(tmp_path, capsys):
    target = tmp_path / "results.csv"
    target.write_bytes(b"a,b\n1,2\n")
    status, _, err = cli(capsys, "--frames", "1", "--out", str(target))
    assert status == 2 and "is an existing file" in one_error_line(err)
    assert target.read_bytes() == b"a,b\n1,2\n" and os.listdir(tmp_path) == ["results.csv"]


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_non_empty_folder_that_is_not_a_dataset_is_refused(tmp_path, capsys, gen, overwrite):
    folder = tmp_path / "photos"
    (folder / "rgb").mkdir(parents=True)
    (folder / "rgb" / "000000.png").write_bytes(b"my photo")
    (folder / "dataset.json").write_text('{"name": "an nnU-Net dataset"}')
    (folder / "annotations.json").write_text("{}")
    before = gen.file_tree(folder)
    status, _, err = cli(capsys, "--frames", "1", "--out", str(folder), *(["--overwrite"] if overwrite else []))
    line = one_error_line(err)
    assert status == 2 and "not an ambulo dataset" in line and "new or empty folder" in line
    assert gen.file_tree(folder) == before and sorted(os.listdir(folder)) == ["annotations.json", "dataset.json",
                                                                              "rgb"]


@pytest.mark.parametrize("where", ["under_a_file", "read_only_fs"])
def test_an_unwritable_out_gets_one_line(tmp_path, capsys, where):
    if where == "under_a_file":
        (tmp_path / "file").write_bytes(b"x")
        out = tmp_path / "file" / "data"
    else:
        if not Path("/sys/kernel").is_dir():
            pytest.skip("needs Linux sysfs (read-only to every user, root too)")
        out = Path("/sys/ambulo-test-data")
    status, _, err = cli(capsys, "--frames", "1", "--out", str(out))
    line = one_error_line(err)
    assert status == 2 and f"can't write to output folder {str(out)!r}" in line and "you can write to" in line


@pytest.mark.parametrize("flag, value", [("frames", "0"), ("workers", "0"), ("width", "-3"), ("height", "0"),
                                         ("frames", "-1"), ("seed", "-1")])
def test_numbers_that_are_not_positive_get_one_line_with_the_fix(tmp_path, capsys, flag, value):
    status, _, err = cli(capsys, "--out", str(tmp_path / "d"), f"--{flag}", value)
    line = one_error_line(err)
    assert status == 2 and f"--{flag} {value}" in line and f"give --{flag} {0 if flag == 'seed' else 1} or more" in line
    assert not (tmp_path / "d").exists()


def test_success_is_printed_only_when_the_output_exists(tmp_path, capsys, monkeypatch):
    status, stdout, _ = cli(capsys, "--frames", "1", "--out", str(tmp_path / "d"))
    out = tmp_path / "d"
    assert status == 0 and stdout == f"wrote a dataset of 1 frames in {out} (COCO annotations: {out / 'annotations.json'})\n"
    assert (tmp_path / "d" / "annotations.json").is_file()
    monkeypatch.setattr(rep, "generate", lambda *a, **k: tmp_path / "gone" / "annotations.json")
    status, stdout, err = cli(capsys, "--frames", "1", "--out", str(tmp_path / "gone"))
    assert status == 2 and stdout == "" and "missing" in one_error_line(err)


def test_a_full_disk_gets_one_line_saying_how_to_resume(tmp_path, capsys, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "d" / "rgb" / "000007.png"))

    monkeypatch.setattr(rep, "generate", full)
    status, stdout, err = cli(capsys, "--frames", "9", "--out", str(tmp_path / "d"))
    line = one_error_line(err)
    assert status == 2 and stdout == "" and "No space left on device" in line and "000007.png" in line
    assert "run the same command again to resume" in line


# -- stopped runs: one line, and a folder that resumes ------------------------------------------------

@pytest.mark.parametrize("sig, workers", [(signal.SIGTERM, "1"), (signal.SIGINT, "2")],
                         ids=["SIGTERM-1-process", "SIGINT-2-processes"])
def test_a_stopped_run_prints_how_to_resume_and_resumes_to_the_clean_result(tmp_path, clean_long, gen, sig, workers):
    out = tmp_path / "out"
    argv = gen.argv(out, LONG_RUN, "--seed", str(SEED), "--workers", workers)
    victim = gen.start(argv, out / "frames")
    victim.send_signal(sig)
    _, err = victim.communicate(timeout=60)
    err = err.decode()
    assert victim.returncode == 128 + sig, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert f"stopped by {sig.name}" in err and "run the same command again to resume" in err
    assert 5 <= records.count_records(out / "frames") < LONG_RUN
    make(config(), out, LONG_RUN)  # what the command does (test_generate runs it after a SIGKILL)
    assert gen.file_tree(out) == gen.file_tree(clean_long)


def test_a_killed_run_refuses_another_seed_and_resumes_to_the_clean_result(tmp_path, clean_long, gen):
    out = tmp_path / "out"
    victim = gen.start(gen.argv(out, LONG_RUN, "--seed", str(SEED)), out / "frames")
    victim.send_signal(signal.SIGKILL)
    victim.wait()
    before = gen.file_tree(out)
    with pytest.raises(DatasetFolderError, match=r"seed 1 \(now 2\)"):
        make(config(), out, LONG_RUN, seed=2)
    assert gen.file_tree(out) == before
    make(config(), out, LONG_RUN)
    assert gen.file_tree(out) == gen.file_tree(clean_long)
