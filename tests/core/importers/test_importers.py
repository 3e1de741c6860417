"""Importers keep what a robot file says, or say (in one line, with the true line number) what
they dropped or could not read. Each test builds a small URDF/USD/Collada file in tmp_path."""

import re
import warnings

import mujoco
import numpy as np
import pytest

from ambulo.core.importers import AssetError, load_spec

trimesh = pytest.importorskip("trimesh")

HEADER = "<?xml version='1.0'?>\n<!-- a comment header\n  of four\n  lines -->\n"
"""Five lines before <robot>: the ones ElementTree used to drop from MuJoCo's line numbers."""
INERTIAL = ('<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" '
            'iyz="0"/></inertial>')


def _urdf(tmp_path, body: str, name: str = "robot.urdf"):
    """A URDF with links base/a/b (unit masses) and ``body``; returns its path."""
    links = "".join(f'<link name="{n}">{INERTIAL}</link>\n' for n in ("base", "a", "b"))
    path = tmp_path / name
    path.write_text(f'{HEADER}<robot name="r">\n{links}{body}\n</robot>\n')
    return path


def _line_of(path, needle: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


def _joint(name="j", parent="base", child="a", limit='<limit lower="-1" upper="1" effort="5" velocity="1"/>',
           extra="", kind="revolute"):
    return (f'<joint name="{name}" type="{kind}">\n<parent link="{parent}"/><child link="{child}"/>'
            f'<axis xyz="0 0 1"/>{limit}{extra}</joint>\n')


def _load(path, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        spec = load_spec(path, **kw)
    return spec, [str(w.message) for w in caught]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("AMBULO_CACHE_DIR", str(folder))
    return folder


def _box_dae(path, size=(0.1, 0.2, 0.3), unit_m=None):
    text = trimesh.exchange.dae.export_collada(trimesh.creation.box(size)).decode()
    if unit_m is not None:
        text = text.replace("<asset>", f'<asset><unit meter="{unit_m}" name="u"/>', 1)
    path.write_text(text)
    return path


def _mesh_extent(model, geom):
    mesh = model.geom_dataid[geom]
    start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    verts = model.mesh_vert[start:start + count]
    return verts.max(0) - verts.min(0)  # compiled vertices carry the mesh scale


# -- item 1: meshes MuJoCo cannot read are converted, cached, and kept visual vs collision --

def test_collada_meshes_are_converted_with_scale_and_visuals_do_not_collide(tmp_path, cache):
    _box_dae(tmp_path / "box.dae")
    _box_dae(tmp_path / "hull.dae", size=(0.3, 0.3, 0.3))
    link = ('<link name="m">' + INERTIAL
            + '<visual><geometry><mesh filename="box.dae" scale="2 2 2"/></geometry></visual>'
            + '<collision><geometry><mesh filename="hull.dae"/></geometry></collision></link>')
    path = _urdf(tmp_path, link + _joint(child="m"))
    spec, messages = _load(path)
    model = spec.compile()
    assert [m for m in messages if "converted 2 .dae meshes" in m and "0 already in the cache" in m]
    visual, collision = (g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH)
    if model.geom_group[visual] != 1:
        visual, collision = collision, visual
    # visual: group 1, never collides; collision: group 0, collides
    assert (model.geom_contype[visual], model.geom_conaffinity[visual], model.geom_group[visual]) == (0, 0, 1)
    assert model.geom_contype[collision] == 1 and model.geom_group[collision] == 0
    # the URDF's <mesh scale> applies to the visual only; the .dae's up axis (Y_UP) is ignored
    np.testing.assert_allclose(sorted(_mesh_extent(model, visual)), [0.2, 0.4, 0.6], atol=1e-6)
    np.testing.assert_allclose(_mesh_extent(model, collision), [0.3, 0.3, 0.3], atol=1e-6)
    # content-addressed and complete: two OBJ files, no temporaries; the next load reuses them
    files = sorted(p.name for p in cache.rglob("*") if p.is_file())
    assert len(files) == 2 and all(f.endswith(".obj") for f in files)
    _, messages = _load(path)
    assert [m for m in messages if "2 already in the cache" in m]
    # an edited mesh is a new cache entry
    _box_dae(tmp_path / "box.dae", size=(0.1, 0.2, 0.4))
    _, messages = _load(path)
    assert [m for m in messages if "1 already in the cache" in m]
    assert len([p for p in cache.rglob("*.obj")]) == 3


def test_collada_unit_scales_the_mesh(tmp_path, cache):
    _box_dae(tmp_path / "mm.dae", size=(100.0, 200.0, 300.0), unit_m=0.001)
    link = f'<link name="m">{INERTIAL}<collision><geometry><mesh filename="mm.dae"/></geometry></collision></link>'
    model = _load(_urdf(tmp_path, link + _joint(child="m")))[0].compile()
    geom = next(g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH)
    np.testing.assert_allclose(_mesh_extent(model, geom), [0.1, 0.2, 0.3], atol=1e-6)


def test_ascii_stl_is_converted(tmp_path, cache):
    (tmp_path / "a.stl").write_bytes(trimesh.exchange.stl.export_stl_ascii(trimesh.creation.box([0.1] * 3)).encode())
    link = f'<link name="m">{INERTIAL}<collision><geometry><mesh filename="a.stl"/></geometry></collision></link>'
    spec, messages = _load(_urdf(tmp_path, link + _joint(child="m")))
    assert spec.compile().nmesh == 1
    assert [m for m in messages if "converted 1 .stl" in m]


def test_collada_with_a_broken_material_reference_keeps_its_geometry(tmp_path, cache):
    # ANYmal B's foot: pycollada drops a node whose material it cannot resolve, geometry and all
    text = trimesh.exchange.dae.export_collada(trimesh.creation.box([0.1] * 3)).decode()
    text = re.sub(r'(<instance_material [^>]*target=)"[^"]*"', r'\1"#missing-material"', text)
    (tmp_path / "foot.dae").write_text(text)
    link = f'<link name="m">{INERTIAL}<collision><geometry><mesh filename="foot.dae"/></geometry></collision></link>'
    model = _load(_urdf(tmp_path, link + _joint(child="m")))[0].compile()
    geom = next(g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH)
    np.testing.assert_allclose(_mesh_extent(model, geom), [0.1, 0.1, 0.1], atol=1e-6)


def test_unreadable_collada_names_the_mesh_element_and_line(tmp_path, cache):
    (tmp_path / "bad.dae").write_text("<COLLADA><not closed")
    link = f'<link name="m">{INERTIAL}<visual><geometry>\n<mesh filename="bad.dae"/></geometry></visual></link>'
    path = _urdf(tmp_path, link + _joint(child="m"))
    with pytest.raises(AssetError, match=rf'robot.urdf:{_line_of(path, "bad.dae")}: <mesh filename="bad.dae">: .*'
                                         "re-export it as OBJ or STL"):
        load_spec(path)
    assert not [p for p in cache.rglob("*") if p.is_file()]


def test_missing_mesh_names_its_line(tmp_path):
    link = f'<link name="m">{INERTIAL}<visual><geometry>\n<mesh filename="nowhere.stl"/></geometry></visual></link>'
    path = _urdf(tmp_path, link + _joint(child="m"))
    with pytest.raises(FileNotFoundError, match=rf"robot.urdf:{_line_of(path, 'nowhere')}: .*not found"):
        load_spec(path)


# -- item 2: what the file says is kept, or the loss is said --

def test_inverted_joint_limits_name_the_joint_and_its_true_line(tmp_path):
    path = _urdf(tmp_path, _joint(name="elbow", limit='<limit lower="1" upper="-1" effort="5" velocity="1"/>'))
    line = _line_of(path, 'name="elbow"')
    assert line > 5
    with pytest.raises(AssetError, match=rf'robot.urdf:{line}: <joint name="elbow">: lower limit 1 > upper limit -1; swap'):
        load_spec(path)


def test_missing_limit_warns_and_leaves_the_joint_unlimited(tmp_path):
    path = _urdf(tmp_path, _joint(name="wrist", limit=""))
    spec, messages = _load(path)
    line = _line_of(path, 'name="wrist"')
    assert [m for m in messages if f"wrist (line {line})" in m and "no <limit>" in m]
    model = spec.compile()
    assert not model.jnt_limited[model.joint("wrist").id]


def test_mimic_joint_follows_its_leader_through_an_equality(tmp_path):
    body = _joint(name="lead") + _joint(name="follow", parent="a", child="b",
                                        extra='<mimic joint="lead" multiplier="-2" offset="0.1"/>')
    model = _load(_urdf(tmp_path, body), fixed_base=True)[0].compile()
    assert model.neq == 1 and model.eq_type[0] == mujoco.mjtEq.mjEQ_JOINT
    assert (model.eq_obj1id[0], model.eq_obj2id[0]) == (model.joint("follow").id, model.joint("lead").id)
    np.testing.assert_allclose(model.eq_data[0, :2], [0.1, -2.0])
    # the follower's drive has no gains: it does not pull the joint away from the equality
    follow = model.actuator("follow").id
    assert model.actuator_biasprm[follow, 1] == 0 and model.actuator_biasprm[follow, 2] == 0
    data = mujoco.MjData(model)
    data.ctrl[model.actuator("lead").id] = 100.0 * 0.3  # hold lead at 0.3 rad (kp 100)
    for _ in range(1000):
        mujoco.mj_step(model, data)
    lead, follow_q = data.qpos[model.jnt_qposadr[model.joint("lead").id]], data.qpos[model.jnt_qposadr[model.joint("follow").id]]
    assert follow_q == pytest.approx(0.1 - 2 * lead, abs=2e-3)


def test_transmission_and_gazebo_tags_are_dropped_with_one_warning(tmp_path):
    extra = ('<transmission name="t"><joint name="j"/><actuator name="m"/></transmission>'
             '<transmission name="t2"/><gazebo reference="a"><mu1>0.5</mu1></gazebo>')
    _, messages = _load(_urdf(tmp_path, _joint() + extra))
    dropped = [m for m in messages if "<transmission>" in m]
    assert len(dropped) == 1 and "ignored 2 <transmission> and 1 <gazebo>" in dropped[0]
    assert "limit effort" in dropped[0] and "\n" not in dropped[0]


def test_mujoco_errors_point_at_the_element_and_line_of_the_users_file(tmp_path):
    body = _joint(extra='\n<origin xyz="1 x 2"/>')
    path = _urdf(tmp_path, body)
    line = _line_of(path, 'xyz="1 x 2"')
    with pytest.raises(AssetError, match=rf"robot.urdf:{line}: <origin>: bad format in attribute 'xyz'"):
        load_spec(path)


def test_malformed_urdf_reports_line_and_column(tmp_path):
    path = tmp_path / "bad.urdf"
    path.write_text(HEADER + '<robot name="r">\n<link name="a">\n</robot>\n')
    with pytest.raises(AssetError, match=r"bad.urdf:7:\d+: malformed URDF \(mismatched tag\)"):
        load_spec(path)


def test_invalid_inertia_and_massless_links_are_repaired_with_a_warning(tmp_path):
    bad = ('<link name="c"><inertial><mass value="1"/><inertia ixx="1e-6" iyy="1e-6" izz="1e-6" ixy="1e-6" '
           'ixz="1e-6" iyz="1e-6"/></inertial></link>\n<link name="virtual"/>\n')
    body = bad + _joint(child="virtual") + _joint(name="k", parent="virtual", child="c")
    path = _urdf(tmp_path, body)
    spec, messages = _load(path)
    model = spec.compile()
    line = _line_of(path, '<link name="c">')
    assert [m for m in messages if f"c (line {line})" in m and "not positive definite" in m]
    assert [m for m in messages if "virtual (line" in m and "mass" in m]
    assert (model.body_inertia[model.body("c").id] > 0).all()
    assert model.body_mass[model.body("c").id] == pytest.approx(1.0)  # the mass the file gives is kept
    assert model.body_mass[model.body("virtual").id] == pytest.approx(1e-3)


def test_a_folder_passed_as_a_file_says_so(tmp_path):
    (tmp_path / "robot.urdf").write_text("<robot/>")
    with pytest.raises(AssetError, match=r"is a folder, not a file.*robot.urdf"):
        load_spec(tmp_path)


# -- USD --

def _usd(path, default=None, roots=("Arm",), joint_kind="RevoluteJoint", limits=None, exclude=False):
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    for root in roots:
        UsdGeom.Xform.Define(stage, f"/{root}")
    if default is not None:
        stage.GetRootLayer().defaultPrim = default
    arm = roots[0]
    for name, z in (("link", 0.3), ("link2", 0.6)):
        cube = UsdGeom.Cube.Define(stage, f"/{arm}/{name}")
        cube.CreateSizeAttr(0.1)
        cube.AddTranslateOp().Set(Gf.Vec3d(0, 0, z))
        UsdPhysics.RigidBodyAPI.Apply(cube.GetPrim())
        UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
        UsdPhysics.MassAPI.Apply(cube.GetPrim()).CreateMassAttr(1.0)
    shoulder = UsdPhysics.RevoluteJoint.Define(stage, f"/{arm}/shoulder")
    shoulder.CreateBody1Rel().SetTargets([f"/{arm}/link"])
    shoulder.CreateAxisAttr("Y")
    elbow = getattr(UsdPhysics, joint_kind).Define(stage, f"/{arm}/elbow")
    elbow.CreateBody0Rel().SetTargets([f"/{arm}/link"])
    elbow.CreateBody1Rel().SetTargets([f"/{arm}/link2"])
    elbow.CreateLocalPos0Attr(Gf.Vec3f(0, 0, 0.15))
    elbow.CreateLocalPos1Attr(Gf.Vec3f(0, 0, -0.15))
    if joint_kind == "RevoluteJoint":
        elbow.CreateAxisAttr("X")
        if limits:
            elbow.CreateLowerLimitAttr(limits[0])
            elbow.CreateUpperLimitAttr(limits[1])
    if exclude:
        elbow.CreateExcludeFromArticulationAttr(True)
    stage.Save()
    return path


def test_usd_without_default_prim_uses_its_only_root_prim_with_a_warning(tmp_path):
    pytest.importorskip("pxr")
    spec, messages = _load(_usd(tmp_path / "a.usda"))
    assert [m for m in messages if "no defaultPrim" in m and 'defaultPrim = "Arm"' in m]
    assert spec.body("link") is not None and spec.joint("elbow") is not None


def test_usd_without_default_prim_and_several_roots_is_an_error_naming_the_fix(tmp_path):
    pytest.importorskip("pxr")
    with pytest.raises(AssetError, match=r"no defaultPrim and 2 root prims \(/Arm, /Other\); set defaultPrim"):
        load_spec(_usd(tmp_path / "a.usda", roots=("Arm", "Other")))


def test_usd_default_prim_naming_nothing_is_an_error(tmp_path):
    pytest.importorskip("pxr")
    with pytest.raises(AssetError, match=r"defaultPrim 'Nope' names no prim \(root prims: /Arm\)"):
        load_spec(_usd(tmp_path / "a.usda", default="Nope"))


@pytest.mark.parametrize("kind, exclude, reason", [
    ("SphericalJoint", False, "SphericalJoint joints are not supported"),
    ("RevoluteJoint", True, "excluded from the articulation"),
])
def test_usd_joints_mujoco_drops_are_named_with_the_reason(tmp_path, kind, exclude, reason):
    pytest.importorskip("pxr")
    spec, messages = _load(_usd(tmp_path / "a.usda", default="Arm", joint_kind=kind, exclude=exclude))
    dropped = [m for m in messages if "dropped 1 joints" in m]
    assert len(dropped) == 1 and f"/Arm/elbow ({reason}" in dropped[0]
    assert spec.joint("elbow") is None and spec.joint("shoulder") is not None


def test_usd_inverted_limits_name_the_joint(tmp_path):
    pytest.importorskip("pxr")
    with pytest.raises(AssetError, match=r"joint /Arm/elbow: lower limit 30 > upper limit -30; swap"):
        load_spec(_usd(tmp_path / "a.usda", default="Arm", limits=(30.0, -30.0)))


def test_usd_syntax_error_keeps_pxrs_file_line_and_column(tmp_path):
    pytest.importorskip("pxr")
    path = tmp_path / "bad.usda"
    path.write_text('#usda 1.0\n(\n  defaultPrim = "A"\n)\ndef Xform "A" {\n  double x = \n}\n')
    with pytest.raises(AssetError, match=r"bad.usda:6:\d+: not a readable USD stage: Expected }"):
        load_spec(path)
