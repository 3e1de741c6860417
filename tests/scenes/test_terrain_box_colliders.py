"""``restrict_box_colliders``: the terrain's boxes collide only with the named bodies' geoms, the
hfield with everything, and nothing else changes; a named sphere stands on a stair box, another
falls through it onto the hfield sunk under the boxes and stops on an hfield tile."""

import itertools

import mujoco
import numpy as np
import pytest

from ambulo.scenes.terrain import TERRAIN_PRIM_PATH, TerrainCfg, add_terrain, candidate_geom_pairs, generate
from ambulo.scenes.terrain.box_colliders import restrict_box_colliders
from ambulo.scenes.terrain.boxes import SUNK_M

# one level (the hardest: 0.15 m risers) of a stairs-down pyramid in boxes and a rough tile in the hfield
CFG = TerrainCfg(num_levels=1, tile_size_m=4.0, platform_size_m=1.0, border_m=1.0, kinds=("stairs_down", "rough"))
RADIUS_M = 0.05
# name: (contype, conaffinity), the humanoid's patterns: its body geoms (2, 1), its sole spheres (0, 1)
BODIES = {"leg": (2, 1), "foot": (0, 1), "hand": (2, 1), "hand_on_rough": (2, 1)}
COLLIDERS = ("leg", "foot")


def scene(restrict: bool):
    """(model, grid): the terrain and one free sphere per ``BODIES`` entry, 5 cm over the ground: the
    first three over the summit's platform (a box), the last over the rough tile's (the hfield)."""
    grid = generate(CFG)
    spec = mujoco.MjSpec()
    add_terrain(spec, grid)
    summit, rough = grid.tile_centers_w[0, 0], grid.tile_centers_w[0, 1]
    starts = {"leg": summit + [0.0, -0.3, 0.0], "foot": summit, "hand": summit + [0.0, 0.3, 0.0], "hand_on_rough": rough}
    for name, (contype, conaffinity) in BODIES.items():
        body = spec.worldbody.add_body(name=name, pos=starts[name] + [0.0, 0.0, RADIUS_M + 0.05])
        body.add_freejoint()
        body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[RADIUS_M, 0, 0], contype=contype,
                      conaffinity=conaffinity)
    if restrict:
        restrict_box_colliders(spec, TERRAIN_PRIM_PATH, COLLIDERS)
    return spec.compile(), grid


def names(model, pairs) -> set[frozenset[str]]:
    return {frozenset(model.geom(int(g)).name for g in pair) for pair in pairs}


@pytest.mark.parametrize("restrict", [False, True])
def test_candidate_pairs_follow_the_bits(restrict):
    """By hand from contype/conaffinity: the spheres (2, 1) and (0, 1) never pair with each other
    (2 & 1 = 0); the terrain's geoms (1, 1) pair with all of them; restricted, a box (B, 0) pairs
    only with the named bodies (conaffinity 1 | B), the hfield still with all."""
    model, _ = scene(restrict)
    boxes = [model.geom(g).name for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX]
    hfield = f"{TERRAIN_PRIM_PATH}/geom"
    assert len(boxes) >= 6  # the height-0 slab around the pyramid and a square a step
    with_boxes = COLLIDERS if restrict else tuple(BODIES)
    expected = {frozenset(p) for p in itertools.product(BODIES, [hfield])}
    expected |= {frozenset(p) for p in itertools.product(with_boxes, boxes)}
    assert names(model, candidate_geom_pairs(model)) == expected
    if restrict:  # the bits themselves: a fresh one, the boxes' only one, added to the colliders' conaffinity
        box = model.geom(boxes[0]).id
        bit = int(model.geom_contype[box])
        assert bit == 4 and model.geom_conaffinity[box] == 0  # 1 and 2 are taken
        assert [int(model.geom(n).conaffinity[0]) for n in BODIES] == [1 | bit, 1 | bit, 1, 1]
        assert [int(model.geom(n).contype[0]) for n in BODIES] == [2, 0, 2, 2]
        assert model.geom(hfield).contype[0] == 1 and model.geom(hfield).conaffinity[0] == 1


@pytest.fixture(params=["mujoco_own", "reduced_as_warp"])
def hfield_contacts(request):
    """Both of MuJoCo C's hfield contact modes, set explicitly: the reduction is process-wide and a terrain env built
    by an earlier test leaves it on (``add_terrain_ground``), so the test must not inherit whichever ran last."""
    from ambulo.engine.mujoco_hfield import reduce_hfield_contacts

    reduce_hfield_contacts(0.02, enabled=request.param == "reduced_as_warp")
    yield request.param
    reduce_hfield_contacts(None, enabled=False)


def test_a_named_sphere_stands_on_a_stair_box_and_another_falls_through_onto_the_hfield(hfield_contacts):
    model, grid = scene(restrict=True)
    data = mujoco.MjData(model)
    for _ in range(round(1.5 / model.opt.timestep)):  # 1.5 s: 1.3 m of fall and settling
        mujoco.mj_step(model, data)
    z = {name: float(data.body(name).xpos[2]) for name in BODIES}
    top = float(grid.tile_centers_w[0, 0, 2])
    assert top == pytest.approx(0.75)  # 5 risers of 0.15 m: the summit
    assert z["leg"] == pytest.approx(top + RADIUS_M, abs=2e-3)  # on the box
    assert z["foot"] == pytest.approx(top + RADIUS_M, abs=2e-3)
    sunk = float(grid.heights_m.min()) - SUNK_M  # the hfield under the boxes
    assert z["hand"] == pytest.approx(sunk + RADIUS_M, abs=2e-3)  # through the box, on the hfield
    assert z["hand_on_rough"] == pytest.approx(float(grid.tile_centers_w[0, 1, 2]) + RADIUS_M, abs=2e-3)
    # at rest on the box and on the rough tile; the hand that fell 1.3 m through the boxes lands on the sunk hfield
    # at ~5 m/s, and with Warp's subset of contacts (a tilted one near a cell edge kept) it leaves rolling, which
    # nothing stops on flat ground (no rolling friction): its height is the check there
    moving = {name: float(np.abs(data.qvel[model.body(name).dofadr[0]:][:6]).max()) for name in BODIES}
    assert max(moving["leg"], moving["foot"], moving["hand_on_rough"]) < 1e-2, moving
    if hfield_contacts == "mujoco_own":
        assert moving["hand"] < 1e-2, moving


def test_bad_names_are_one_clear_error():
    grid = generate(CFG)
    spec = mujoco.MjSpec()
    add_terrain(spec, grid)
    with pytest.raises(ValueError, match="no body 'nope'"):
        restrict_box_colliders(spec, TERRAIN_PRIM_PATH, ("nope",))
    spec.worldbody.add_body(name="visual").add_geom(size=[0.1, 0, 0], contype=0, conaffinity=0)
    with pytest.raises(ValueError, match="'visual' has no colliding geom"):
        restrict_box_colliders(spec, TERRAIN_PRIM_PATH, ("visual",))
