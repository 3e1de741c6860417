"""ONNX export of a trained detector (model + NMS-free decoding in one graph), checked with ONNX Runtime.

The graph takes ``images`` (1, 3, H, W) float32 in [0, 1] at the checkpoint's canvas size ((1, 4, H, W)
for an ``inputs="rgbd"`` model, the 4th channel ``model.depth_channel``'s; (1, 5, H, W) for ``"rgbdh"``, the
5th ``model.height_channel``'s; the sidecar's ``inputs`` says which) and returns
``boxes`` (1, K, 4) x0 y0 x1 y1 px, ``scores`` (1, K) and ``classes`` (1, K) int64 (0-based; the
category names are in ``<file>.json`` beside it); a model with masks also returns ``masks`` (1, K,
H/4, W/4) float32, each detection's mask probabilities at stride 4 (``model.paste_masks`` makes
them pixels). ``check_onnx`` runs both on one image and returns the largest differences, so an
export that disagrees with torch is caught where it is made.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import torch

from ambulo.utils.atomic import atomic_write_json

from .model import INPUT_CHANNELS, CenterNet, ExportedDetector
from .train import load_trained

OUTPUTS = ("boxes", "scores", "classes")
MASK_OUTPUT = "masks"


def output_names(model: CenterNet) -> list[str]:
    return [*OUTPUTS, MASK_OUTPUT] if model.cfg.mask_prototypes else list(OUTPUTS)


def export_onnx(checkpoint: str | Path, out: str | Path, opset: int = 17) -> Path:
    """Write ``out`` (ONNX) and ``out``.json (categories, canvas size) from a training checkpoint."""
    model, state = load_trained(checkpoint)
    out = export_model(model, state["canvas_hw"], out, opset)
    atomic_write_json(sidecar(out), {"categories": state["categories"], "category_ids": state["category_ids"],
                                     "canvas_hw": list(state["canvas_hw"]),
                                     "max_detections": model.cfg.max_detections,
                                     "outputs": output_names(model), "inputs": model.cfg.inputs})
    return out


def export_model(model: CenterNet, canvas_hw: tuple[int, int], out: str | Path, opset: int = 17) -> Path:
    """Write the ONNX graph of ``model`` + decoding for images of ``canvas_hw`` (H, W) to ``out``."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    example = torch.rand(1, INPUT_CHANNELS[model.cfg.inputs], *canvas_hw)
    # the TorchScript exporter: the graph is static (one canvas size), and it needs no onnxscript
    with warnings.catch_warnings():  # the trace's shape arithmetic is constant for one canvas size
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        torch.onnx.export(ExportedDetector(model.eval()), (example,), str(out), input_names=["images"],
                          output_names=output_names(model), opset_version=opset, dynamo=False)
    return out


def sidecar(onnx_path: str | Path) -> Path:
    return Path(f"{onnx_path}.json")


def check_onnx(checkpoint: str | Path, onnx_path: str | Path, image: np.ndarray | None = None,
               seed: int = 0) -> dict:
    """``compare_detections`` of torch and ONNX Runtime on one image (1, C, H, W) float32 in [0, 1] at
    the canvas size (C: 3, or 4 for an rgbd model; a random one by default)."""
    import onnxruntime as ort

    model, state = load_trained(checkpoint)
    h, w = state["canvas_hw"]
    if image is None:
        image = np.random.default_rng(seed).random((1, INPUT_CHANNELS[model.cfg.inputs], h, w), dtype=np.float32)
    with torch.no_grad():
        expected = [t.numpy() for t in ExportedDetector(model)(torch.from_numpy(image))]
    session = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    got = session.run(output_names(model), {"images": image})
    return compare_detections(expected, got)


def compare_detections(expected: list[np.ndarray], got: list[np.ndarray], score_tol: float = 1e-4,
                       box_tol_px: float = 0.01) -> dict:
    """Order-free agreement of two (boxes, scores, classes[, masks]) outputs of batch 1.

    ``scores``: the largest score difference between matched boxes (a box below the cut-off may
    enter or leave the K best on the runtime's last bit, so sorted lists are not compared). Each expected box whose score stands
    clear of the K-th (ties at the cut-off may be broken either way) is ``compared`` with the boxes of
    ``got`` of its class and score; ``boxes_px`` is the largest distance (largest coordinate) to the
    nearest of them among the boxes that have one within ``box_tol_px``, ``unmatched`` counts those
    that have none. A box is unmatched when two neighbouring cells' scores are equal to float
    rounding: which of them is the 3x3 maximum then depends on the runtime's last bit (the box moves
    by one 4 px cell). That happens on flat, untrained heatmaps; a trained model's peaks stand clear.
    With masks, ``masks`` is the largest probability difference between the masks of matched boxes."""
    (eb, es, ec, *em), (gb, gs, gc, *gm) = ([a[0] for a in out] for out in (expected, got))
    inner = np.flatnonzero(es > es.min() + score_tol)
    worst, unmatched, worst_mask, score_diff = 0.0, 0, 0.0, 0.0
    for i in inner:
        same = np.flatnonzero((gc == ec[i]) & (np.abs(gs - es[i]) <= score_tol))
        distances = np.abs(gb[same] - eb[i]).max(axis=1) if len(same) else np.array([np.inf])
        if distances.min() > box_tol_px:
            unmatched += 1
            continue
        match = same[distances.argmin()]
        worst = max(worst, float(distances.min()))
        score_diff = max(score_diff, float(abs(gs[match] - es[i])))
        if em:
            worst_mask = max(worst_mask, float(np.abs(gm[0][match] - em[0][i]).max()))
    out = {"scores": score_diff, "boxes_px": worst, "compared": int(len(inner)), "unmatched": unmatched}
    if em:
        out["masks"] = worst_mask
    return out


def read_sidecar(onnx_path: str | Path) -> dict:
    return json.loads(sidecar(onnx_path).read_text())
