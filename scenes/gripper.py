"""The parallel-jaw gripper: one geometry, used by the simulator and by the grasp planner.

Gripper frame (the frame of a grasp, as the env's action gives it):
- origin: the *tool centre point* (TCP), midway between the two finger pads' centres;
- +z: the approach direction (from the hand towards the object; the fingers point along +z);
- +y: the closing axis (the fingers slide along +/-y, towards the TCP when closing);
- +x = y cross z.

Dimensions are Franka-hand-like in opening (8 cm) and finger length, with a narrower palm
(12 cm instead of 20 cm) because our objects are toy-scale tabletop objects.
Every shape of the hand is a box given as (centre, half-extents) in the gripper frame, with
the fingers at a given half-opening ``q`` (0 closed, ``MAX_OPENING / 2`` fully open).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_OPENING = 0.08
"""Largest distance between the finger pads (m)."""


@dataclass(frozen=True)
class GripperGeometry:
    """Dimensions of the hand (metres). Defaults are the simulated gripper's."""

    max_opening: float = MAX_OPENING
    # finger: a box whose inner face is the pad; it spans z in [-finger_length + tip, tip]
    finger_length: float = 0.055
    finger_tip: float = 0.012  # how far the finger tips reach beyond the TCP along +z
    finger_thickness: float = 0.012  # along y
    finger_width: float = 0.02  # along x (the pad is as wide as the finger)
    # palm: a box behind the fingers
    palm_half: tuple[float, float, float] = (0.025, 0.06, 0.02)
    pregrasp_distance: float = 0.10  # approach starts this far back along -z
    lift_height: float = 0.15
    grip_force: float = 20.0  # N per finger (force limit of the finger actuators)
    pad_friction: float = 1.2

    @property
    def palm_center_z(self) -> float:
        """z of the palm's centre: the palm starts where the fingers end."""
        return self.finger_tip - self.finger_length - self.palm_half[2]

    def finger_boxes(self, half_opening: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """(centre, half-extents) of the two fingers at ``half_opening`` (the pad faces sit
        at y = +/-half_opening)."""
        hz = self.finger_length / 2
        cz = self.finger_tip - hz
        half = np.array([self.finger_width / 2, self.finger_thickness / 2, hz])
        out = []
        for s in (1.0, -1.0):
            cy = s * (half_opening + self.finger_thickness / 2)
            out.append((np.array([0.0, cy, cz]), half))
        return out

    def palm_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(centre, half-extents) of the palm."""
        return np.array([0.0, 0.0, self.palm_center_z]), np.array(self.palm_half)

    def boxes(self, half_opening: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """Every box of the hand at ``half_opening``: palm first, then the two fingers."""
        return [self.palm_box(), *self.finger_boxes(half_opening)]


GRIPPER = GripperGeometry()
"""The gripper every scene and the planner use."""
