"""Car: a lower body hull, a greenhouse (cabin) hull on it, and four wheels.

The nose points to +x. The lower body is the convex hull of a side profile (a bumper at
each end, the hood sloping down to the nose, the trunk deck sloping down to the tail)
extruded across the width; the cabin is a hull from its base on the beltline to a
narrower, shorter roof, raked at the windshield and the rear window. The rear style places
the cabin: a sedan has a separate trunk, a hatchback's roof slopes down to the tail, an
SUV's box cabin runs to the tail, and a pickup has a short cab and an open bed behind it.
A wheel is a short cylinder along y, half inside the body (a toy car without wheel
arches). Close to a box with low cabins (classes overlap in parts, as in ShapeNet).

The body is at most 7 cm wide, so the car is picked across it. A car has no rotational
symmetry; the hood is always longer than the rear overhang behind the cabin of a sedan,
the nose lower than the tail and the cabin set back, so that the car turned by 180 degrees
about z is visibly different (volume IoU well below 0.95).
"""

from __future__ import annotations

import numpy as np

from beo_bench.geometry import no_symmetry
from beo_bench.objects.params import Choice, Flag, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, hull
from beo_bench.objects.registry import register_category

_MAX_WIDTH = 0.07  # the body fits an 8 cm gripper


def _profile(xz: list[tuple[float, float]], half_width: float) -> np.ndarray:
    """A side profile (x, z) extruded across +-half_width (the hull is taken later)."""
    return np.array([[x, s * half_width, z] for x, z in xz for s in (-1.0, 1.0)])


def _wheel(x: float, y0: float, y1: float, r: float, z: float, sections: int = 20) -> np.ndarray:
    """Points of a wheel: two rings in xz-planes at y0 and y1, the tread's edges chamfered."""
    a = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    c = 0.12 * abs(y1 - y0)
    rings = []
    for y, rad in (
        (y0, r - c),
        (y0 + np.sign(y1 - y0) * c, r),
        (y1 - np.sign(y1 - y0) * c, r),
        (y1, r - c),
    ):
        rings.append(
            np.stack([x + rad * np.cos(a), np.full_like(a, y), z + rad * np.sin(a)], axis=1)
        )
    return np.concatenate(rings)


