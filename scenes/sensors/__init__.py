"""Depth sensors: what a real device returns of a rendered scene (docs/sensors.md).

One module per sensor, each citing the published source of every parameter:

- :mod:`.ideal`: the render as it is (the isolated suites' default, as the dissertation's);
- :mod:`.kinect_v1`: structured light (Microsoft Kinect v1): Nguyen, Izadi and Lovell 2012's
  axial and lateral noise, 1/8-pixel disparity, projector shadows, grazing-angle dropout;
- :mod:`.d435`: active stereo (Intel RealSense D435): infrared images lit by a dot pattern,
  matched by OpenCV's StereoSGBM, at the device's 50 mm baseline.

:func:`make_sensor` builds one by name for an image size and field of view.
"""

from __future__ import annotations

from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.sensors.base import Sensor, SensorError

SENSORS: tuple[str, ...] = ("ideal", "kinect-v1", "d435")
"""The registered sensor names, in the order the robustness tables show them."""

DEFAULT_SENSOR = "ideal"

SENSOR_VERSIONS: dict[str, int] = {"ideal": 1, "kinect-v1": 4, "d435": 3}
"""Bumped whenever a change alters what a sensor returns: a run's identity names it (the
suite record's ``sensor_version``, for every sensor but ``ideal``), so results of an older
model are never resumed into or compared with a newer one. Version 2 (kinect-v1: axial noise
drawn per 2x2 block, Box-Muller draws; d435: the texture threshold, matching only where a
surface is, the longer exposure) changed every capture of both. d435 version 3: SGBM's
disparity refined by a Lucas-Kanade step (no pixel locking), the sensor noise calibrated to
the D4 series' 0.08 px sub-pixel RMS, a longer exposure limit and the texture threshold
above the new noise. kinect-v1 version 3: an edge moves by a draw shared by the pixels on
both sides of it (smooth displacement fields), at the incidence of the surface whose edge it
is (so the lateral noise grows beyond 60 degrees, as Nguyen et al.'s eq. 2); the incidence
and its limit per 2x2 block, the shadows on every other row. kinect-v1 version 4: a pixel
with no surface in the render returns nothing (version 3 gave the background pixels of a
2x2 block that straddles an object's edge the block's axial noise, a depth of a few mm
either side of 0)."""


def check_sensor_name(name: str) -> str:
    """``name`` if it is a registered sensor, else :class:`SensorError` with the close
    matches (case-insensitively)."""
    from beo_bench.names import did_you_mean

    if name in SENSORS:
        return name
    hint = did_you_mean(name, SENSORS, cutoff=0.5)
    raise SensorError(
        f"unknown sensor {name!r}: {hint}use one of {', '.join(SENSORS)} (--sensor NAME)"
    )


def make_sensor(name: str, intrinsics: Intrinsics) -> Sensor:
    """The sensor ``name`` for depth images of ``intrinsics``' size and field of view.
    Raises :class:`SensorError` for an unknown name or a size the sensor cannot support."""
    check_sensor_name(name)
    if name == "ideal":
        from beo_bench.scenes.sensors.ideal import IdealSensor

        return IdealSensor(intrinsics)
    if name == "kinect-v1":
        from beo_bench.scenes.sensors.kinect_v1 import KinectV1

        return KinectV1(intrinsics)
    from beo_bench.scenes.sensors.d435 import D435

    return D435(intrinsics)


__all__ = [
    "DEFAULT_SENSOR",
    "SENSORS",
    "SENSOR_VERSIONS",
    "Sensor",
    "SensorError",
    "check_sensor_name",
    "make_sensor",
]
