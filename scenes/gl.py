"""Choose MuJoCo's off-screen GL platform before ``mujoco`` is imported.

``MUJOCO_GL`` is read once, when ``mujoco`` is first imported (docs/design.md "Scenes"): every
module of beo-bench that renders imports ``mujoco`` through :func:`load_mujoco`, so the choice
is made here and only here. Order: the user's own ``MUJOCO_GL`` if set, else EGL (Mesa's
llvmpipe renders on the CPU), else OSMesa.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from types import ModuleType

from beo_bench.errors import BeoBenchError

EGL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0"
OSMESA_PACKAGES = "libosmesa6"


class GLUnavailableError(BeoBenchError):
    """No off-screen OpenGL platform could be loaded."""


def _loads(*names: str) -> bool:
    for name in names:
        try:
            ctypes.CDLL(name)
        except OSError:
            return False
    return True


def choose_platform() -> str:
    """The GL platform to use: ``MUJOCO_GL`` when set, else ``egl``, else ``osmesa``."""
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    if _loads("libEGL.so.1", "libOpenGL.so.0"):
        return "egl"
    if _loads("libOSMesa.so.8") or ctypes.util.find_library("OSMesa"):
        return "osmesa"
    raise GLUnavailableError(
        "no off-screen OpenGL platform: neither EGL nor OSMesa could be loaded. On Debian or "
        f"Ubuntu install them as root: `apt-get install {EGL_PACKAGES}` (or "
        f"`{OSMESA_PACKAGES}` for OSMesa); `make setup` does this for you."
    )


def load_mujoco() -> ModuleType:
    """``import mujoco`` with the GL platform chosen (idempotent)."""
    # Mesa's llvmpipe renders on its own thread pool by default. Those threads make a
    # process that has rendered unsafe to fork (a forked child's first render hangs on a
    # lock held by a thread that does not exist there, and gymnasium's async vector envs
    # fork by default), and they buy nothing here: frames are small and work is spread
    # over worker processes, one renderer each (measured on 2 cores, 640x480 depth +
    # segmentation: 7.2 ms with the pool, 7.1 ms without). Mesa reads this when the first
    # context is made, so it holds even when mujoco was imported before beo_bench.
    os.environ.setdefault("LP_NUM_THREADS", "0")
    if "mujoco" not in sys.modules:
        platform = choose_platform()
        os.environ["MUJOCO_GL"] = platform
        if platform in ("egl", "osmesa"):
            # PyOpenGL, used by mujoco's GL contexts, must agree with MuJoCo's choice.
            os.environ.setdefault("PYOPENGL_PLATFORM", platform)
    import mujoco

    return mujoco
