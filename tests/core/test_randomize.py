"""core.randomize: distributions under a seed, per-world writes to exactly the selected rows,
Entity operations against hand-computed values, the placement loop, CPU/Warp parity."""

import math

import mujoco
import numpy as np
import pytest
import torch

from ambulo.core import Entity
from ambulo.core import randomize as dr
from ambulo.engine import make_engine
from ambulo.utils.math import quat_from_yaw

XML = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <geom name="/World/floor" type="plane" size="5 5 0.1" friction="0.9 0.01 0.001"/>
    <body name="/World/arm" pos="0 0 1">
      <geom name="/World/arm/base" type="box" size="0.1 0.1 0.1" mass="2"/>
      <body name="/World/arm/link" pos="0 0 0.3">
        <joint name="/World/arm/hinge" type="hinge" axis="0 1 0" range="-1 2" limited="true" damping="0.5"
               armature="0.01"/>
        <geom name="/World/arm/link_geom" type="capsule" size="0.05 0.1" mass="1"/>
        <body name="/World/arm/tip" pos="0 0 0.3">
          <joint name="/World/arm/slide" type="slide" axis="1 0 0" damping="2"/>
          <geom name="/World/arm/tip_geom" type="sphere" size="0.05" mass="0.5" rgba="1 0 0 1"/>
        </body>
      </body>
    </body>
    <body name="/World/box" pos="1 0 0.2">
      <freejoint/>
      <geom name="/World/box/geom" type="box" size="0.1 0.1 0.1" mass="1"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="/World/arm/hinge_motor" joint="/World/arm/hinge"/>
  </actuator>
