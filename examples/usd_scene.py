"""Isaac Sim "load a USD scene" ported: author a small UsdPhysics stage (a table with a
crate and a ball on it), reference it at /World/Scene, and simulate.

    python examples/usd_scene.py [--usd my_scene.usda] [--seconds 2]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from ambulo.sim import RigidPrim, World, add_reference_to_stage


def author_scene(path: Path) -> Path:
    """Write a UsdPhysics stage: a static table top, a 1 kg crate and a 0.2 kg ball above it."""
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Scene")
    stage.SetDefaultPrim(root.GetPrim())
    table = UsdGeom.Cube.Define(stage, "/Scene/table")
    table.CreateSizeAttr(1.0)
    table.AddTranslateOp().Set(Gf.Vec3d(0, 0, 0.375))
    table.AddScaleOp().Set(Gf.Vec3f(1.2, 0.8, 0.75))
    UsdPhysics.CollisionAPI.Apply(table.GetPrim())
    crate = UsdGeom.Cube.Define(stage, "/Scene/crate")
    crate.CreateSizeAttr(0.2)
    crate.AddTranslateOp().Set(Gf.Vec3d(0.2, 0, 1.0))
    ball = UsdGeom.Sphere.Define(stage, "/Scene/ball")
    ball.CreateRadiusAttr(0.05)
    ball.AddTranslateOp().Set(Gf.Vec3d(-0.3, 0.1, 1.2))
    for prim, mass in ((crate.GetPrim(), 1.0), (ball.GetPrim(), 0.2)):
        UsdPhysics.RigidBodyAPI.Apply(prim)
        UsdPhysics.CollisionAPI.Apply(prim)
        UsdPhysics.MassAPI.Apply(prim).CreateMassAttr(mass)
    stage.Save()
    return path


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--usd", default=None, help="a UsdPhysics stage; default: author one")
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args(argv)
    usd = Path(args.usd) if args.usd else author_scene(Path(tempfile.mkdtemp()) / "table_scene.usda")

    world = World()
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=str(usd), prim_path="/World/Scene")
    crate = world.scene.add(RigidPrim(prim_path="/World/Scene/crate"))
    ball = world.scene.add(RigidPrim(prim_path="/World/Scene/ball"))
    world.reset()
    while world.current_time < args.seconds - 1e-9:
        world.step(render=False)
    crate_pos, ball_pos = crate.get_world_pose()[0], ball.get_world_pose()[0]
    print(f"crate ({crate.get_mass():.1f} kg) rests at {np.round(crate_pos, 3)} m; "
          f"ball ({ball.get_mass():.1f} kg) at {np.round(ball_pos, 3)} m")
    return {"crate_position": crate_pos, "ball_position": ball_pos}


if __name__ == "__main__":
    main()
