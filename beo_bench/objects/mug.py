"""Mug: a thin tapered wall of revolution on a solid base, usually with a handle.

Without a handle a mug is close to a can (classes overlap in parts, as in ShapeNet).
The handle sits on the +y side; the mug is picked by its wall (one finger inside) or handle.
"""

from __future__ import annotations

import numpy as np

from beo_bench.geometry import continuous_symmetry, no_symmetry
from beo_bench.objects.params import Choice, Flag, Params, Uniform
from beo_bench.objects.primitives import Assembly, frustum, revolve_shell, tube
from beo_bench.objects.registry import register_category


@register_category(
    "mug",
    params={
        "height": Uniform(0.075, 0.115),
        "radius": Uniform(0.03, 0.045),
        "taper": Uniform(0.8, 1.1),  # top radius / bottom radius
        "wall": Uniform(0.003, 0.006),
        "base": Uniform(0.004, 0.012),  # bottom thickness
        "handle": Flag(0.85),
        "handle_shape": Choice(("round", "square")),
        "handle_span": Uniform(0.45, 0.8),  # vertical span / height
        "handle_reach": Uniform(0.018, 0.035),
        "handle_radius": Uniform(0.004, 0.007),
        "handle_centre": Uniform(0.42, 0.58),  # centre height / height
    },
    shapenet_synsets=("03797390",),
    modelnet_names=("cup",),
)
def build(p: Params) -> Assembly:
    """Mug (11 parameters: body height, radius, taper, wall, base; handle presence, shape,
    span, reach, thickness and height)."""
    h, r0 = float(p["height"]), float(p["radius"])
    r1 = r0 * float(p["taper"])
    wall, base = float(p["wall"]), float(p["base"])
    parts = revolve_shell([(r0, 0.0), (r1, h)], wall)
    parts.append(frustum(r0, r0 + (r1 - r0) * base / h, 0.0, base))
    if not p["handle"]:
        return Assembly(parts, continuous_symmetry())

    span = float(p["handle_span"]) * h
    zc = float(np.clip(float(p["handle_centre"]) * h, span / 2 + base, h - span / 2 - 0.004))
    z_top, z_bot = zc + span / 2, zc - span / 2
    reach, rad = float(p["handle_reach"]), float(p["handle_radius"])

    def wall_r(z: float) -> float:  # outer radius of the wall at height z, minus a bit so
        return r0 + (r1 - r0) * z / h - wall / 2  # the handle roots inside the wall

    if p["handle_shape"] == "round":
        t = np.linspace(-np.pi / 2, np.pi / 2, 9)
        y = wall_r(zc) + reach * np.cos(t)
        y[0], y[-1] = wall_r(z_bot), wall_r(z_top)
        path = np.stack([np.zeros_like(t), y, zc + span / 2 * np.sin(t)], axis=1)
    else:
        path = np.array(
            [
                [0.0, wall_r(z_top), z_top],
                [0.0, wall_r(z_top) + reach, z_top],
                [0.0, wall_r(z_bot) + reach, z_bot],
                [0.0, wall_r(z_bot), z_bot],
            ]
        )
    parts += tube(path, rad)
    return Assembly(parts, no_symmetry())
