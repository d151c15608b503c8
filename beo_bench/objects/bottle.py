"""Bottle: a solid of revolution (or a square-bodied one) narrowing through a shoulder to a
neck, optionally with a support collar on the neck and a cap.

The profile, bottom to top: a bevelled foot, a straight body (optionally pinched in at a
waist, like a soda bottle), a shoulder blending from a straight cone to a rounded quarter
ellipse, and a cylindrical neck. A square-bodied bottle (a whisky or sauce bottle) uses
rounded-square cross-sections whose corners round off through the shoulder into the round
neck. Every profile segment is one convex hull of its two end sections, so the solid is
exact and has a dozen parts. Bottles are closed solids (as ShapeNet's); one is picked by
its body (at most 8 cm across) or its neck.
"""

from __future__ import annotations

import itertools

import numpy as np

from beo_bench.geometry import continuous_symmetry, cyclic_z
from beo_bench.objects.params import Flag, Params, Uniform
from beo_bench.objects.primitives import Assembly, cylinder, frustum, hull
from beo_bench.objects.registry import register_category


def _section(r: float, z: float, corner: float) -> np.ndarray:
    """A rounded square of half-width r whose corner radius is ``corner`` * r (1 = a
    circle), as points at height z."""
    rho = float(np.clip(corner, 0.0, 1.0)) * r
    pts = []
    for k, (cx, cy) in enumerate(((1, 1), (-1, 1), (-1, -1), (1, -1))):
        # the corner arc's centre, then its quarter arc
        a = np.linspace(k * np.pi / 2, (k + 1) * np.pi / 2, 7)
        x0, y0 = cx * (r - rho), cy * (r - rho)
        pts += [[x0 + rho * np.cos(t), y0 + rho * np.sin(t), z] for t in a]
    return np.array(pts)


@register_category(
    "bottle",
    params={
        "height": Uniform(0.15, 0.3),  # bottom to the top of the neck
        "radius": Uniform(0.025, 0.04),  # body radius (half-width if square)
        "body": Uniform(0.4, 0.7),  # straight body height / height
        "neck": Uniform(0.1, 0.3),  # neck length / height
        "neck_radius": Uniform(0.28, 0.55),  # / body radius
        "shoulder": Uniform(0.0, 1.0),  # 0 = conical, 1 = rounded
        "bevel": Uniform(0.03, 0.12),  # foot bevel / radius
        "waist": Flag(0.35),  # a pinch in the middle of the body
        "waist_depth": Uniform(0.04, 0.14),  # / radius
        "square": Flag(0.25),
        "corner": Uniform(0.15, 0.4),  # corner radius / half-width of a square body
        "collar": Flag(0.35),
        "cap": Flag(0.7),
        "cap_height": Uniform(0.01, 0.03),
        "cap_radius": Uniform(1.05, 1.35),  # / neck radius
    },
    shapenet_synsets=("02876657",),
    modelnet_names=("bottle",),
)
def build(p: Params) -> Assembly:
    """Bottle (15 parameters: height, body radius and height, neck length and radius,
    shoulder roundness, foot bevel; waist presence and depth; square body and its corner
    rounding; collar presence; cap presence, height and radius)."""
    h, R = float(p["height"]), float(p["radius"])
    rn = float(np.clip(float(p["neck_radius"]), 0.15, 0.8)) * R
    rn = max(rn, 0.006)  # a neck a finger can still close on, and a cap can sit on
    neck = float(np.clip(float(p["neck"]), 0.05, 0.4)) * h
    z_body = float(np.clip(float(p["body"]), 0.25, 0.8)) * h
    z_body = min(z_body, h - neck - 0.01)  # leave a shoulder of at least 1 cm
    z_neck = h - neck
    bevel = float(np.clip(float(p["bevel"]), 0.0, 0.3)) * R
    waist = float(np.clip(float(p["waist_depth"]), 0.0, 0.3)) if p["waist"] else 0.0
    e = float(np.clip(float(p["shoulder"]), 0.0, 1.0))
    square = bool(p["square"])
    c0 = float(np.clip(float(p["corner"]), 0.05, 0.7)) if square else 1.0

    # the profile as (radius, z, corner rounding) from the foot to the top of the neck
    prof = [(R - bevel, 0.0, c0), (R, 1.5 * bevel, c0)]
    if waist > 0.0:
        # a smooth pinch centred on the body, over its middle half
        zb0, zb1 = 1.5 * bevel, z_body
        for s, d in ((0.25, 0.0), (0.4, 0.7), (0.5, 1.0), (0.6, 0.7), (0.75, 0.0)):
            prof.append((R * (1 - waist * d), zb0 + s * (zb1 - zb0), c0))
    prof.append((R, z_body, c0))
    for s in (0.25, 0.5, 0.75, 1.0):
        # blend a straight cone with a quarter ellipse; corners round off towards the neck
        r = rn + (R - rn) * ((1 - e) * (1 - s) + e * np.sqrt(1 - s**2))
        prof.append((r, z_body + s * (z_neck - z_body), c0 + (1 - c0) * s))
    prof.append((rn, h, 1.0))

    parts = []
    for (r0, z0, k0), (r1, z1, k1) in itertools.pairwise(prof):
        if k0 >= 1.0 and k1 >= 1.0:
            parts.append(frustum(r0, r1, z0, z1))
        else:
            parts.append(hull(np.concatenate([_section(r0, z0, k0), _section(r1, z1, k1)])))

    if p["collar"]:
        # the support ring of a PET bottle, a third of the way up the neck
        zc = z_neck + 0.35 * neck
        parts.append(cylinder(rn + max(0.15 * rn, 0.002), zc - 0.0015, zc + 0.0015))
    if p["cap"]:
        hc = float(np.clip(float(p["cap_height"]), 0.005, 0.6 * neck))
        rc = float(np.clip(float(p["cap_radius"]), 1.0, 1.6)) * rn
        # the cap sleeves the top of the neck and stands a little proud of it
        parts.append(frustum(rc, rc * 0.97, h - 0.7 * hc, h + 0.3 * hc))
    return Assembly(parts, cyclic_z(4) if square else continuous_symmetry())
