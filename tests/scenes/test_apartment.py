"""Seeded procedural apartments (``ambulo.scenes.apartment``): determinism, the plan's bounds, the
occupancy against an independent shapely rasterization and MuJoCo's ray caster, the sampler's
starts and goals against shapely's geometry and an exact visibility-graph geodesic, and the
scene in a World with the humanoid standing in it."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import LineString, Point, Polygon, box

from ambulo.maps import OCCUPIED
from ambulo.robots.humanoid import BODY_RADIUS_M as HUMANOID_RADIUS_M
from ambulo.robots.humanoid import HEAD_HEIGHT_M as HUMANOID_HEAD_HEIGHT_M
from ambulo.scenes.apartment import ApartmentCfg, apartment
from ambulo.scenes.apartment_paths import path_length_m
from one_line import raises_one_line

SEEDS = (0, 1, 2, 3)


@pytest.fixture(scope="module")
def apartments():
    return {seed: apartment(seed) for seed in SEEDS}


def blocking_shapes(apt, cfg: ApartmentCfg | None = None):
    """The test's own reading of the body-band rule on the plan's solids: shapely rectangles
    (from the box's corners) and exact discs (centre, radius)."""
    cfg = cfg or apt.cfg
    rects, discs = [], []
    for s in apt.solids:
        bottom, top = s.center_m[2] - s.half_m[2], s.center_m[2] + s.half_m[2]
        if not (top > cfg.step_height_m and bottom < cfg.head_height_m):
            continue
        if s.shape == "box":
            c, si = math.cos(s.yaw_rad), math.sin(s.yaw_rad)
            hx, hy = s.half_m[0], s.half_m[1]
            rects.append(Polygon([(s.center_m[0] + px * c - py * si, s.center_m[1] + px * si + py * c)
                                  for px, py in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))]))
        else:
            discs.append((Point(s.center_m[:2]), s.half_m[0]))
    return rects, discs


def obstacle_union(apt, clearance_m: float, quad_segs: int = 8):
    """The configuration-space obstacles: every blocking footprint grown by ``clearance_m``
    (shapely's polygonal arcs lie inside the true arcs, so obstacles come out a little small)."""
    rects, discs = blocking_shapes(apt)
    grown = [r.buffer(clearance_m, quad_segs=quad_segs) for r in rects]
    grown += [p.buffer(rad + clearance_m, quad_segs=quad_segs) for p, rad in discs]
    return shapely.unary_union(grown)


def test_same_seed_same_apartment_and_mjcf():
    a, b, c = apartment(5), apartment(5), apartment(6)
    assert np.array_equal(a.occupancy.occupancy, b.occupancy.occupancy)
    assert a.occupancy.origin_xy_m == b.occupancy.origin_xy_m
    assert a.build().to_xml() == b.build().to_xml()
    assert a.build(robot_pose=(1.0, 2.0, 0.5)).to_xml() == b.build(robot_pose=(1.0, 2.0, 0.5)).to_xml()
    assert a.occupancy.shape != c.occupancy.shape or not np.array_equal(a.occupancy.occupancy, c.occupancy.occupancy)
    assert a.sample_start_goal(3).start_pose == b.sample_start_goal(3).start_pose


def test_rooms_doors_and_walls_within_bounds():
    counts = set()
    for seed in range(14):
        apt = apartment(seed)
        rooms = [r for r in apt.rooms if not r.is_corridor]
        counts.add(len(rooms))
        assert 2 <= len(rooms) <= 5
        assert sum(r.is_corridor for r in apt.rooms) == 1
        walls = [s for s in apt.solids if s.look == "wall"]
        thickness = {round(2 * min(w.half_m[:2]), 9) for w in walls}
        assert len(thickness) == 1 and 0.1 <= thickness.pop() <= 0.15
        for room in rooms:  # every room has a door
            assert any(room.name in d.rooms for d in apt.doors), (seed, room.name)
        rects, discs = blocking_shapes(apt)
        for door in apt.doors:
            assert 0.8 <= door.width_m <= 1.0
            # the opening: no solid nearer the door's centre than its jambs, half the width away
            centre = Point(door.center_xy_m)
            nearest = min([r.distance(centre) for r in rects] + [p.distance(centre) - rad for p, rad in discs])
            assert nearest == pytest.approx(door.width_m / 2, abs=1e-9), (seed, door)
    assert counts == {2, 3, 4, 5}


