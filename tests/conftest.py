import pytest

from ambulo.sim import World


@pytest.fixture(autouse=True)
def _fresh_world_singleton():
    # World.instance() is the "current stage"; keep tests from seeing each other's
    yield
    World._instance = None
