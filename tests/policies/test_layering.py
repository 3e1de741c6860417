"""policies/ is content (DESIGN.md "Layers"): it may read core, robots and assets, never the
layers that run it (sim, envs, rl, the apps)."""

import pytest
from test_layers import wrong_way_imports

ABOVE_POLICIES = ["ambulo.sim", "ambulo.envs", "ambulo.rl", "ambulo.isaac", "ambulo.ros2", "ambulo.perception",
                  "ambulo.nav", "ambulo.locomotion", "ambulo.replicator", "ambulo.cli", "ambulo.demo"]


@pytest.mark.parametrize("higher", ABOVE_POLICIES)
def test_policies_import_nothing_above_them(higher):
    found = wrong_way_imports("ambulo.policies", higher)
    assert not found, f"ambulo.policies must not import {higher}: " + "; ".join(found)