</mujoco>
"""

N = 5


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_string(XML)


def cpu(model, n=N):
    return make_engine(model, n, device="cpu", engine="mujoco")


def fields(engine, *names):
    return {name: engine.model_field(name).clone() for name in names}


# -- distributions ------------------------------------------------------------------------------
def test_distribution_ranges_and_moments_under_a_seed():
    g = torch.Generator().manual_seed(0)
    n = 40_000
    u = dr.uniform(2.0, 5.0).sample(g, n)
    assert u.shape == (n,) and u.dtype == torch.float64
    assert 2.0 <= u.min() and u.max() < 5.0
    # mean 3.5, variance (5 - 2)^2 / 12 = 0.75; 5 standard errors
    assert abs(u.mean().item() - 3.5) < 5 * math.sqrt(0.75 / n)
    assert abs(u.var().item() - 0.75) < 0.02
    z = dr.normal(1.0, 2.0).sample(g, n)
    assert abs(z.mean().item() - 1.0) < 5 * 2.0 / math.sqrt(n) and abs(z.std().item() - 2.0) < 0.03
    k = dr.uniform_int(2, 6).sample(g, n)
    assert k.dtype == torch.int64 and sorted(k.unique().tolist()) == [2, 3, 4, 5, 6]  # both ends inclusive
    assert (torch.bincount(k - 2).double() / n - 0.2).abs().max() < 0.015
    picks = dr.choice(["a", "b"], weights=[1.0, 3.0]).sample_index(g, n)
    assert abs(picks.double().mean().item() - 0.75) < 0.015
    colors = dr.choice([(1, 0, 0), (0, 0, 1)]).sample(g, 4)
    assert colors.shape == (4, 3) and set(map(tuple, colors.tolist())) <= {(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)}
    # per-component bounds and shapes; a point range is its value exactly
    v = dr.uniform((0.0, 10.0, -1.0), (1.0, 20.0, -1.0)).sample(g, 1000)
    assert v.shape == (1000, 3) and (v[:, 0] < 1).all() and (v[:, 1] >= 10).all() and (v[:, 2] == -1).all()
    assert dr.constant((1.5, 2.5)).sample(g, 2).tolist() == [[1.5, 2.5], [1.5, 2.5]]
    assert dr.uniform(0.0, 1.0).sample(g).shape == ()


def test_the_same_seed_draws_the_same_numbers_and_float32_rounds_the_float64_draw():
    a, b = torch.Generator().manual_seed(7), torch.Generator().manual_seed(7)
    assert torch.equal(dr.normal((0, 0), (1, 2)).sample(a, 5), dr.normal((0, 0), (1, 2)).sample(b, 5))
    a, b = torch.Generator().manual_seed(7), torch.Generator().manual_seed(7)
    wide = dr.uniform(0.4, 1.2).sample(a, 6)
    narrow = dr.uniform(0.4, 1.2).sample(b, 6, dtype=torch.float32)
    u = torch.rand(6, generator=torch.Generator().manual_seed(7), dtype=torch.float64)
    assert torch.equal(wide, 0.4 + (1.2 - 0.4) * u)
    assert torch.equal(narrow, 0.4 + (1.2 - 0.4) * u.to(torch.float32))  # RLEnv._uniform's numbers


def test_a_numpy_generator_seeds_a_torch_one_from_its_own_state():
    x = dr.uniform(0, 1).sample(dr.as_generator(np.random.default_rng([3, 1, 4])), 3)
    y = dr.uniform(0, 1).sample(dr.as_generator(np.random.default_rng([3, 1, 4])), 3)
    z = dr.uniform(0, 1).sample(dr.as_generator(np.random.default_rng([3, 1, 5])), 3)
    assert torch.equal(x, y) and not torch.equal(x, z)
    g = torch.Generator()
    assert dr.as_generator(g) is g
    with pytest.raises(TypeError, match="torch.Generator"):
        dr.as_generator("seed")


# -- per-world writes ---------------------------------------------------------------------------
def test_friction_is_written_to_the_selected_worlds_only(model):
    engine = cpu(model)
    before = fields(engine, "geom_friction")["geom_friction"]
    rows = torch.tensor([1, 3])
    dr.geom_friction(engine, dr.constant(0.25), torch.Generator(), rows=rows)
    after = engine.model_field("geom_friction")
    expected = before.clone()
    expected[1, :, 0] = expected[3, :, 0] = 0.25  # every geom of worlds 1 and 3, sliding column only
    assert torch.equal(after, expected)
    # one shared draw per world: each selected world has a single value for all its geoms
    g = torch.Generator().manual_seed(2)
    values = dr.geom_friction(engine, dr.uniform(0.4, 1.2), g, rows=torch.tensor([0, 4]))
    assert values.shape == (2, 1)
    assert torch.equal(after[[0, 4], :, 0], values.expand(2, model.ngeom))
    assert torch.equal(after[[1, 2, 3]], expected[[1, 2, 3]])


def test_a_bool_mask_writes_the_masked_worlds_and_draws_for_every_world(model):
    engine = cpu(model)
    before = fields(engine, "body_mass")["body_mass"]
    mask = torch.tensor([True, False, True, False, False])
    robot = Entity(engine, "/World/arm", require_drives=False)
    values = dr.body_mass(robot, dr.constant(2.0), torch.Generator(), bodies=["link", "tip"], rows=mask,
                          operation="scale")
    assert values.shape == (N, 2)
    link, tip = model.body("/World/arm/link").id, model.body("/World/arm/tip").id
    expected = before.clone()
    expected[[0, 2], link] = 2.0  # 2 x 1 kg
    expected[[0, 2], tip] = 1.0   # 2 x 0.5 kg
    assert torch.equal(engine.model_field("body_mass"), expected)


def test_add_and_scale_offset_the_nominal_values_so_draws_never_compound(model):
    engine = cpu(model)
    robot = Entity(engine, "/World/arm", require_drives=False)
    for _ in range(3):  # the same draw three times: the result stays nominal + offset
        dr.body_mass(robot, dr.constant(0.5), torch.Generator(), bodies=["link"], rows=torch.tensor([2]))
        dr.joint_dof_field(robot, "dof_damping", dr.constant(3.0), torch.Generator(), joints=["slide"])
    link = model.body("/World/arm/link").id
    assert engine.model_field("body_mass")[:, link].tolist() == [1.0, 1.0, 1.5, 1.0, 1.0]
    slide = model.jnt_dofadr[model.joint("/World/arm/slide").id]
    hinge = model.jnt_dofadr[model.joint("/World/arm/hinge").id]
    damping = engine.model_field("dof_damping")
    assert damping[:, slide].tolist() == [6.0] * N and damping[:, hinge].tolist() == [0.5] * N
    com = dr.body_com_offset(robot, dr.constant((0.01, 0.0, -0.02)), torch.Generator(), bodies=["tip"], rows=0)
    assert com.shape == (1, 1, 3)
    ipos = engine.model_field("body_ipos")[:, model.body("/World/arm/tip").id]
    assert np.allclose(ipos[0].numpy(), model.body_ipos[model.body("/World/arm/tip").id] + [0.01, 0.0, -0.02])
    assert np.array_equal(ipos[1:].numpy(), np.broadcast_to(model.body_ipos[model.body("/World/arm/tip").id],
                                                            (N - 1, 3)))
    with pytest.raises(ValueError, match="dof_damping"):
        dr.joint_dof_field(robot, "dof_stiffness", dr.constant(1.0), torch.Generator())
    with pytest.raises(ValueError, match="operation"):
        dr.randomize_field(engine, "body_mass", dr.constant(1.0), torch.Generator(), operation="mul")


def test_joint_range_box_and_free_poses(model):
    engine = cpu(model)
    robot = Entity(engine, "/World/arm", require_drives=False)
    low, high = dr.joint_range_box(robot, 0.5)
    # hinge [-1, 2]: middle 0.5, half width 1.5 -> 0.5 +- 0.75; slide unlimited -> +-0.5 pi
    assert np.allclose(low, [-0.25, -0.5 * np.pi]) and np.allclose(high, [1.25, 0.5 * np.pi])
    qpos_before = engine.qpos.clone()
    box = model.jnt_qposadr[model.joint(model.body("/World/box").jntadr[0]).id]
    pos = np.array([[[1.0, 2.0, 0.3]], [[4.0, 5.0, 0.6]]])
    quat = quat_from_yaw(np.array([[math.pi / 2], [0.0]]))
    dr.write_free_poses(engine, [box], pos, quat, rows=torch.tensor([4, 1]))
    expected = qpos_before.clone()
    expected[4, box:box + 7] = torch.tensor([1.0, 2.0, 0.3, math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)],
                                            dtype=torch.float64)
    expected[1, box:box + 7] = torch.tensor([4.0, 5.0, 0.6, 1.0, 0, 0, 0], dtype=torch.float64)
    assert torch.allclose(engine.qpos, expected, atol=1e-15, rtol=0)


def test_body_geoms_resolve_once_and_write_each_geom_once(model):
    engine = cpu(model, 2)
    targets = dr.BodyGeoms.resolve(model, "/World/arm*", "colors")
    # /World/arm's subtree holds all three arm geoms, the link's two of them, the tip's one: each
    # geom takes the value of the last body listing it, as writing body after body would leave it
    names = [model.geom(g).name for g in targets.targets]
    assert names == ["/World/arm/base", "/World/arm/link_geom", "/World/arm/tip_geom"]
    arm, link, tip = (model.body(f"/World/arm{s}").id for s in ("", "/link", "/tip"))
    assert targets.bodies == [arm, link, tip] and [targets.bodies[o] for o in targets.owner] == [arm, link, tip]
    rgba_before = engine.model_field("geom_rgba").clone()
    per_body = np.arange(len(targets.bodies) * 4, dtype=np.float64).reshape(1, -1, 4) / 16  # exact in float32
    targets.write(engine.model_field("geom_rgba"), per_body, rows=1)
    rgba = engine.model_field("geom_rgba")
    assert torch.equal(rgba[0], rgba_before[0])
    for geom, owner in zip(targets.targets, targets.owner):
        assert rgba[1, geom].tolist() == per_body[0, owner].tolist()
    with pytest.raises(ValueError, match="no body matches"):
        dr.BodyGeoms.resolve(model, "/World/nothing*", "colors")


# -- placement ----------------------------------------------------------------------------------
def test_placement_redraws_only_colliding_objects_and_reports_the_rest(model):
    data_model = model
    floor = [data_model.geom("/World/floor").id]
    checker = dr.CollisionChecker(data_model, floor)
    box_adr = data_model.jnt_qposadr[data_model.body("/World/box").jntadr[0]]
    qpos = data_model.qpos0.copy()
    rounds = []

    def draw(todo):
        rounds.append(list(todo))
        # first round: the box inside the arm's base; later rounds: clear of it
        qpos[box_adr:box_adr + 3] = [0.0, 0.0, 1.0] if len(rounds) == 1 else [2.0, 0.0, 0.2]

    box_body = data_model.body("/World/box").id
    assert dr.place_without_overlap([0], [box_body], qpos, draw, checker, max_tries=5) == []
    assert rounds == [[0], [0]]
    rounds.clear()
    assert dr.place_without_overlap([0], [box_body], qpos, draw, checker, max_tries=1) == [0]
    rounds.clear()
    assert dr.place_without_overlap([0], [box_body], qpos, draw, None, max_tries=5) == []
    assert rounds == [[0]]
    assert dr.park_z(3) == -19.0


def test_yaw_to_quaternion_is_one_function_for_tensors_and_arrays():
    yaw = np.array([0.0, math.pi / 2, -math.pi])
    q = quat_from_yaw(yaw)
    assert isinstance(q, np.ndarray)
    assert np.allclose(q, [[1, 0, 0, 0], [math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)], [0, 0, 0, -1]],
                       atol=1e-15)
    assert np.array_equal(quat_from_yaw(torch.from_numpy(yaw)).numpy(), q)


# -- parity -------------------------------------------------------------------------------------
@pytest.mark.slow  # compiling Warp's kernels for the CPU takes ~15 s
def test_the_warp_engine_gets_the_same_writes_as_the_cpu_engine(model):
    pytest.importorskip("mujoco_warp")
    engines = [cpu(model, 4), make_engine(model, 4, device="cpu", engine="warp")]
    out = []
    for engine in engines:
        robot = Entity(engine, "/World/arm", require_drives=False)
        g = torch.Generator().manual_seed(5)
        dr.geom_friction(engine, dr.uniform(0.4, 1.2), g, rows=torch.tensor([True, False, True, True]))
        dr.body_mass(robot, dr.uniform(-0.2, 0.3), g, bodies=["link"], rows=torch.tensor([1, 2]))
        dr.joint_dof_field(robot, "dof_armature", dr.uniform(1.0, 2.0), g)
        out.append({name: engine.model_field(name).detach().to("cpu", torch.float64).clone()
                     for name in ("geom_friction", "body_mass", "dof_armature")})
    for name in out[0]:
        assert torch.allclose(out[0][name], out[1][name], atol=1e-6, rtol=1e-6), name
    assert torch.equal(out[1]["geom_friction"][1], torch.tensor(model.geom_friction, dtype=torch.float32).double())


def test_checker_with_movers_makes_only_their_contacts_exactly_as_before():
    """Given the placed bodies' geoms, the checker reports a mover that penetrates anything (as
    without ``movers``) and nothing for bodies that touch only each other."""
    xml = """<mujoco><worldbody>
      <geom name="floor" type="plane" size="5 5 .1"/>
      <body name="a"><freejoint/><geom name="a" type="box" size=".1 .1 .1" contype="2" conaffinity="3"/></body>
      <body name="b"><freejoint/><geom name="b" type="box" size=".1 .1 .1"/></body>
      <body name="c"><freejoint/><geom name="c" type="sphere" size=".1"/></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    floor, a, b, c = (m.geom(n).id for n in ("floor", "a", "b", "c"))
    qpos = m.qpos0.copy()
    qpos[[0, 7, 14]] = [0.0, 0.05, 3.0]  # a and b overlap; c stands alone
    qpos[[2, 9, 16]] = 1.0
    bodies = {m.body(n).id for n in ("a", "b")}
    assert dr.CollisionChecker(m, [floor]).colliding_roots(qpos) == bodies
    assert dr.CollisionChecker(m, [floor], movers=[c]).colliding_roots(qpos) == set()  # a-b not made
    assert dr.CollisionChecker(m, [floor], movers=[a]).colliding_roots(qpos) == bodies
    assert dr.CollisionChecker(m, [floor], movers=[b]).colliding_roots(qpos) == bodies
    qpos[14] = 0.1  # c into a
    assert dr.CollisionChecker(m, [floor], movers=[c]).colliding_roots(qpos) == bodies | {m.body("c").id}
    m.geom_conaffinity[a] = 0  # a's contype 2 meets c's conaffinity 1 nowhere: c-a is no pair now
    m.geom_contype[c] = 0  # c-b still is (b's contype 1, c's conaffinity 1); a-b is never made
    assert dr.CollisionChecker(m, [floor], movers=[c]).colliding_roots(qpos) == {m.body("b").id, m.body("c").id}


