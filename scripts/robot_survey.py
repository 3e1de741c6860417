"""Survey every robot file of ``example-robot-data``: does it load, with how many DoF, and does
it simulate 1 s without diverging? Writes ``docs/robot-survey.md``.

Each URDF (and MJCF, if the package ships any) is loaded the way a user loads a robot:
``new_scene`` + ``add_ground`` + ``add_robot(RobotCfg)`` + ``compile_scene``, stepped by the
``CpuEngine``. Two 1 s runs hold the initial (all-zero) pose with PD drives:
- fixed base: the root welded 1 cm above the ground, legs and arms hanging;
- on the ground: a free base dropped with its lowest collision geom 1 cm above the plane.
A run is stable when no world diverged (the engine's NaN/instability counters), the state
is finite and no joint moves faster than ``MAX_SPEED_RAD_S``.

The hold gains are derived from each joint's inertia, not ``DriveDefaults``: kp gives the
joint a natural period of ``HOLD_PERIOD_S`` and kd damps it critically, so that the check
tests the model, not one gain for a finger and a hip alike. The "default gains" column says
whether ``DriveDefaults`` (kp 100) would be too stiff for the 5 ms step on some joint
(``core.physics.timestep_warning``).

Run: ``python scripts/robot_survey.py [--out docs/robot-survey.md]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import torch

from ambulo.core import PhysicsCfg
from ambulo.core.importers import AssetError
from ambulo.core.importers.packages import package_search_path
from ambulo.core.physics import timestep_warning
from ambulo.core.scene import GroundCfg, RobotCfg, add_ground, add_robot, compile_scene, new_scene
from ambulo.engine.cpu import CpuEngine

SIM_TIME_S = 1.0
HOLD_PERIOD_S = 0.1
"""Natural period of the hold drives: 20 steps of 5 ms, well inside implicitfast's stable range
(omega dt = 0.31 < 2)."""
MAX_SPEED_RAD_S = 100.0
"""A joint faster than this after 1 s of holding still has blown up (about 1000 rpm)."""
CLEARANCE_M = 0.01
_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_URDF_DOF_TYPES = ("revolute", "continuous", "prismatic")


def robots_dir() -> Path | None:
    """``example-robot-data``'s ``robots`` folder, None if the package is not installed."""
    for folder in package_search_path():
        candidate = folder / "example-robot-data" / "robots"
        if candidate.is_dir():
            return candidate
    return None


def robot_files(root: Path) -> list[Path]:
    """Every URDF and MJCF under ``root`` (SDF and SRDF are not robot descriptions ambulo reads)."""
    files = [p for p in root.rglob("*") if p.suffix.lower() == ".urdf"]
    files += [p for p in root.rglob("*.xml") if _root_tag(p) == "mujoco"]
    return sorted(files)


def urdf_dof(file: Path) -> int:
    """Moving joints a URDF declares (revolute, continuous, prismatic): the DoF it should load with."""
    return sum(j.get("type") in _URDF_DOF_TYPES for j in ET.parse(file).getroot().findall("joint"))


@dataclass
class Row:
    file: str
    loaded: bool = False
    reason: str = ""
    dof: int = 0
    expected_dof: int | None = None
    mass_kg: float = float("nan")
    fixed_stable: bool | None = None
    ground_stable: bool | None = None
    default_gains_ok: bool | None = None
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0


