"""``ambulo navigate``: a short oracle episode end to end, and one-line errors for bad input."""

import json
import math
import re

import imageio.v3 as iio
import numpy as np
import pytest

from ambulo.cli import main
from ambulo.cli.errors import CliError
from ambulo.cli.navigate import check_point
from ambulo.navigation import benchmark
from ambulo.navigation.topdown import COLORS
from ambulo.robots import humanoid
from ambulo.scenes.apartment import apartment

SEED = 1000
START = "4.375,3.025,-17.6"  # apartment 1000's episode 0 with a 3.0-3.5 m geodesic: 3.17 m
GOAL = "7.125,1.725"


def _error_line(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("ambulo navigate: error: ")
    return err


@pytest.fixture(scope="module")
def web_episode(tmp_path_factory):
    """(out folder, served viewer) of one short oracle episode watched with ``--viewer web``: the two
    tests below read the same run (each ran it before: 16 s + 19 s). The viewer only observes (an
    observer of the navigator), so the episode's json and map are what a run without it writes."""
    import socket

    import ambulo.viewer as viewer_pkg

    served = []
    real_serve = viewer_pkg.serve

    def serve(world, port, **kw):
        served.append(real_serve(world, port, announce=False, **kw))
        # as fast as it runs: held to real time (the page's default) the 3.2 m walk took 15 s more; what
        # is checked is what reaches the page, not the pacing (tests/viewer cover that)
        served[-1].set_speed(None)
        return served[-1]

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path_factory.mktemp("navigate") / "ep"
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(viewer_pkg, "serve", serve)
        code = main(["navigate", "apartment", "--seed", str(SEED), "--start", START, "--goal", GOAL,
                     "--out", str(out), "--viewer", "web", "--viewer-port", str(port)])
    assert code == 0
    (viewer,) = served
    return out, viewer


def test_a_short_oracle_episode_arrives_and_writes_its_json_and_map(web_episode):
    out, _ = web_episode
    data = json.loads((out / "episode.json").read_text())
    assert data["success"] and data["status"] == "arrived" and not data["fell"]
    assert data["distance_to_goal_m"] <= 0.3
    assert data["geodesic_m"] == pytest.approx(3.17, abs=0.01)
    assert 0.5 < data["spl"] <= 1.0
    # the map PNG (80 px/m, y up): the true path's pixels run from the start to the goal through free cells
    png = iio.imread(out / "map.png")
    grid = apartment(SEED).occupancy
    ox, oy = grid.origin_xy_m
    h = png.shape[0]
    xy = np.array([float(v) for v in START.split(",")[:2]])
    goal = np.array([float(v) for v in GOAL.split(",")])
    blue = np.all(png == COLORS["true"], axis=-1)
    assert blue.sum() > 100
    rows, cols = np.nonzero(blue)
    path_xy = np.stack([ox + (cols + 0.5) / 80.0, oy + (h - rows - 0.5) / 80.0], -1)
    # the drawn path starts at the start pose and ends near the goal, and never crosses a wall
    assert np.linalg.norm(path_xy - xy, axis=1).min() < 0.05
    assert np.linalg.norm(path_xy - goal, axis=1).min() < 0.35
    iy, ix = grid.cells_of(path_xy)
    assert not grid.occupied()[iy, ix].any()


def test_bad_inputs_give_one_line_with_the_fix(capsys, tmp_path):
    grid = apartment(SEED).occupancy
    iy, ix = np.argwhere(grid.occupied())[len(np.argwhere(grid.occupied())) // 2]
    wx, wy = grid.cell_center_xy_m(iy, ix)
    base = ["navigate", "apartment", "--seed", str(SEED), "--out", str(tmp_path)]
    err = _error_line(capsys, [*base, "--start", START, "--goal", f"{wx},{wy}"])
    assert "inside an obstacle" in err and "nearest point with room for the robot" in err
    x0, y0, x1, y1 = grid.extent_xy_m()
    err = _error_line(capsys, [*base, "--start", f"{x1 + 5},{y0},0", "--goal", GOAL])
    assert "--start" in err and "outside the map" in err
    err = _error_line(capsys, [*base, "--goal", "4,abc"])
    assert "--goal '4,abc' is not x,y" in err and "e.g. --goal" in err
    err = _error_line(capsys, [*base, "--start", "1,2,3,4", "--goal", GOAL])
    assert "--start" in err
    err = _error_line(capsys, ["navigate", str(tmp_path / "nope.xml"), "--start", "0,0", "--goal", "1,1"])
    assert "neither 'apartment' nor a file" in err
    world = tmp_path / "w.xml"
    world.write_text("<mujoco/>")
    err = _error_line(capsys, ["navigate", str(world), "--goal", "1,1"])
    assert "needs --start and --goal" in err
    err = _error_line(capsys, [*base, "--mode", "teleport"])
    assert "--mode 'teleport' is not a mode" in err
    err = _error_line(capsys, [*base, "--time-limit", "-3"])
    assert "--time-limit" in err
    err = _error_line(capsys, ["navigate", "--episodes", "2", "--goal", "1,1", "--out", str(tmp_path)])
    assert "--goal applies to one episode" in err
    # object goals: an unknown class, a class the apartment lacks, a missing detector, a goal beside the object
    err = _error_line(capsys, ["navigate", "apartment", "--seed", "5", "--object", "unicorn", "--out", str(tmp_path)])
    assert "no apartment object is called 'unicorn'" in err and "--object" in err
    err = _error_line(capsys, ["navigate", "apartment", "--seed", "5", "--object", "table", "--out", str(tmp_path)])
    assert "apartment 5 has no table; it has armchair" in err and "another --seed" in err
    err = _error_line(capsys, ["navigate", "apartment", "--seed", "5", "--object", "sofa", "--detector",
                               str(tmp_path / "none.onnx"), "--out", str(tmp_path)])
    assert "no detector at" in err
    err = _error_line(capsys, [*base, "--object", "sofa", "--goal", GOAL])
    assert "--goal does not go with --object" in err


def test_zmp_walker_refused_with_one_line_while_its_adapter_is_missing(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(benchmark, "zmp_walker_available", lambda: False)
    err = _error_line(capsys, ["navigate", "apartment", "--seed", str(SEED), "--walker", "zmp", "--start", START,
                               "--goal", GOAL, "--out", str(tmp_path)])
    assert "not available yet" in err and "--walker policy" in err


def test_a_point_too_near_a_wall_gets_a_suggestion_that_passes():
    grid = apartment(SEED).occupancy
    occupied = grid.occupied()
    # a free cell next to an occupied one: 0.025 m of clearance
    free_next = np.argwhere(~occupied[1:-1, 1:-1] & occupied[1:-1, 2:])[0] + 1
    x, y = (float(v) for v in grid.cell_center_xy_m(*free_next))
    with pytest.raises(CliError) as info:
        check_point(grid, (x, y), "--goal", humanoid.BODY_RADIUS_M)
    assert re.search(r"is 0\.0\d m from an obstacle", info.value.problem)
    sx, sy = (float(v) for v in re.search(r"--goal (-?[\d.]+),(-?[\d.]+)$", info.value.fix).groups())
    check_point(grid, (sx, sy), "--goal", humanoid.BODY_RADIUS_M)  # passes
    assert math.dist((x, y), (sx, sy)) < 0.6  # the nearest such point: within the body radius + a few cells


ROOM = """<mujoco><worldbody>
  <geom type="plane" size="5 5 0.1"/>
  <geom type="box" pos="1.5 0.5 0.5" size="0.3 0.3 0.5"/>
  <geom type="box" pos="0 3 0.5" size="4 0.1 0.5"/>
</worldbody></mujoco>"""


@pytest.mark.slow
def test_a_users_mjcf_world(tmp_path, capsys):
    world = tmp_path / "room.xml"
    world.write_text(ROOM)
    # the goal inside the box: refused, with a point beside it
    err = _error_line(capsys, ["navigate", str(world), "--start", "0,0,0", "--goal", "1.5,0.5", "--out", str(tmp_path)])
    assert "inside an obstacle" in err
    # past the box: it walks around it, the geodesic taken from the route on the true map
    assert main(["navigate", str(world), "--start", "0,0,0", "--goal", "3,0.5", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "episode.json").read_text())
    assert data["success"] and data["collisions"] == 0 and data["geodesic_m"] >= math.dist((0, 0), (3, 0.5))
    assert data["world"] == str(world) and "not exact" in data["extras"]["geodesic"]


def test_viewer_web_gets_the_navigators_map_plan_footsteps_and_path(web_episode):
    """``--viewer web`` feeds the page what the navigator sees: its map, route, footsteps and walk."""
    _, viewer = web_episode
    assert {"map", "plan", "footsteps", "path"} <= set(viewer.feed.layers())
    walked = viewer.feed.get("path")
    goal = np.array([float(v) for v in GOAL.split(",")])
    assert np.linalg.norm(walked[-1][:2] - goal) < 0.35  # the page's walked path ends at the goal


def test_walker_offers_every_walker_of_the_benchmark():
    """``--walker`` (a literal tuple: the CLI imports the navigation package only when it runs) names the same
    walkers as ``navigation.benchmark.WALKERS``, the learned footstep walker among them."""
    import argparse

    from ambulo.cli import navigate

    parser = argparse.ArgumentParser()
    navigate.add_commands(parser.add_subparsers())
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices["navigate"]
    walker = next(a for a in sub._actions if a.dest == "walker")
    assert tuple(walker.choices) == benchmark.WALKERS
