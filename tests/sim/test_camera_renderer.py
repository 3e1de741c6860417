"""Isaac's ``SimulationApp({"renderer": ...})`` picks the colour tier of the cameras made after it."""

import pytest

from ambulo.isaac.app import SimulationApp
from ambulo.sim import camera as sim_camera
from ambulo.sim.world import World


@pytest.fixture(autouse=True)
def _restore_default_renderer():
    # the cameras join the current World: start without one another test left (a name taken there fails)
    World.clear_instance()
    yield
    World.clear_instance()
    sim_camera.set_default_renderer("raster")


@pytest.mark.parametrize(("mode", "tier"), [("RayTracedLighting", "pbr"), ("PathTracing", "path"), ("raster", "raster")])
def test_simulation_app_renderer_sets_the_tier_of_new_cameras(mode, tier):
    SimulationApp({"headless": True, "renderer": mode})
    assert sim_camera.default_renderer() == tier
    assert sim_camera.Camera("/World/cam", resolution=(64, 48)).cfg.renderer == tier
    # an explicit argument wins over the app's default
    assert sim_camera.Camera("/World/cam2", resolution=(64, 48), renderer="raster").cfg.renderer == "raster"


def test_simulation_app_without_a_renderer_keeps_the_rasterizer():
    sim_camera.set_default_renderer("pbr")
    sim_camera.set_default_renderer("raster")
    SimulationApp({"headless": True})
    assert sim_camera.Camera("/World/cam", resolution=(64, 48)).cfg.renderer == "raster"


def test_an_unknown_render_mode_is_refused_in_one_line():
    with pytest.raises(ValueError, match="renderer 'Storm' is not one ambulo renders"):
        SimulationApp({"renderer": "Storm"})
