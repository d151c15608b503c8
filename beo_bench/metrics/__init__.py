"""Evaluation metrics: pure numpy/scipy functions, cheap to import (no torch, no mujoco).
Every one is imported from here (``beo_bench.metrics.rotation_error``); each kind lives in
its module: :mod:`.pose` (rotation, translation, size, MSSD, MSPD, NOCS accuracies, Pix3D
viewpoints), :mod:`.shape` (IoU, EDT, Chamfer-L1, F-score on exact surface distances),
:mod:`.classes` (accuracy, confusion, entropy, "unknown"), :mod:`.episodes` (pick success,
per-view times).

Conventions shared by every function here:

- Rotations are (3, 3) matrices acting on column vectors and map the object's canonical
  frame (+z up, +x front) to the camera frame (OpenCV axes: x right, y down, z forward),
  like ``Estimate.rotation`` and ``GroundTruth.R_cam``. Translations and sizes are metres.
- Symmetry groups are in the BOP toolkit's ``models_info`` form
  (:class:`beo_bench.types.Symmetry`); a symmetry element ``S`` maps the object onto itself,
  so poses ``R`` and ``R @ S`` are indistinguishable.
- Aggregates over many episodes (rates, accuracies) drop NaN entries; an aggregate over
  nothing is NaN. Intervals and paired tests over items are in :mod:`beo_bench.stats`.
- Shape errors raise ``ValueError`` saying what was expected.

References:

- [BOP] Hodaň et al., "BOP: Benchmark for 6D Object Pose Estimation", ECCV 2018, and the
  BOP toolkit (``bop_toolkit_lib/pose_error.py``: ``re``, ``te``, ``mssd``, ``mspd``;
  ``misc.get_symmetry_transformations``); MSSD and MSPD are defined in the BOP Challenge
  2019 evaluation (Hodaň et al., "BOP Challenge 2020 on 6D Object Localization", ECCVW 2020).
- [NOCS] Wang et al., "Normalized Object Coordinate Space for Category-Level 6D Object Pose
  and Size Estimation", CVPR 2019 (the 5deg2cm / 5deg5cm / 10deg5cm accuracies; a pose
  passes when both errors are <= the thresholds).
- [Pix3D] Sun et al., "Pix3D: Dataset and Methods for Single-Image 3D Shape Modeling",
  CVPR 2018 (azimuth / elevation bin accuracy, following Pascal3D+'s AVP bins).
- [Burchfiel] B. Burchfiel, "Bayesian Eigenobjects ..." (PhD dissertation, Duke 2019):
  EDT error (eq. 4.5), gross-error rate (Table 5.2), entropy "unknown" (section 6.2.4).
- [ONet] Mescheder et al., "Occupancy Networks", CVPR 2019 (Chamfer-L1, voxel IoU).
- [Tatarchenko] Tatarchenko et al., "What Do Single-view 3D Reconstruction Networks
  Learn?", CVPR 2019 (F-score at a distance threshold).
"""

from __future__ import annotations

from beo_bench.metrics.classes import (
    class_accuracy,
    confusion_matrix,
    entropy,
    per_class_accuracy,
    predict_with_unknown,
)
from beo_bench.metrics.episodes import (
    pick_summary,
    runtime_stats,
)
from beo_bench.metrics.pose import (
    AZIMUTH_BINS,
    ELEVATION_BINS,
    GROSS_ERROR_DEG,
    MAX_SYM_DISC_STEP,
    NOCS_THRESHOLDS,
    bin_accuracy,
    closest_symmetric_pose,
    gross_error_rate,
    is_gross_error,
    mspd,
    mssd,
    nocs_accuracies,
    pose_accuracy,
    pose_hits,
    rotation_error,
    size_error,
    symmetry_rotations,
    symmetry_transforms,
    translation_error,
    viewpoint,
    viewpoint_bin_accuracy,
    viewpoint_bins,
)
from beo_bench.metrics.shape import (
    FSCORE_TAU,
    NEAREST_TRIANGLES,
    Surface,
    camera_frame_iou,
    chamfer_l1,
    edt,
    edt_error,
    edt_error_per_voxel,
    fscore,
    posed_iou,
    surface_scores,
    voxel_iou,
)

__all__ = [
    "AZIMUTH_BINS",
    "ELEVATION_BINS",
    "FSCORE_TAU",
    "GROSS_ERROR_DEG",
    "MAX_SYM_DISC_STEP",
    "NEAREST_TRIANGLES",
    "NOCS_THRESHOLDS",
    "Surface",
    "bin_accuracy",
    "camera_frame_iou",
    "chamfer_l1",
    "class_accuracy",
    "closest_symmetric_pose",
    "confusion_matrix",
    "edt",
    "edt_error",
    "edt_error_per_voxel",
    "entropy",
    "fscore",
    "gross_error_rate",
    "is_gross_error",
    "mspd",
    "mssd",
    "nocs_accuracies",
    "per_class_accuracy",
    "pick_summary",
    "pose_accuracy",
    "pose_hits",
    "posed_iou",
    "predict_with_unknown",
    "rotation_error",
    "runtime_stats",
    "size_error",
    "surface_scores",
    "symmetry_rotations",
    "symmetry_transforms",
    "translation_error",
    "viewpoint",
    "viewpoint_bin_accuracy",
    "viewpoint_bins",
    "voxel_iou",
]
