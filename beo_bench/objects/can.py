"""Can: a closed cylinder, either a beverage can or a food tin.

A beverage can necks in towards its top, whose lid is recessed inside a thin rim, and
tapers in at its foot; the neck is made decisively longer than the foot so that the can is
clearly not the same upside down (an undeclared near-symmetry). A food tin has a proud
seam at both ends and grooves (beads) around its body placed symmetrically about its middle,
so it is exactly the same upside down and declares that flip. Unlike a handle-less mug,
both kinds are closed solids. A slim can is picked round its body; a wide tin across its
height or by a seam.
"""

from __future__ import annotations

import numpy as np

from beo_bench.geometry import axis_angle, continuous_symmetry
from beo_bench.objects.params import Choice, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly, cylinder, revolve_shell, revolve_solid
from beo_bench.objects.registry import register_category


@register_category(
    "can",
    params={
        "style": Choice(("beverage", "tin")),
        "height": Uniform(0.06, 0.16),
        "radius": Uniform(0.026, 0.045),
        "neck_in": Uniform(0.12, 0.22),  # beverage: lid radius = (1 - neck_in) radius
        "neck_height": Uniform(0.08, 0.16),  # beverage: / height
        "foot_in": Uniform(0.04, 0.1),  # beverage: foot radius = (1 - foot_in) radius
        "recess": Uniform(0.005, 0.008),  # beverage: lid depth below the rim
        "rim": Uniform(0.0015, 0.003),  # beverage: rim thickness
        "seam": Uniform(0.001, 0.003),  # tin: how far the end seams stand proud
        "beads": Integer(0, 4),  # tin: grooves around the body
        "bead_depth": Uniform(0.001, 0.003),
    },
    shapenet_synsets=("02946921",),
)
def build(p: Params) -> Assembly:
    """Can (11 parameters: beverage can or tin; height, radius; a beverage can's neck
    depth and height, foot taper, lid recess and rim thickness; a tin's seam size and
    the number and depth of its body grooves)."""
    h, R = float(p["height"]), float(p["radius"])
    if p["style"] == "beverage":
        rn = R * (1 - float(np.clip(float(p["neck_in"]), 0.05, 0.35)))
        hn = float(np.clip(float(p["neck_height"]), 0.04, 0.25)) * h
        rf = R * (1 - float(np.clip(float(p["foot_in"]), 0.02, 0.25)))
        # the foot is short and steep, the neck long and gradual: a clear top and bottom
        hf = min(0.3 * hn, 0.008)
        parts = revolve_solid([(rf, 0.0), (R, hf), (R, h - hn), (rn, h)])
        rim = float(np.clip(float(p["rim"]), 0.001, 0.3 * rn))
        recess = max(float(p["recess"]), 0.001)
        # the rim rises from just below the lid (so they overlap) to above it
        parts += revolve_shell([(rn, h - 0.002), (rn, h + recess)], rim)
        return Assembly(parts, continuous_symmetry())

    # a tin: the body profile with V grooves spaced evenly, symmetric about mid-height
    n = max(int(p["beads"]), 0)
    g = float(np.clip(float(p["bead_depth"]), 0.0005, 0.2 * R))
    prof = [(R, 0.0)]
    for i in range(n):
        zc = h * (i + 1) / (n + 1)
        w = min(1.5 * g, 0.25 * h / (n + 1))
        prof += [(R, zc - w), (R - g, zc), (R, zc + w)]
    prof.append((R, h))
    parts = revolve_solid(prof)
    s = max(float(p["seam"]), 0.0005)
    hs = min(0.004, 0.1 * h)
    parts += [cylinder(R + s, 0.0, hs), cylinder(R + s, h - hs, h)]
    flip = axis_angle([1.0, 0.0, 0.0], np.pi)
    return Assembly(parts, continuous_symmetry(offset=(0.0, 0.0, h / 2), flips=[flip]))
