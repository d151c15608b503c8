"""Box: a closed block (a package), a box with an overhanging lid, or an open tray.

Width runs along x, depth along y (never longer than the width), height along z. The
footprint is either exactly square or at least 1.25 times as wide as deep, and a flat box
is at most 0.85 times as high as deep while a tall one is at least 1.15 times as high as
wide, so no two dimensions are nearly equal: the symmetry group follows from the
parameters alone. A plain closed block has the 180-degree turns about x, y and z (and the
quarter turns of a square footprint, with the flips about its diagonals); a lid, an open
top or feet keep only the turns about z. A bar handle lies along x, so it is only fitted
to an oblong box (which has only the half turn anyway); a square box gets a knob instead.
The lid overhangs by a fraction of the depth so that a lidded box is clearly not the same
upside down. Vertical edges may be chamfered, by at most a quarter of the half-depth so
that a square box stays far from a regular octagon. A box is picked across its depth or
height (a closed block is scaled down until one of them is at most 7 cm), by its lid's
edge or by an open tray's wall.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.geometry import axis_angle, cyclic_z, discrete_symmetry
from beo_bench.objects.params import Choice, Flag, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, cylinder, hull
from beo_bench.objects.registry import register_category


def _block(a: float, b: float, z0: float, z1: float, c: float) -> trimesh.Trimesh:
    """A box of half-sizes (a, b) from z0 to z1, its vertical edges chamfered by c."""
    if c < 5e-4:
        return box((2 * a, 2 * b, z1 - z0), (0.0, 0.0, (z0 + z1) / 2))
    xy = [(sx * a, sy * (b - c)) for sx in (-1, 1) for sy in (-1, 1)]
    xy += [(sx * (a - c), sy * b) for sx in (-1, 1) for sy in (-1, 1)]
    return hull([(x, y, z) for x, y in xy for z in (z0, z1)])


@register_category(
    "box",
    params={
        "style": Choice(("closed", "lidded", "open")),
        "width": Uniform(0.06, 0.16),
        "square": Flag(0.3),
        "aspect": Uniform(1.25, 2.0),  # width / depth unless square
        "tall": Flag(0.2),
        "height": Uniform(0.3, 0.8, ood=(0.2, 0.85)),  # flat: height / depth
        "chamfer": Uniform(0.0, 0.25),  # / half-depth (closed and lidded)
        "lid_height": Uniform(0.25, 0.45, ood=(0.2, 0.5)),  # / height
        "overhang": Uniform(0.05, 0.1, ood=(0.04, 0.12)),  # lid overhang / depth
        "wall": Uniform(0.003, 0.008),  # open tray
        "feet": Flag(0.3),
        "foot_size": Uniform(0.006, 0.014),
        "handle": Choice(("none", "knob", "bar"), p=(0.4, 0.35, 0.25)),  # on a lid
    },
)
def build(p: Params) -> Assembly:
    """Box (13 parameters: closed, lidded or open; width, square footprint, aspect, tall,
    height; edge chamfer; lid height and overhang; tray wall; feet presence and size; a
    knob or bar handle on the lid)."""
    w = float(p["width"])
    if p["tall"]:
        w *= 0.75  # a tall box (a tea box) is narrower than a flat one
    square = bool(p["square"])
    d = w if square else w / max(float(p["aspect"]), 1.05)
    ratio = float(np.clip(float(p["height"]), 0.2, 0.85))
    # flat: at most 0.85 times the depth; tall: at least 1.15 times the width
    h = w * (2.0 - ratio) if p["tall"] else ratio * d
    style = str(p["style"])
    if style == "closed":
        # a plain block offers nothing but its faces to pinch: scale it (keeping its
        # proportions, hence its symmetry) so its depth or height is at most 7 cm
        s = min(1.0, 0.07 / min(d, h))
        w, d, h = w * s, d * s, h * s
    a, b = w / 2, d / 2
    c = float(np.clip(float(p["chamfer"]), 0.0, 0.25)) * b if style != "open" else 0.0

    parts = []
    zf = 0.0
    if p["feet"]:
        # four round feet under the corners, reaching into the bottom
        fs = float(np.clip(float(p["foot_size"]), 0.003, 0.4 * b))
        zf = 0.8 * fs
        for sx in (-1, 1):
            for sy in (-1, 1):
                ctr = (sx * (a - c / 2 - fs), sy * (b - c / 2 - fs))
                parts.append(cylinder(0.6 * fs, 0.0, zf + 0.001, sections=16, center=ctr))
    top = zf + h

    # the symmetry group: the turns about z that the footprint allows ...
    turns_z = cyclic_z(4 if square else 2)
    if style == "open":
        t = float(np.clip(float(p["wall"]), 0.0015, 0.25 * b))
        parts.append(box((w, d, t), (0.0, 0.0, zf + t / 2)))  # floor
        for s in (-1, 1):
            parts.append(box((w, t, h), (0.0, s * (b - t / 2), zf + h / 2)))
            parts.append(box((t, d, h), (s * (a - t / 2), 0.0, zf + h / 2)))
        return Assembly(parts, turns_z)

    parts.append(_block(a, b, zf, top, c))
    if style == "closed":
        if p["feet"]:
            return Assembly(parts, turns_z)
        # ... and for a plain block also the flips, about the block's centre
        quarter = axis_angle([0, 0, 1], np.pi / 2 if square else np.pi)
        flip = axis_angle([1, 0, 0], np.pi)
        return Assembly(parts, discrete_symmetry([quarter, flip], offset=(0.0, 0.0, h / 2)))

    # a lid: a slab over the top of the body, overhanging it all round
    # with the overhang a fraction of the depth, the overhanging rim is at least ~3 % of
    # the volume, so the box is clearly not the same upside down (IoU < 0.94)
    o = float(np.clip(float(p["overhang"]), 0.02, 0.2)) * d
    hl = float(np.clip(float(p["lid_height"]), 0.15, 0.6)) * h
    parts.append(_block(a + o, b + o, top - hl, top, c))
    handle = str(p["handle"])
    if handle == "knob" or (handle == "bar" and square):
        # (a bar would make a square box only nearly symmetric under the quarter turns)
        rk = 0.12 * min(w, d)
        parts.append(cylinder(rk * 0.8, top - 0.001, top + 0.6 * rk, sections=24))
        parts.append(cylinder(rk, top + 0.6 * rk, top + 1.1 * rk, sections=24))
    elif handle == "bar":
        # a bar along x on two posts, far enough above the lid for fingers
        L, rb = 0.5 * w, 0.004
        hb = 0.018
        for s in (-1, 1):
            parts.append(box((2 * rb, 2 * rb, hb + 0.001), (s * L / 2, 0.0, top + hb / 2)))
        parts.append(box((L + 2 * rb, 2 * rb, 2 * rb), (0.0, 0.0, top + hb)))
    return Assembly(parts, turns_z)