def test_occupancy_is_the_exact_rasterization(apartments):
    """Every cell against shapely: the cell's square (shrunk by 1 um) meets a rectangle, or lies
    within a disc's radius of its centre (exact for a disc, unlike a polygonal buffer)."""
    for seed in SEEDS[:2]:
        apt = apartments[seed]
        grid = apt.occupancy
        ny, nx = grid.shape
        iy, ix = np.mgrid[0:ny, 0:nx]
        shrink = 1e-6
        x0 = grid.origin_xy_m[0] + ix * grid.resolution_m + shrink
        y0 = grid.origin_xy_m[1] + iy * grid.resolution_m + shrink
        cells = shapely.box(x0, y0, x0 + grid.resolution_m - 2 * shrink, y0 + grid.resolution_m - 2 * shrink)
        rects, discs = blocking_shapes(apt)
        union = shapely.unary_union(rects)
        shapely.prepare(union)
        expected = shapely.intersects(cells, union)
        for centre, radius in discs:
            expected |= shapely.distance(cells, centre) < radius
        got = grid.occupancy == OCCUPIED
        assert np.array_equal(got, expected), (seed, int((got != expected).sum()))
        assert 0.05 < got.mean() < 0.6


def test_occupancy_agrees_with_mujoco_ray_casts(apartments):
    """A ray straight down from above the walls at each cell centre (every 2nd cell): it stops
    above the step height exactly where the map says a solid covers that centre, and never in a
    FREE cell."""
    apt = apartments[3]
    assert len(apt.footprints.disc_radius_m) >= 3  # pots, round tables, lamp poles: discs as well as boxes
    model = apt.build().compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    grid = apt.occupancy
    top = apt.cfg.wall_height_m + 0.5
    geomid = np.zeros(1, np.int32)
    centres = grid.cell_centers_xy_m()[::2, ::2]
    hit = np.zeros(centres.shape[:2], bool)
    for iy in range(centres.shape[0]):
        for ix in range(centres.shape[1]):
            x, y = centres[iy, ix]
            d = mujoco.mj_ray(model, data, np.array([x, y, top]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid)
            hit[iy, ix] = d >= 0 and top - d > apt.cfg.step_height_m
    occupied = grid.occupied()[::2, ::2]
    assert not (hit & ~occupied).any()  # a solid in the band at a centre: its cell is occupied
    rects, discs = blocking_shapes(apt)
    inside = shapely.intersects_xy(shapely.unary_union(rects), centres[..., 0], centres[..., 1])
    for centre, radius in discs:
        inside |= np.hypot(centres[..., 0] - centre.x, centres[..., 1] - centre.y) <= radius
    assert np.array_equal(hit, inside)
    assert hit.sum() > 500 and (~occupied).sum() > 500


def test_the_band_rule_keeps_low_clutter_and_drops_rugs():
    low = rugs = 0
    with_low = None
    for seed in range(12):
        apt = apartment(seed)
        if with_low is None and any(s.top_m < 0.2 and s.look == "furniture" for s in apt.solids):
            with_low = seed
        for s in apt.solids:
            top = s.center_m[2] + s.half_m[2]
            cell = apt.occupancy.cell_of(s.center_m[:2])
            if s.look == "rug":
                rugs += 1
                assert not s.collides and top <= apt.cfg.step_height_m
            elif top < 0.2 and s.center_m[2] - s.half_m[2] == 0.0 and "/base" not in s.name:
                low += 1  # shoe boxes and book piles: under the shins, still obstacles
                assert apt.occupancy.occupied()[cell]
    assert low > 3 and rugs > 3
    # a raised step height lets the same clutter through
    raised = apartment(with_low, ApartmentCfg(step_height_m=0.2))
    assert raised.occupancy.occupied().sum() < apartment(with_low).occupancy.occupied().sum()


def test_sampled_starts_and_goals_are_connected_with_clearance(apartments):
    for seed, apt in apartments.items():
        obstacles = [*blocking_shapes(apt)[0]] + [p.buffer(rad, quad_segs=64) for p, rad in blocking_shapes(apt)[1]]
        union = shapely.unary_union(obstacles)
        rng = np.random.default_rng(100 + seed)
        for _ in range(4):
            ep = apt.sample_start_goal(rng)
            path = ep.path_xy_m
            assert 3.0 <= ep.geodesic_m <= 15.0
            assert ep.geodesic_m <= path_length_m(path) <= ep.geodesic_m * 1.001  # arcs drawn outside
            assert tuple(path[0]) == ep.start_pose[:2] and tuple(path[-1]) == ep.goal_xy_m
            # shapely's distance from the whole path to every footprint: the robot's radius at least
            # (the polygonal discs sit inside the true ones: this can only be generous by 0.1 mm)
            assert LineString(path).distance(union) >= HUMANOID_RADIUS_M - 1e-4, seed
            assert ep.clearance_m == HUMANOID_RADIUS_M


def exact_geodesic(apt, start, goal, clearance_m):
    """Shortest path length among the grown obstacles (``obstacle_union``): the visibility graph of
    their vertices (an edge kept only where the segment is tangent at both ends, then checked by
    shapely), solved by Dijkstra."""
    x0, y0, x1, y1 = apt.layout.extent_xy_m
    free = box(x0, y0, x1, y1).difference(obstacle_union(apt, clearance_m))
    parts = getattr(free, "geoms", [free])
    free = next(p for p in parts if p.covers(Point(start)))
    rings = [free.exterior, *free.interiors]
    verts, prev, nxt = [], [], []
    for ring in rings:
        c = np.asarray(ring.coords)[:-1]
        verts.append(c)
        prev.append(np.roll(c, 1, axis=0))
        nxt.append(np.roll(c, -1, axis=0))
    verts, prev, nxt = (np.concatenate(v) for v in (verts, prev, nxt))
    pts = np.concatenate([[start], [goal], verts])
    n = len(pts)
    i, j = np.triu_indices(n, 1)
    d = pts[j] - pts[i]

    def cross(u, v):
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]

    def tangent(k, other_dir):  # both ring neighbours of vertex k on one side of the line
        return np.sign(cross(other_dir, prev[k - 2] - pts[k])) * np.sign(cross(other_dir, nxt[k - 2] - pts[k])) >= 0

    ok = np.ones(len(i), bool)
    ok[i >= 2] &= tangent(i[i >= 2], d[i >= 2])
    ok[j >= 2] &= tangent(j[j >= 2], -d[j >= 2])
    i, j = i[ok], j[ok]
    lines = shapely.linestrings(np.stack([pts[i], pts[j]], 1))
    shapely.prepare(free)
    ok = shapely.covers(free, lines)
    i, j = i[ok], j[ok]
    w = np.linalg.norm(pts[j] - pts[i], axis=1)
    graph = coo_matrix((w, (i, j)), shape=(n, n)).tocsr()
    dist, pred = dijkstra(graph, directed=False, indices=0, return_predecessors=True)
    nodes = [1]
    while nodes[-1] > 0:
        nodes.append(int(pred[nodes[-1]]))
    return float(dist[1]), pts[nodes[::-1]]