def survey(file: Path, root: Path | None = None) -> Row:
    """Load ``file`` through the core and run the two 1 s holds."""
    start = time.perf_counter()
    row = Row(file=str(file.relative_to(root)) if root else file.name)
    if file.suffix.lower() == ".urdf":
        row.expected_dof = urdf_dof(file)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            model = _compile(file, fixed_base=True)
        except (AssetError, ValueError) as err:
            row.reason = str(err).replace(str(file.parent) + "/", "")
            row.seconds = time.perf_counter() - start
            return row
    row.notes = sorted({_note(str(w.message)) for w in caught if issubclass(w.category, UserWarning)})
    row.loaded = True
    row.dof = sum(int(t) in _DOF for t in model.jnt_type)
    row.mass_kg = float(sum(model.body_mass[b] for b in range(1, model.nbody)
                            if model.body(b).name.startswith("/World/robot/")))
    row.default_gains_ok = timestep_warning(model) is None
    row.fixed_stable = _hold(model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        row.ground_stable = _hold(_compile(file, fixed_base=False))
    row.seconds = time.perf_counter() - start
    return row


def _compile(file: Path, fixed_base: bool) -> mujoco.MjModel:
    spec = new_scene()
    add_ground(spec, GroundCfg(sky=False, sun=False))
    add_robot(spec, RobotCfg(file=str(file), fixed_base=fixed_base))
    model = compile_scene(spec, PhysicsCfg())
    _lift_onto_ground(model, fixed_base)
    return model


def _lift_onto_ground(model: mujoco.MjModel, fixed_base: bool) -> None:
    """Move the robot so its lowest collision geom is ``CLEARANCE_M`` above the plane."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    robot = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0
             and model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE
             and (model.geom_contype[g] or model.geom_conaffinity[g])]
    if not robot:
        return
    lowest = min(data.geom_xpos[g, 2] - model.geom_rbound[g] for g in robot)
    lift = CLEARANCE_M - lowest
    if fixed_base:
        for body in range(1, model.nbody):
            if model.body_parentid[body] == 0 and model.body(body).name != "/World/defaultGroundPlane":
                model.body_pos[body, 2] += lift
    else:
        free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
        for joint in free[:1]:
            model.qpos0[model.jnt_qposadr[joint] + 2] += lift


def _hold(model: mujoco.MjModel) -> bool:
    """Whether holding the initial pose for ``SIM_TIME_S`` stays finite and slow."""
    kp, kd, target = _hold_gains(model)
    engine = CpuEngine(model, num_worlds=1, num_threads=1)
    engine.model_field("actuator_biasprm")[0, :, 1] = torch.from_numpy(-kp)
    engine.model_field("actuator_biasprm")[0, :, 2] = torch.from_numpy(-kd)
    engine.ctrl[0] = torch.from_numpy(kp * target)
    steps = round(SIM_TIME_S / model.opt.timestep)
    engine.step(steps)
    qpos, qvel = engine.qpos[0].numpy(), engine.qvel[0].numpy()
    speed = np.abs(qvel[[model.jnt_dofadr[j] for j in range(model.njnt) if int(model.jnt_type[j]) in _DOF]])
    return bool(engine.num_diverged == 0 and np.isfinite(qpos).all() and np.isfinite(qvel).all()
                and (speed.max(initial=0.0) < MAX_SPEED_RAD_S))


def _hold_gains(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """kp, kd (from each joint's inertia) and the initial joint position of every drive.
    Drives that arrive with kp = kd = 0 (a <mimic> joint follows its equality) stay so."""
    omega = 2 * math.pi / HOLD_PERIOD_S
    kp, kd, target = np.zeros(model.nu), np.zeros(model.nu), np.zeros(model.nu)
    for a in range(model.nu):
        joint = model.actuator_trnid[a, 0]
        if model.actuator_biasprm[a, 1] == 0 and model.actuator_biasprm[a, 2] == 0:
            continue
        inertia = 1.0 / max(float(model.dof_invweight0[model.jnt_dofadr[joint]]), 1e-12)
        kp[a], kd[a] = inertia * omega ** 2, 2 * inertia * omega
        target[a] = model.qpos0[model.jnt_qposadr[joint]]
    return kp, kd, target


def _note(message: str) -> str:
    """A warning reduced to its gist for the table."""
    text = message.split(": ", 1)[-1]
    for key, gist in (("converted", "converted meshes"), ("ignored", "ROS-only tags ignored"),
                      ("not positive definite", "inertia repaired"), ("needs mass", "massless links given 1 g"),
                      ("enclose no volume", "flat mesh: shell inertia"), ("have no <limit>", "joint without limit"),
                      ("lower == upper", "empty joint range")):
        if key in text:
            return gist
    return text[:60]


def _root_tag(file: Path) -> str:
    try:
        for _, elem in ET.iterparse(file, events=("start",)):
            return elem.tag
    except ET.ParseError:
        return ""
    return ""


def _yes(value: bool | None) -> str:
    return "" if value is None else "yes" if value else "**no**"


def markdown(rows: list[Row], seconds: float) -> str:
    loaded = [r for r in rows if r.loaded]
    stable = [r for r in loaded if r.fixed_stable and r.ground_stable]
    lines = [
        "# example-robot-data survey",
        "",
        "Written by `scripts/robot_survey.py` (do not edit by hand). Every URDF/MJCF of the pip "
        "package `example-robot-data` is loaded through `ambulo.core` (`add_robot` + `compile_scene`) "
        "and held at its initial pose for 1 s by PD drives derived from each joint's inertia: "
        "once with the base fixed, once standing free on a ground plane. *Stable* = no divergence, "
        "finite state, no joint faster than 100 rad/s. *DoF* counts hinge and slide joints "
        "(URDF: revolute, continuous, prismatic). *Default gains ok* = `DriveDefaults` (kp 100) suits "
        "the 5 ms step on every joint.",
        "",
        f"**{len(loaded)} of {len(rows)} files load**, {len(stable)} of them stable in both runs "
        f"(survey time {seconds:.0f} s).",
        "",
        "| file | loads | DoF | mass kg | fixed base 1 s | on ground 1 s | default gains ok | notes / reason |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        dof = f"{r.dof}" if r.expected_dof in (None, r.dof) else f"{r.dof} (URDF {r.expected_dof})"
        text = r.reason if not r.loaded else "; ".join(r.notes)
        lines.append(
            f"| {r.file} | {'yes' if r.loaded else '**no**'} | {dof if r.loaded else ''} | "
            f"{r.mass_kg:.2f} | " if r.loaded else f"| {r.file} | **no** | | | ")
        lines[-1] += (f"{_yes(r.fixed_stable)} | {_yes(r.ground_stable)} | {_yes(r.default_gains_ok)} | "
                      f"{text.replace('|', '/')} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/robot-survey.md")
    args = parser.parse_args(argv)
    root = robots_dir()
    if root is None:
        print("example-robot-data is not installed: pip install 'ambulo[robots]'", file=sys.stderr)
        return 1
    start = time.perf_counter()
    rows = []
    for file in robot_files(root):
        rows.append(survey(file, root))
        r = rows[-1]
        print(f"{r.seconds:5.1f}s {r.file}: " + (f"{r.dof} DoF, fixed {r.fixed_stable}, ground {r.ground_stable}"
                                                 if r.loaded else f"not loaded: {r.reason[:100]}"), flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(markdown(rows, time.perf_counter() - start))
    print(f"wrote {args.out}: {sum(r.loaded for r in rows)} of {len(rows)} load")
    return 0


if __name__ == "__main__":
    sys.exit(main())
