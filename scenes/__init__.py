"""Tabletop scenes and off-screen rendering (``beo_bench.scenes``; docs/design.md "Scenes").

- :mod:`.camera`: intrinsics (K), the camera rig, the one MuJoCo <-> OpenCV conversion;
- :mod:`.renderer`: metric depth + instance segmentation (+ RGB) with a reused GL context;
- :mod:`.builder`: MjSpec models (table, objects, gripper, camera);
- :mod:`.layout`: rest poses and non-overlapping placement;
- :mod:`.execute`: scripted, physical grasp execution;
- :mod:`.pickconfig`: BEOPick-v0's settings, checked once (``PickConfig``: the env's, its
  scenes' and the bench's tabletop and pick items');
- :mod:`.tabletop`: BEOPick-v0's scenes drawn, settled and rendered (what the env's ``reset``
  runs; for code below the envs, which never imports them);
- :mod:`.isolated`: views of an isolated instance (training data, perception suites);
- :mod:`.sensors`: depth sensors (``ideal``, ``kinect-v1``, ``d435``): what a suite's and
  the env's views are captured by (docs/sensors.md);
- :mod:`.noise`: HBEO's training augmentation (``DepthNoise``; no suite's sensor);
- :mod:`.gripper`: the gripper's geometry (shared with the grasp planner).

Names are loaded lazily so that importing a light module (``gripper``, ``camera``) does not
load MuJoCo and a GL platform.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Intrinsics": "camera",
    "CameraRig": "camera",
    "TABLE_RIG": "camera",
    "OBJECT_RIG": "camera",
    "TOP_DOWN_RIG": "camera",
    "look_at": "camera",
    "backproject": "camera",
    "project": "camera",
    "Renderer": "renderer",
    "Frame": "renderer",
    "IsolatedRenderer": "isolated",
    "IsolatedView": "isolated",
    "render_isolated": "isolated",
    "DepthNoise": "noise",
    "apply_noise": "noise",
    "GRIPPER": "gripper",
    "GripperGeometry": "gripper",
    "GLUnavailableError": "gl",
    "TabletopScenes": "tabletop",
    "NoVisibleTargetError": "tabletop",
    "PickConfig": "pickconfig",
    "default_categories": "pickconfig",
}


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"beo_bench.scenes.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'beo_bench.scenes' has no attribute {name!r}")


__all__ = sorted(_EXPORTS)
