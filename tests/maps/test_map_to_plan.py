"""Acceptance: ``ambulo map indoor --out m`` then ``ambulo plan --map m/costmap.npz`` plans on that
map: the footsteps avoid what the mapper saw, and unknown (never seen) ground is blocked."""

from ambulo.cli import main
from ambulo.maps import load_npz


def test_plan_reads_the_costmap_ambulo_map_writes(tmp_path, capsys):
    out = tmp_path / "m"
    # the smallest run the trajectory scoring accepts (fewer frames or pixels: a degenerate alignment)
    assert main(["map", "indoor", "--frames", "30", "--width", "160", "--height", "120", "--out", str(out)]) == 0
    grid = load_npz(out / "costmap.npz")
    assert grid.cost is not None and grid.unknown().any() and grid.occupied().any() and grid.free().any()
    capsys.readouterr()

    png = tmp_path / "plan.png"
    argv = ["plan", "--map", str(out / "costmap.npz"), "--png", str(png)]
    assert main([*argv, "--start", "2.0,-2.4,0", "--goal", "3.2,0,90"]) == 0  # across the seen floor
    assert "plan: success" in capsys.readouterr().out and png.stat().st_size > 0

    box, unseen = (3.7, -1.3), (2.2, 1.0)  # a box the camera saw; ground it never saw
    iy, ix = grid.cell_of(box)
    near_box = grid.occupied()[iy - 5:iy + 6, ix - 5:ix + 6]  # within 0.25 m of its centre
    # the face the camera saw is occupied; the box's inside was never seen, so it is unknown, not occupied
    assert near_box.any() and grid.unknown()[iy, ix] and grid.unknown()[grid.cell_of(unseen)]
    assert main([*argv, "--start", "2.0,-2.4,0", "--goal", f"{box[0]},{box[1]}"]) == 1
    assert "goal_in_collision" in capsys.readouterr().out
    assert main([*argv, "--start", f"{unseen[0]},{unseen[1]},-90", "--goal", "3.2,0,90"]) == 1
    assert "start_in_collision" in capsys.readouterr().out