@register_category(
    "car",
    params={
        "length": Uniform(0.08, 0.15),
        "width": Uniform(0.38, 0.48),  # / length (clipped to 7 cm)
        "body_height": Uniform(0.13, 0.19),  # / length, from the sill to the beltline
        "clearance": Uniform(0.035, 0.06),  # / length, the sill above the floor
        "rear_style": Choice(("sedan", "hatchback", "suv", "pickup"), p=(0.35, 0.25, 0.25, 0.15)),
        "cabin_length": Uniform(0.38, 0.52),  # / length, at the beltline
        "cabin_position": Uniform(-0.12, -0.02),  # / length, cabin centre (rearwards < 0)
        "cabin_height": Uniform(0.1, 0.15),  # / length
        "windshield_rake": Uniform(0.3, 0.55),  # / cabin length, run of the windshield
        "rear_rake": Uniform(0.1, 0.35),  # / cabin length, run of the rear window
        "hood_drop": Uniform(0.2, 0.5),  # / body height, beltline to the nose top
        "trunk_drop": Uniform(0.0, 0.15),  # / body height, beltline to the tail top
        "wheel_radius": Uniform(0.085, 0.115),  # / length
        "wheel_width": Uniform(0.16, 0.26),  # / width
        "wheelbase": Uniform(0.56, 0.66),  # / length
        "spoiler": Flag(0.2),
    },
    shapenet_synsets=("02958343",),
    modelnet_names=("car",),
)
def build(p: Params) -> Assembly:
    """Car (16 parameters: body length, width, height, clearance; rear style; cabin
    length, position, height; windshield and rear window rake; hood and trunk drop; wheel
    radius, width; wheelbase; spoiler)."""
    L = float(p["length"])
    W = float(np.clip(float(p["width"]) * L, 0.02, _MAX_WIDTH))
    style = str(p["rear_style"])
    rw = float(np.clip(float(p["wheel_radius"]), 0.06, 0.15)) * L
    # the sill sits below the wheel tops so that wheels and body overlap well
    clr = float(np.clip(float(p["clearance"]) * L, 0.3 * rw, 1.3 * rw))
    bh = float(np.clip(float(p["body_height"]), 0.09, 0.25)) * L
    if style == "suv":
        bh *= 1.12
    # the beltline and the nose stay above the wheel tops (no wheel pokes through a fender)
    z_belt = max(clr + bh, 2.3 * rw)
    z_nose = max(z_belt - float(np.clip(float(p["hood_drop"]), 0.1, 0.7)) * bh, 2.05 * rw)
    z_tail = z_belt - float(np.clip(float(p["trunk_drop"]), 0.0, 0.3)) * bh
    ch = float(np.clip(float(p["cabin_height"]), 0.06, 0.2)) * L
    lc = float(np.clip(float(p["cabin_length"]), 0.25, 0.6)) * L
    ws_run = float(np.clip(float(p["windshield_rake"]), 0.15, 0.7)) * lc
    rear_run = float(np.clip(float(p["rear_rake"]), 0.03, 0.5)) * lc
    hood_min = 0.2 * L  # the nose is always well ahead of the cabin

    # --- cabin placement by rear style: x_r, x_f are the cabin's base ends on the beltline
    if style == "sedan":
        # set back by at least 4% of the length: a centred cabin would make a sedan nearly
        # 2-fold symmetric about z
        xc = float(np.clip(float(p["cabin_position"]), -0.2, -0.04)) * L
        x_f = min(xc + lc / 2, L / 2 - hood_min)
        # leave a trunk, shorter than the hood (another asymmetry of front and rear)
        x_r = float(np.clip(x_f - lc, -L / 2 + 0.14 * L, -L / 2 + 0.7 * (L / 2 - x_f)))
    elif style == "hatchback":
        x_r = -L / 2 + 0.02 * L
        x_f = min(x_r + 1.2 * lc, L / 2 - hood_min)
        rear_run = max(rear_run, 0.3 * (x_f - x_r))  # the hatch slopes down to the tail
        z_tail = z_belt
    elif style == "suv":
        x_r = -L / 2 + 0.01 * L
        x_f = min(x_r + 1.3 * lc, L / 2 - hood_min)
        rear_run = 0.04 * (x_f - x_r)  # an upright tailgate
        ch *= 1.15
        z_tail = z_belt
    else:  # pickup: a short cab ahead of the middle, an open bed behind
        x_f = min(0.12 * L + 0.3 * lc, L / 2 - hood_min)
        x_r = x_f - 0.6 * lc
        rear_run = 0.06 * (x_f - x_r)
        ch *= 1.1
        z_tail = z_belt
    ws_run = min(ws_run, 0.45 * (x_f - x_r))
    rear_run = min(rear_run, 0.45 * (x_f - x_r))

    # --- lower body: the hull of its side profile (front bumper, hood, beltline under the
    # cabin, trunk deck, rear bumper), slightly narrower at the top (tumblehome)
    hw = W / 2
    lower = [
        (L / 2 - 0.03 * L, clr),
        (L / 2, clr + 0.35 * bh),
        (-L / 2, clr + 0.4 * bh),
        (-L / 2 + 0.02 * L, clr),
    ]
    upper = [(L / 2 - 0.04 * L, z_nose), (x_f, z_belt), (x_r, z_belt), (-L / 2 + 0.01 * L, z_tail)]
    parts = [hull(np.concatenate([_profile(lower, hw), _profile(upper, 0.94 * hw)]))]

    # --- cabin: base on (just below) the beltline, the roof narrower and shorter
    z_roof = z_belt + ch
    base = [(x_f, z_belt - 0.002), (x_r, z_belt - 0.002)]
    roof = [(x_f - ws_run, z_roof), (x_r + rear_run, z_roof)]
    parts.append(hull(np.concatenate([_profile(base, 0.9 * hw), _profile(roof, 0.72 * hw)])))

    if style == "pickup":
        # the bed: two side walls and a tailgate on the rear deck, overlapping the cab
        wall_h = 0.3 * ch
        wt = float(np.clip(0.07 * W, 0.002, 0.004))
        x0 = -L / 2 + 0.01 * L
        for s in (-1.0, 1.0):
            parts.append(
                box(
                    (x_r - x0 + 0.002, wt, wall_h + 0.002),
                    center=(
                        (x_r + x0) / 2 + 0.001,
                        s * (0.94 * hw - wt / 2),
                        z_belt + wall_h / 2 - 0.001,
                    ),
                )
            )
        parts.append(
            box(
                (wt, 1.88 * hw, wall_h + 0.002),
                center=(x0 + wt / 2, 0.0, z_belt + wall_h / 2 - 0.001),
            )
        )
    elif p["spoiler"]:
        # a wing on two struts at the tail (on the roof's rear edge of an SUV)
        if style == "suv":
            zs, xs = z_roof, x_r + rear_run + 0.04 * L
        else:
            zs, xs = z_tail, -L / 2 + 0.06 * L
        sh = 0.25 * ch
        for s in (-0.5, 0.5):
            parts.append(
                box((0.015 * L, 0.01 * L, sh + 0.003), center=(xs, s * hw, zs + sh / 2 - 0.0015))
            )
        parts.append(box((0.07 * L, 1.7 * hw, 0.012 * L), center=(xs - 0.01 * L, 0.0, zs + sh)))

    # --- wheels: the axles are centred on the car, the outer faces 1 mm out of the body
    # (not flush: coplanar faces leave slivers in a boolean union)
    wb = float(np.clip(float(p["wheelbase"]), 0.45, 0.75)) * L
    wb = min(wb, L - 2 * rw - 0.06 * L)  # wheels stay within the bumpers
    ww = float(np.clip(float(p["wheel_width"]), 0.1, 0.35)) * W
    for x in (-wb / 2, wb / 2):
        for s in (-1.0, 1.0):
            parts.append(hull(_wheel(x, s * (hw + 0.001), s * (hw - ww), rw, rw)))

    return Assembly(parts, no_symmetry())
