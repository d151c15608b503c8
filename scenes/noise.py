"""HBEO's training augmentation: a simple depth-noise model applied to a share of its
training crops (``beo_bench.perception.hbeo.data``, ``DatasetConfig.noise_share``), which the
published models were trained with.

It is no suite's sensor any more: the suites and BEOPick-v0 capture their depth through
``beo_bench.scenes.sensors`` (``--sensor``, ``sensor=``; the tabletop suite's own is
``kinect-v1``, a fuller model of the same device; docs/sensors.md). It stays as it is so that
the published recipe renders the same crops.

Three effects of structured-light / stereo depth sensors, applied in this order:
1. axial Gaussian noise whose standard deviation grows with depth, sigma(z) = a + b (z - z0)^2
   (the Kinect model of Nguyen, Izadi and Lovell, 3DIMPVT 2012: a = 1.2 mm, b = 1.9 mm/m^2,
   z0 = 0.4 m);
2. disparity quantisation: depth is rounded in disparity, so the step grows as z^2
   (step = z^2 / (f * baseline) * disparity_step);
3. dropout at depth discontinuities (missing pixels along object edges, as on real sensors).
Seeded through the generator the caller passes.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class DepthNoise:
    """Parameters of :func:`apply_noise` (metres unless named otherwise)."""

    sigma_a: float = 0.0012
    sigma_b: float = 0.0019
    sigma_z0: float = 0.4
    focal_px: float = 580.0
    baseline: float = 0.075
    disparity_step: float = 1.0 / 8.0  # sub-pixel disparity resolution (pixels)
    edge_jump: float = 0.02  # a neighbour this much farther makes a pixel an edge pixel
    edge_dropout: float = 0.5  # probability that an edge pixel reads 0


def apply_noise(depth: np.ndarray, rng: np.random.Generator, noise: DepthNoise) -> np.ndarray:
    """A noisy copy of ``depth`` (float32 metres, 0 = no reading stays 0)."""
    d = np.asarray(depth, dtype=np.float32)
    valid = d > 0
    z = d.astype(np.float64)
    sigma = noise.sigma_a + noise.sigma_b * (z - noise.sigma_z0) ** 2
    z = z + rng.standard_normal(z.shape) * sigma
    # disparity = f b / z, quantised to disparity_step pixels
    disp = noise.focal_px * noise.baseline / np.maximum(z, 1e-6)
    disp = np.round(disp / noise.disparity_step) * noise.disparity_step
    z = noise.focal_px * noise.baseline / np.maximum(disp, 1e-9)
    # edge pixels: a 3x3 neighbourhood whose max depth jumps (dilate = max filter)
    far = np.where(valid, d, np.float32(1e3))
    neighbour_max = cv2.dilate(far, np.ones((3, 3), np.uint8))
    edge = valid & (neighbour_max - d > noise.edge_jump)
    drop = edge & (rng.random(d.shape) < noise.edge_dropout)
    out = np.where(valid & ~drop, z, 0.0).astype(np.float32)
    return out
