"""``rep.orchestrator.preview()`` under ``ambulo run``: one frame, nothing written; a script that
ends after it gets Kit's Run (its frames written, said on stderr). Replicator's Hello World."""

import json
from pathlib import Path

from ambulo.isaac import run_script

HELLO = Path(__file__).resolve().parents[2] / "examples" / "isaac" / "replicator_hello_world.py"
RUN_LINE = "ambulo run: the script ended after rep.orchestrator.preview(); running its"

SCRIPT = """
import json, os, sys
import omni.replicator.core as rep
out, listing, mode = sys.argv[1:4]
rep.set_global_seed(3)
cam = rep.create.camera(position=(0, -5, 3), look_at=(0, 0, 0))
rp = rep.create.render_product(cam, (32, 24))
torus = rep.create.torus(semantics=[("class", "torus")])
with rep.trigger.on_frame(num_frames=2):
    with torus:
        rep.modify.pose(position=rep.distribution.uniform((-1, -1, 0), (1, 1, 0)),
                        scale=rep.distribution.uniform(0.5, 1.5))
writer = rep.WriterRegistry.get("BasicWriter")
writer.initialize(output_dir=out, rgb=True, bounding_box_2d_tight=True)
writer.attach([rp])
if mode != "run":
    rep.orchestrator.preview()
with open(listing, "w") as f:
    json.dump(sorted(os.listdir(out)) if os.path.isdir(out) else [], f)
if mode == "step":
    rep.orchestrator.step()
if mode == "run":
    rep.orchestrator.run()
"""


def frames(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}


def run(tmp_path: Path, mode: str) -> tuple[Path, list[str]]:
    script = tmp_path / "preview.py"
    script.write_text(SCRIPT)
    out, listing = tmp_path / mode, tmp_path / f"{mode}.json"
    run_script(script, [str(out), str(listing), mode])
    return out, json.loads(listing.read_text())


def names(count: int) -> list[str]:
    return sorted(f"{s}_{i:04d}.{e}" for i in range(count) for s, e in (
        ("rgb", "png"), ("bounding_box_2d_tight", "npy"), ("bounding_box_2d_tight_labels", "json"),
        ("bounding_box_2d_tight_prim_paths", "json")))


def test_preview_writes_nothing_and_the_script_end_runs_the_triggers_frames(tmp_path, capsys):
    out, after_preview = run(tmp_path, "preview")
    assert after_preview == []  # preview() renders a frame for the viewport, not for the writers
    assert f"{RUN_LINE} 2 frames" in capsys.readouterr().err
    written = frames(out)
    assert sorted(written) == names(2)
    # preview() did not use up a frame: Run writes frames 0 and 1, as run() alone would
    ran, _ = run(tmp_path, "run")
    assert RUN_LINE not in capsys.readouterr().err
    assert frames(ran) == written


def test_a_script_that_steps_after_preview_gets_only_its_own_frames(tmp_path, capsys):
    out, after_preview = run(tmp_path, "step")
    assert after_preview == []
    assert sorted(frames(out)) == names(1)
    assert RUN_LINE not in capsys.readouterr().err


def test_replicators_hello_world_runs_unchanged_and_writes_its_output(tmp_path, capsys):
    num_frames, out = 3, tmp_path / "_output"
    run_script(HELLO, ["--output_dir", str(out), "--resolution", "64", "64", "--num_frames", str(num_frames)])
    assert f"{RUN_LINE} {num_frames} frames" in capsys.readouterr().err
    assert sorted(frames(out)) == names(num_frames)
    labels = json.loads((out / "bounding_box_2d_tight_labels_0000.json").read_text())
    assert set(v["class"] for v in labels.values()) <= {"torus", "sphere", "cube"}
