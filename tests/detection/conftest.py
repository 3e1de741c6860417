import dataclasses

import pytest

from ambulo import replicator as rep


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """8 frames of the example warehouse at 160x120 made by the project's own generator."""
    config = rep.example_config()
    config = dataclasses.replace(config, camera=dataclasses.replace(config.camera, width=160, height=120))
    out = tmp_path_factory.mktemp("detection_data")
    rep.generate(config, out, num_frames=8, seed=3, workers=1, show_progress=False)
    return out
