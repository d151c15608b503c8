"""Bowl: a curved wall of revolution on a solid floor, with an optional foot.

The outer profile follows r(z) = r_base + (R - r_base) (z / H)^k: k < 1 gives the rounded
belly of a soup bowl, k = 1 a conical salad bowl; a flare bends the top outwards. The
lowest stretch of the profile is a solid floor (a flat stretch of wall thickened
horizontally, as the shell primitive does, would be paper thin); above it the wall is one
ring of 32 convex sectors, each the hull of the whole wall cross-section: the outer profile
points, and inner points offset along the normal by the wall thickness, which grows or
shrinks towards the rim. On a rounded profile the hull keeps the curved outside and makes
the inside a straight chord, so the wall is thickest at mid-height as on a thrown bowl; one
ring instead of one per profile segment halves the part count and the union time. (For the
same reason there is no protruding rim lip: the hull would run the outside straight from
the floor to the lip.)

Each sector's outside follows the circle (three angles per sector) so that only the inner
chords facet the wall: a bowl has twice a mug's radius, and a plain 32-sector shell of bowl
size with a 3 mm wall keeps only IoU 0.88 under a rotation about its axis; with the outside
curved and the wall at least 4.5 % of the radius it stays above 0.95, so the bowl is
declared continuously symmetric. A foot is a short solid pedestal under the floor. The bowl
is picked by its rim, one finger inside.
"""

from __future__ import annotations

import numpy as np

from beo_bench.geometry import continuous_symmetry
from beo_bench.objects.params import Flag, Params, Uniform
from beo_bench.objects.primitives import Assembly, frustum, hull
from beo_bench.objects.registry import register_category

_SECTORS = 32
# neighbouring sectors overlap by this angle, as in primitives.revolve_shell
_OVERLAP = 1e-3
# heights of the outer profile points along the wall (fractions of the wall's height)
_KNOTS = (0.0, 0.12, 0.3, 0.55, 0.8, 1.0)


@register_category(
    "bowl",
    params={
        "radius": Uniform(0.05, 0.09),  # outer rim radius before the flare
        "depth": Uniform(0.5, 1.0),  # height / radius
        "base": Uniform(0.35, 0.6),  # base radius / rim radius
        "roundness": Uniform(0.45, 1.0),  # profile exponent k: small = round belly
        "flare": Uniform(0.0, 0.12),  # extra outward flare at the rim / radius
        "wall": Uniform(0.045, 0.075, ood=(0.04, 0.09)),  # wall thickness / radius
        "floor": Uniform(0.004, 0.01),  # floor thickness
        "foot": Flag(0.5),
        "foot_height": Uniform(0.004, 0.012),
        "foot_radius": Uniform(0.6, 0.95),  # foot radius / base radius
        "rim": Uniform(0.8, 1.8),  # wall thickness at the rim / at the floor
    },
    shapenet_synsets=("02880940",),
    modelnet_names=("bowl",),
)
def build(p: Params) -> Assembly:
    """Bowl (11 parameters: rim radius, depth, base width, roundness, flare, wall, rim and
    floor thickness; foot presence, height and width)."""
    R = float(p["radius"])
    H = float(p["depth"]) * R
    rb = float(np.clip(float(p["base"]), 0.15, 0.8)) * R
    k = max(float(p["roundness"]), 0.1)
    flare = max(float(p["flare"]), 0.0) * R
    wall = float(p["wall"]) * R
    # the floor must leave a cavity: at most 30 % of the height
    f = float(np.clip(float(p["floor"]), 0.002, 0.3 * H))
    z0 = float(p["foot_height"]) if p["foot"] else 0.0

    def r_of(z: float) -> float:  # outer radius at height z above the bottom of the bowl
        return rb + (R - rb) * (z / H) ** k + flare * max((z - f) / (H - f), 0.0) ** 2

    parts = [frustum(rb, r_of(f), z0, z0 + f)]
    if p["foot"]:
        rf = float(np.clip(float(p["foot_radius"]), 0.3, 1.0)) * rb
        # slightly tapered, and reaching into the floor so the two overlap
        parts.append(frustum(rf * 0.92, rf, 0.0, z0 + 0.5 * f))

    zs = [f + (H - f) * s for s in _KNOTS]
    outer = [(r_of(z), z) for z in zs]
    rim = max(float(p["rim"]), 0.5)
    inner = []
    for i, (r, z) in enumerate(outer):
        # offset inwards so the wall is ``wall`` thick along the normal of the adjacent
        # segment (``rim`` times that at the top); capped where the profile is nearly flat
        # and so that the cavity stays open
        (ra, za), (rc, zc) = outer[max(i - 1, 0)], outer[min(i + 1, len(outer) - 1)]
        sin = (zc - za) / np.hypot(rc - ra, zc - za)
        t = wall * (1.0 + (rim - 1.0) * _KNOTS[i])
        inner.append((r - min(t / max(sin, 0.25), 0.5 * r), z))

    # one ring of sectors: the outer points at three angles across the sector (a convex
    # outside following the circle), the inner ones at its two bounding angles
    step = 2 * np.pi / _SECTORS
    for j in range(_SECTORS):
        a0, a1 = j * step - _OVERLAP, (j + 1) * step + _OVERLAP
        pts = [
            [r * np.cos(a), r * np.sin(a), z0 + z] for a in np.linspace(a0, a1, 3) for r, z in outer
        ]
        pts += [[r * np.cos(a), r * np.sin(a), z0 + z] for a in (a0, a1) for r, z in inner]
        parts.append(hull(pts))
    return Assembly(parts, continuous_symmetry())
