import dataclasses

import pytest

from ambulo import replicator as rep

SIZE = (160, 120)


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
