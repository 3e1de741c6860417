"""benchmarks/terrain_engines.py on the CPU engine: it finds the sole spheres and the terrain by
name and counts their contacts as MuJoCo's own contact list has them."""

import argparse
import sys

import pytest

from script_loader import ROOT, load_script

bench = load_script(ROOT / "benchmarks" / "terrain_engines.py")


def test_resting_feet_touch_the_terrain_through_their_sole_spheres_only():
    args = argparse.Namespace(task="humanoid-footsteps-stairs", kinds="flat", box_kinds=None, mujoco_hfield=None,
                              worlds=2, settle_s=0.5, seed=7, episode_length_s=20.0)
    env = bench.make(args, "mujoco", "cpu", args.worlds, None)
    env.reset()
    terrain, soles = bench.geom_ids(env.engine.model)
    assert len(soles) == 8 and terrain  # four spheres under each sole; the terrain's geoms
    counts = bench.sphere_contact_counts(env)
    # both robots stand on some of their 16 spheres, each touching through at least one contact
    assert 4 <= counts.size <= 16 and counts.min() >= 1
    # the count is MuJoCo's: every terrain contact of world 0 is a sole sphere's
    data = env.engine.get_data(0)
    touching = [c for c in data.contact[:data.ncon] if {int(c.geom1), int(c.geom2)} & terrain]
    assert touching and all({int(c.geom1), int(c.geom2)} & soles for c in touching)
    env.close()


def test_a_wrong_run_task_or_tile_kind_is_one_line_before_anything_is_built(monkeypatch):
    for args, said in ((["--run", "/no/such/run"], "is neither a run folder"),
                       (["--task", "cartpole"], "task cartpole has no terrain"),
                       (["--kinds", "flat,bogus"], "unknown ['bogus']"),
                       (["--box-kinds", "flat,rough"], "['rough'] cannot be boxes"),
                       (["--engines", "mujoco,wrap"], "unknown ['wrap']")):
        monkeypatch.setattr(sys, "argv", ["terrain_engines.py", *args])
        with pytest.raises(SystemExit) as stop:
            bench.main()
        assert said in str(stop.value) and "\n" not in str(stop.value)