def test_host_draws_are_numpys_draws_with_the_torch_paths_shapes_and_arithmetic():
    """``sample_host`` draws with NumPy from the generator it is given: low + (high - low) * u,
    mean + std * z, integers in [low, high], options by index, in the shapes ``sample`` gives."""
    def rng():
        return np.random.Generator(np.random.Philox(key=7))

    cases = [(dr.uniform(2.0, 5.0), lambda g, s: 2.0 + 3.0 * g.random(s)),
             (dr.normal((0, 1, 2), (0.5, 1.0, 2.0)),
              lambda g, s: np.array([0, 1, 2.0]) + np.array([0.5, 1.0, 2.0]) * g.standard_normal(s)),
             (dr.uniform((0, -1), (1, 4)), lambda g, s: np.array([0, -1.0]) + np.array([1, 5.0]) * g.random(s)),
             (dr.uniform_int(2, 6), lambda g, s: g.integers(2, 7, s)),
             (dr.choice((1.5, 2.5, 9.0)), lambda g, s: np.array([1.5, 2.5, 9.0])[g.choice(3, size=s)]),
             (dr.choice((1.5, 2.5), (1, 3)), lambda g, s: np.array([1.5, 2.5])[g.choice(2, size=s, p=[0.25, 0.75])]),
             (dr.constant((1.0, 2.0)), lambda g, s: np.broadcast_to([1.0, 2.0], s))]
    for dist, numpy_draw in cases:
        for num in (None, 7):
            torch_shape = tuple(dist.sample(torch.Generator().manual_seed(3), num).shape)
            got = dist.sample_host(rng(), num)
            assert got.shape == torch_shape, (dist, num)
            np.testing.assert_array_equal(got, numpy_draw(rng(), torch_shape), err_msg=f"{dist} {num}")
    columns = dr.Columns((dr.uniform(0, 1), dr.uniform(-3.0, 2.0), dr.uniform(10, 11)))
    np.testing.assert_array_equal(columns.sample_host(rng(), 9),
                                  np.array([0, -3.0, 10]) + np.array([1, 5.0, 1]) * rng().random((9, 3)))
    mixed = dr.Columns((dr.uniform(0, 1), dr.normal(0.0, 2.0), 0.5))
    g = rng()
    expected = np.stack([g.random(9), 2.0 * g.standard_normal(9), np.full(9, 0.5)], axis=1)
    np.testing.assert_array_equal(mixed.sample_host(rng(), 9), expected)

    class Twice(dr.Distribution):  # no NumPy draw of its own: a torch generator seeded from the rng
        def sample(self, generator, num=None, *, dtype=torch.float64):
            return 2 * torch.rand(() if num is None else (num,), generator=generator, dtype=dtype)

    expected = Twice().sample(dr.as_generator(rng()), 4).numpy()
    np.testing.assert_array_equal(Twice().sample_host(rng(), 4), expected)