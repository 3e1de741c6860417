"""Detection trained on ambulo's own synthetic data: read an ``ambulo generate`` COCO dataset,
train a small CenterNet with instance masks from scratch (nothing downloaded), evaluate with
pycocotools (boxes and masks, on held-out frames or another dataset: ``evaluate_checkpoint``),
export to ONNX and run it on frames (``Detector``). See docs/detection.md."""

from .augment import AugmentCfg, augment_batch, generic, geometry_only, no_augment, viewpoint
from .dataset import CocoFrames, DatasetError, load_coco, split_image_ids
from .detector import Detections, Detector
from .evaluate import coco_metrics, predict_coco
from .export import check_onnx, export_onnx
from .model import MODELS, CenterNet, ModelCfg, build_model, decode
from .train import CHECKPOINT, TrainCfg, TrainResult, load_trained, train
from .transfer import evaluate_checkpoint

__all__ = ["CHECKPOINT", "MODELS", "AugmentCfg", "CenterNet", "CocoFrames", "DatasetError", "augment_batch", "generic", "geometry_only", "viewpoint", "Detections", "Detector",
           "ModelCfg", "TrainCfg", "TrainResult", "build_model", "check_onnx", "coco_metrics", "decode",
           "evaluate_checkpoint", "export_onnx", "load_coco", "load_trained", "no_augment", "predict_coco", "split_image_ids", "train"]
