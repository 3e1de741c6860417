"""Local worker processes: the same files as one process, a killed parallel run resumes, worker errors surface."""

import dataclasses
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ambulo import replicator as rep
from ambulo.replicator.processes import _MAX_CHUNK, _MIN_CHUNK, _chunks, default_workers
from ambulo.utils.atomic import TMP_MARK


def test_one_and_two_worker_processes_write_identical_files(tmp_path, small_config, gen):
    config = small_config()
    # a closure, as a config file or notebook would give: the workers get it by value (cloudpickle)
    build = config.build_scene
    config = dataclasses.replace(config, build_scene=lambda: build())
    rep.generate(config, tmp_path / "one", num_frames=10, seed=7, workers=1, show_progress=False)
    rep.generate(config, tmp_path / "two", num_frames=10, seed=7, workers=2, show_progress=False,
                 backend="processes")
    one, two = gen.file_tree(tmp_path / "one"), gen.file_tree(tmp_path / "two")
    assert one.keys() == two.keys() and len(one) == 10 * 3 + 1 + 3  # 3 images a frame, the records, 3 top files
    assert [name for name in one if one[name] != two[name]] == []


def test_an_error_in_a_worker_process_is_raised_by_generate(tmp_path, small_config):
    def broken_scene():
        raise RuntimeError("no scene here")

    config = dataclasses.replace(small_config(), build_scene=broken_scene)
    with pytest.raises(RuntimeError, match="no scene here"):
        rep.generate(config, tmp_path, num_frames=8, seed=0, workers=2, show_progress=False)


def test_default_workers_and_chunks():
    assert default_workers(10) == 1  # process start-up would cost more than it saves
    assert 1 <= default_workers(100_000) <= os.cpu_count()
    frames = list(range(3, 1000))
    chunks = _chunks(frames, 2)
    sizes = [len(c) for c in chunks]
    assert [i for c in chunks for i in c] == frames and max(sizes) <= _MAX_CHUNK
    # few tasks (each drains the render/write pipeline), shrinking so the processes end together
    assert len(chunks) <= 10 and sizes == sorted(sizes, reverse=True) and sizes[-2] == _MIN_CHUNK
    # the last tasks are small, so a process left without one waits little for the other's last
    assert _MIN_CHUNK <= 4 and sizes[-1] <= _MIN_CHUNK
    assert [len(c) for c in _chunks(list(range(40)), 2)] == [20, 10, 5, 4, 1]


def _children(pid: int) -> list[int]:
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            kids.append(int(stat.parent.name))
    return kids


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_killed_parallel_run_leaves_no_workers_and_resumes_to_the_one_process_result(tmp_path, gen):
    frames = 120
    records = tmp_path / "resumed" / "frames"
    victim = gen.start(gen.argv(tmp_path / "resumed", frames, "--workers", "2"), records)
    workers = [pid for pid in _children(victim.pid) if "spawn_main" in Path(f"/proc/{pid}/cmdline").read_text()]
    victim.send_signal(signal.SIGKILL)
    victim.wait()
    assert len(workers) == 2
    deadline = time.time() + 10
    while any(Path(f"/proc/{pid}").exists() for pid in workers) and time.time() < deadline:
        time.sleep(0.05)
    # they died with their parent: nothing writes into the folder while it is resumed
    assert not [pid for pid in workers if Path(f"/proc/{pid}").exists() and
                (Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z")]
    done_before = len(gen.records(tmp_path / "resumed"))
    assert 5 <= done_before < frames
    subprocess.run(gen.argv(tmp_path / "resumed", frames, "--workers", "2"), env=gen.env(), check=True,
                   capture_output=True)
    subprocess.run(gen.argv(tmp_path / "straight", frames, "--workers", "1"), env=gen.env(), check=True,
                   capture_output=True)
    resumed, straight = gen.file_tree(tmp_path / "resumed"), gen.file_tree(tmp_path / "straight")
    assert not [name for name in resumed if TMP_MARK in name]
    assert resumed == straight
