"""``evaluate_checkpoint``: a trained detector scored on another dataset, categories matched by name."""

import json
import shutil

import pytest

from ambulo.detection import DatasetError, evaluate_checkpoint


def test_scores_follow_category_names_not_ids(tmp_path, trained_shapes):
    root, checkpoint = trained_shapes
    own = evaluate_checkpoint(checkpoint, root)
    # trained on these frames: it finds them (so the comparisons below compare something)
    assert own["frames"] == 4 and own["mAP50"] > 0.3 and own["mask"]["mAP50"] > 0.3, (own["mAP50"], own["per_class"]) and set(own["per_class"]) == set(own["mask"]["per_class"]) == {"disc", "square"}
    boxes_only = evaluate_checkpoint(checkpoint, root, held_out_fraction=0.5, masks=False)
    assert boxes_only["frames"] == 2 and "mask" not in boxes_only and boxes_only["mAP50"] > 0
    # the same frames with the categories renumbered (and one more the detector never saw): the same scores
    other = tmp_path / "renumbered"
    shutil.copytree(root, other)
    coco = json.loads((other / "annotations.json").read_text())
    new_id = {1: 7, 2: 3}
    coco["categories"] = [{"id": 7, "name": "disc"}, {"id": 3, "name": "square"}, {"id": 9, "name": "triangle"}]
    for ann in coco["annotations"]:
        ann["category_id"] = new_id[ann["category_id"]]
    (other / "annotations.json").write_text(json.dumps(coco))
    renumbered = evaluate_checkpoint(checkpoint, other)
    assert renumbered["per_class"] == pytest.approx(own["per_class"])
    assert renumbered["mask"]["mAP"] == pytest.approx(own["mask"]["mAP"]) and renumbered["mAP"] == pytest.approx(own["mAP"])
    # swapping the names swaps what is scored: the detector's discs are now called squares
    for category in coco["categories"]:
        category["name"] = {"disc": "square", "square": "disc"}.get(category["name"], category["name"])
    (other / "annotations.json").write_text(json.dumps(coco))
    assert evaluate_checkpoint(checkpoint, other)["mAP50"] < 0.5 * own["mAP50"]
    coco["categories"] = coco["categories"][:1] + coco["categories"][2:]
    coco["annotations"] = [a for a in coco["annotations"] if a["category_id"] != 3]
    (other / "annotations.json").write_text(json.dumps(coco))
    with pytest.raises(DatasetError, match="no categories"):
        evaluate_checkpoint(checkpoint, other)


def test_cli_evaluates_a_checkpoint_on_a_dataset(tmp_path, trained_shapes, capsys):
    from ambulo.cli import main

    root, checkpoint = trained_shapes
    assert main(["evaluate-detector", str(checkpoint), str(root), "--held-out", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "2 frames, boxes: mAP" in out and "2 frames, masks: mAP" in out and "disc" in out
    assert main(["evaluate-detector", str(checkpoint), str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no annotations.json" in err
