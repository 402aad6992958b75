"""Rebar segmentation: a binary rebar mask for the colour image (method.md, Stage 3, step 1).

One idea per module:

* :mod:`.model` and :mod:`.sidecar`, the model contract: :class:`SegmentationModel` runs any ONNX
  segmentation network with onnxruntime, described by a small sidecar JSON (how to feed it, how
  to read it); :meth:`SegmentationModel.default` loads the model shipped in ``rebarlib/models``
  (trained by ``training/train_segmentation.py``).
* :mod:`.depth`: :func:`mask_from_depth`, the pixels whose depth lies clearly above the formwork
  plane, which shadows and rust cannot fool.
* :mod:`.fusion`: :func:`fuse_masks` keeps the colour mask's edges where depth agrees that a bar
  is there, and fills bars that colour missed; :func:`soft_mask` makes a fused mask soft again.
* :mod:`.registration`: :func:`estimate_registration`, how far the depth image lies from the
  colour one, and :func:`shift_image`.
* :mod:`.metrics`: :func:`confusion_counts`, :func:`pixel_accuracy`, :func:`iou`, :func:`dice`,
  the paper's formulas (method.md, "Segmentation metrics").

The synthetic data set the shipped model was trained and is tested on lives outside the runtime,
in :mod:`rebarlib.synth_segmentation`. The runtime imports neither torch nor :mod:`rebarlib.synth`.
"""

from __future__ import annotations

from .depth import fit_formwork_plane, height_above_plane, mask_from_depth
from .fusion import depth_overreach_px, fuse_masks, soft_mask, trim_depth_overreach
from .metrics import confusion_counts, dice, iou, pixel_accuracy
from .model import DEFAULT_MODEL, MODELS_DIR, SegmentationModel
from .registration import estimate_registration, shift_image
from .sidecar import SIDECAR_FORMAT, read_sidecar

__all__ = [
    "SegmentationModel",
    "read_sidecar",
    "confusion_counts",
    "pixel_accuracy",
    "iou",
    "dice",
    "fit_formwork_plane",
    "height_above_plane",
    "mask_from_depth",
    "fuse_masks",
    "soft_mask",
    "depth_overreach_px",
    "trim_depth_overreach",
    "estimate_registration",
    "shift_image",
    "MODELS_DIR",
    "DEFAULT_MODEL",
    "SIDECAR_FORMAT",
]
