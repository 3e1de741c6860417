"""One object-goal episode end to end: the shipped detector, the search and the approach (slow: minutes)."""

import pytest

from ambulo.navigation import NavigatorCfg
from ambulo.navigation.object_episode import DETECTOR_PATH, ObjectEpisodeCfg, run_object_episode

pytestmark = pytest.mark.slow


@pytest.mark.skipif(not DETECTOR_PATH.is_file(), reason="the apartment-objects detector is not shipped")
def test_the_robot_finds_a_shelf_and_stops_within_a_metre_facing_it():
    # apartment 1101 (after the detector's training apartments 1000-1079): oracle pose and map; ~25 s simulated,
    # ~15-25 s of wall time on an idle core
    cfg = ObjectEpisodeCfg(navigator=NavigatorCfg(mode="oracle", time_limit_s=60.0), time_limit_s=150.0)
    r = run_object_episode(1101, 0, "shelf", cfg)
    assert r["status"] == "found", r
    assert r["localized_correct"], r
    assert r["distance_to_object_m"] <= 1.0 and r["facing"] and not r["fell"]
    assert r["success"]