def test_geodesic_is_the_exact_one(apartments):
    worst = 0.0
    for seed in SEEDS[:2]:
        apt = apartments[seed]
        rng = np.random.default_rng(7 + seed)
        for _ in range(3):
            ep = apt.sample_start_goal(rng)
            exact, _ = exact_geodesic(apt, ep.start_pose[:2], ep.goal_xy_m, HUMANOID_RADIUS_M)
            # shapely's arcs are chords inside the true arcs: its geodesic is a little shorter,
            # by well under 0.1 % (measured: 0.03 % at most over 30 pairs of 6 seeds)
            assert exact - 1e-6 <= ep.geodesic_m <= exact * 1.001 + 1e-3, (seed, ep.geodesic_m, exact)
            worst = max(worst, ep.geodesic_m / exact - 1)
    print(f"largest relative excess over shapely's geodesic: {worst:.5f}")


def test_every_door_is_passable_with_the_robots_clearance(apartments):
    for seed, apt in apartments.items():
        for door in apt.doors:
            x, y = door.center_xy_m
            a, b = ((x, y - 0.6), (x, y + 0.6)) if door.along_x else ((x - 0.6, y), (x + 0.6, y))
            through = apt.geodesic_m(a, b)
            assert through == pytest.approx(1.2, abs=1e-6), (seed, door)  # straight through the opening
        # a robot wider than the narrowest door cannot pass: the same points are cut off
        narrowest = min(apt.doors, key=lambda d: d.width_m)
        x, y = narrowest.center_xy_m
        a, b = ((x, y - 0.6), (x, y + 0.6)) if narrowest.along_x else ((x - 0.6, y), (x + 0.6, y))
        assert apt.geodesic_m(a, b, clearance_m=narrowest.width_m / 2 + 0.01) > 1.3


