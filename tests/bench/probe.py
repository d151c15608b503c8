"""A test-only adversarial backend: it never looks at a pixel, only at the View's other
fields (``cam_to_world``, ``K``, the hints, the viewpoint prior), and tries to recover what
the suite's protocol hides: the class, the rotation and the translation.

Two attacks, each a way a plugin could exploit a leak:

- ``origin``: assume the object sits at the world origin in its canonical frame (how the
  isolated renderer places it), so its camera pose is the inverse of ``cam_to_world``;
- ``neighbour``: learn from views of the same suite under another seed (the suites are
  public, so a plugin can render as many as it likes) and answer with the truth of the
  training view whose non-image fields are nearest (standardised Euclidean distance).

``probe_features`` is everything the probe reads; a field added to ``View`` that is not an
image belongs there too (the test checks that it lists every field).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from scipy.spatial import cKDTree

from beo_bench.backend import Backend
from beo_bench.types import Estimate, GroundTruth, View

IMAGE_FIELDS = ("depth", "mask", "segmentation")
"""The View's pixels: what the probe must not read."""
READ_FIELDS = (
    "K",
    "cam_to_world",
    "categories",
    "class_hint",
    "up_hint",
    "world_up",
    "pose_hint",
    "viewpoint_prior",
    "ground_truth",
)
"""Every other field of a View (``ground_truth`` is always None for the probe: it is not
privileged, which the probe asserts)."""


def probe_features(view: View, with_pose_hint: bool = False) -> np.ndarray:
    """Every non-image field of ``view`` as one vector. ``pose_hint`` (known-pose: the true
    pose and size, which the protocol hands out on purpose) only when asked for."""
    assert view.ground_truth is None, "the probe is not privileged: it must not get the truth"
    parts = [np.asarray(view.cam_to_world, float).ravel(), np.asarray(view.K, float).ravel()]
    parts.append(np.zeros(3) if view.up_hint is None else np.asarray(view.up_hint, float))
    parts.append(np.zeros(3) if view.world_up is None else np.asarray(view.world_up, float))
    parts.append([-1.0 if view.class_hint is None else float(view.class_hint)])
    prior = view.viewpoint_prior
    parts.append([0.0, 0.0, 0.0] if prior is None else [*prior.elevation_deg, prior.roll_sigma_deg])
    if with_pose_hint and view.pose_hint is not None:
        R, t, size = view.pose_hint
        parts += [np.asarray(R, float).ravel(), np.asarray(t, float), np.asarray(size, float)]
    return np.concatenate([np.asarray(p, dtype=float).ravel() for p in parts])


@dataclass
class Memory:
    """Training views' features and truths (the ``neighbour`` attack's knowledge)."""

    features: np.ndarray
    truths: list[GroundTruth]

    def nearest(self, x: np.ndarray) -> GroundTruth:
        mu = self.features.mean(axis=0)
        sd = self.features.std(axis=0)
        sd[sd < 1e-12] = 1.0  # a constant field tells nothing: weigh it out
        tree = cKDTree((self.features - mu) / sd)
        _, j = tree.query((x - mu) / sd)
        return self.truths[int(j)]


class FieldProbe(Backend):
    """The probe as a backend (``predict(view) -> Estimate``), reading no pixel."""

    name = "test-probe"

    def __init__(self, attack: str, memory: Memory | None = None) -> None:
        self.attack = attack
        self.memory = memory

    def predict(self, view: View) -> Estimate:
        x = probe_features(view)
        n = len(view.categories)
        p = np.full(n, 1.0 / n)
        if self.attack == "origin":
            inv = np.linalg.inv(np.asarray(view.cam_to_world, dtype=float))
            R, t = inv[:3, :3], inv[:3, 3]
        else:
            assert self.memory is not None
            gt = self.memory.nearest(x)
            R, t = gt.R_cam, gt.t_cam
            p = np.full(n, 0.5 / n)
            p[gt.class_index] += 0.5
        D = 8
        return Estimate(p, R, t, np.ones(3) * 0.1, np.zeros((D, D, D), np.float32))


def view_fields() -> set[str]:
    """The names of View's fields (to check the probe covers every one)."""
    return {f.name for f in fields(View)}