def test_humanoid_constants_match_the_model():
    from ambulo import assets
    model = mujoco.MjModel.from_xml_path(assets.path("humanoid"))
    data = mujoco.MjData(model)
    reach, top = [], []
    for key in (None, "home"):
        if key is None:
            mujoco.mj_resetData(model, data)
        else:
            mujoco.mj_resetDataKeyframe(model, data, model.key(key).id)
        mujoco.mj_forward(model, data)
        axis = data.xpos[model.body("pelvis").id][:2]
        r = 0.0
        for g in range(model.ngeom):
            # a sphere around each geom's bounding box: the geom is inside it
            rbound = model.geom_rbound[g]
            r = max(r, np.linalg.norm(data.geom_xpos[g][:2] - axis) + rbound if model.geom_type[g] == 2 else r)
        reach.append(r)
        head = model.geom("head").id
        top.append(data.geom_xpos[head][2] + model.geom_size[head][0])
    assert top[0] == pytest.approx(HUMANOID_HEAD_HEIGHT_M, abs=1e-6)
    assert max(reach) <= HUMANOID_RADIUS_M


def test_bad_configs_are_refused_in_one_line():
    raises_one_line(lambda: ApartmentCfg(door_width_range_m=(1.0, 0.8)), "door_width_range_m", "low end")
    raises_one_line(lambda: ApartmentCfg(num_rooms_range=(2, 9)), "num_rooms_range", "<= 6")
    raises_one_line(lambda: ApartmentCfg(resolution_m=0.0), "resolution_m")
    raises_one_line(lambda: ApartmentCfg(step_height_m=2.0), "head_height_m", "band")
    raises_one_line(lambda: apartment(0).sample_start_goal(0, 5.0, 3.0), "min_geodesic_m")
    raises_one_line(lambda: apartment(-1), "seed")


def test_humanoid_stands_at_a_sampled_start_for_one_second_touching_nothing():
    """The scene in an ``ambulo.sim.World`` with the humanoid at a sampled start, held standing by
    the shipped walking policy (zero command) for 1 s: no geom of the robot but its feet touches
    anything, no apartment solid is touched at all, and it is still upright where it started."""
    pytest.importorskip("onnxruntime")
    from ambulo.robots import humanoid
    from ambulo.sim import HumanoidWalkingPolicy, Robot, World

    apt = apartment(2)
    ep = apt.sample_start_goal(0)
    x, y, yaw = ep.start_pose
    world = World(physics_dt=humanoid.POLICY_PHYSICS_DT_S, rendering_dt=0.02)
    apt.build(spec=world.stage.mjspec, robot_pose=ep.start_pose)
    robot = world.scene.add(Robot(prim_path=humanoid.PRIM_PATH, name="humanoid", position=[x, y, 0.0],
                                  orientation=[math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]))
    world.reset()
    walker = HumanoidWalkingPolicy(robot)
    walker.initialize()
    world.add_physics_callback("stand", lambda dt: walker.forward(dt, (0.0, 0.0, 0.0)))
    model = world.engine.model
    robot_body = np.array([model.body(b).name.startswith(humanoid.PRIM_PATH + "/") for b in range(model.nbody)])
    feet = {model.body(f"{humanoid.PRIM_PATH}/{name}").id for name in humanoid.FOOT_BODIES}
    solids = {model.geom(s.name + "/geom").id for s in apt.solids}
    data, touches = None, []
    for _ in range(50):
        world.step(render=False)
        data = world.engine.get_data(0, data)
        for c in data.contact[:data.ncon]:
            bodies = model.geom_bodyid[[c.geom1, c.geom2]]
            if robot_body[bodies].any() and not robot_body[bodies].all():  # robot vs the apartment
                if {c.geom1, c.geom2} & solids or not set(bodies.tolist()) & feet:
                    touches.append((model.geom(c.geom1).name, model.geom(c.geom2).name))
    assert not touches, touches[:5]
    pos = robot.get_world_pose()[0]
    assert np.hypot(pos[0] - x, pos[1] - y) < 0.25 and pos[2] > 0.8


def test_the_figure_script_draws_the_apartments(tmp_path):
    from script_loader import ROOT, run_main

    out = run_main(ROOT / "scripts" / "apartments_figure.py", "--seeds", "1", "4", "--out", str(tmp_path / "a.png"))
    import imageio.v3 as iio

    image = iio.imread(out)
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 600
