"""Lamp: a small desk lamp, a heavy base carrying a pole or an arm, with a shade (a thin
shell opening downwards, closed at the top by a cap) and optionally a bulb inside it.

Three layouts: a straight lamp has its pole up the middle of the base into the shade's cap,
all coaxial (a round base makes it continuously symmetric about z, a square one 4-fold);
an angled lamp leans its lower arm back from the rear of the base to an elbow, from which
the upper arm runs forwards (+x) and down to the shade, tilted to face the front; a hook
lamp has a vertical pole at the rear and a horizontal arm from which the shade hangs. The
last two have no symmetry; their shade, arm and offset pole are a large enough share of
the volume that no turn about z comes close to mapping them onto themselves, even though
the base alone would. Toy / tabletop size; picked by the pole or the arm.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.geometry import axis_angle, continuous_symmetry, cyclic_z, no_symmetry, rigid
from beo_bench.objects.params import Choice, Flag, Params, Uniform
from beo_bench.objects.primitives import (
    Assembly,
    box,
    cylinder,
    ellipsoid,
    frustum,
    hull,
    tube,
)
from beo_bench.objects.registry import register_category

_SECTORS = 32
_OVERLAP = 1e-3  # neighbouring sectors overlap by this angle, as in revolve_shell


def _shade_wall(r0: float, r1: float, h: float, t: float) -> list[trimesh.Trimesh]:
    """The shade's wall from radius r0 at z = -h to r1 at z = 0, thickened inwards by t:
    revolve_shell's 32 sectors, with two changes. Each sector's outside follows the circle
    (three angles per sector), so only the inner chords facet the wall and a turn about
    the axis keeps volume IoU above 0.95 for a wall 4 % of the radius (revolve_shell's
    circumscribed outside needs twice that). And every other sector is lengthened by
    0.1 mm along the same cone: neighbouring sectors overlap in coplanar end faces, and
    once the shade is tilted (and rounded to float32 by the boolean engine) nearly
    coplanar faces can leave a degenerate sliver in the union."""
    step = 2 * np.pi / _SECTORS
    slope = (r0 - r1) / h
    parts = []
    for k in range(_SECTORS):
        e = 1e-4 * (k % 2)
        prof = ((r0 + slope * e, -h - e), (r1 - slope * e, e))
        a0, a1 = k * step - _OVERLAP, (k + 1) * step + _OVERLAP
        pts = [[r * np.cos(a), r * np.sin(a), z] for a in np.linspace(a0, a1, 3) for r, z in prof]
        pts += [[(r - t) * np.cos(a), (r - t) * np.sin(a), z] for a in (a0, a1) for r, z in prof]
        parts.append(hull(pts))
    return parts


@register_category(
    "lamp",
    params={
        "base_shape": Choice(("round", "square")),
        "base_radius": Uniform(0.045, 0.075),  # half-width if square
        "base_height": Uniform(0.01, 0.025),
        "height": Uniform(0.2, 0.34),  # top of the pole or arm
        "pole_radius": Uniform(0.004, 0.008),
        "arm": Choice(("straight", "angled", "hook"), p=(0.4, 0.35, 0.25)),
        "reach": Uniform(0.08, 0.14),  # horizontal reach of the arm from the pole
        "lean": Uniform(0.0, 0.3),  # angled: backward lean of the lower arm (rad)
        "drop": Uniform(0.05, 0.25),  # angled: fall of the upper arm / height
        "tilt": Uniform(0.1, 0.6),  # angled and hook: forward tilt of the shade (rad)
        "shade": Choice(("cone", "cylinder")),
        "shade_radius": Uniform(0.04, 0.075),  # at the opening
        "shade_height": Uniform(0.05, 0.1),
        "shade_top": Uniform(0.35, 0.7),  # cone: top radius / opening radius
        "shade_wall": Uniform(0.04, 0.06, ood=(0.035, 0.07)),  # / opening radius
        "bulb": Flag(0.5),
    },
    shapenet_synsets=("03636649",),
    modelnet_names=("lamp",),
)
def build(p: Params) -> Assembly:
    """Lamp (16 parameters: base shape, size and thickness; height, pole thickness; arm
    layout, reach, lean and drop; shade tilt, shape, radius, height, taper and wall; bulb
    presence)."""
    rb = float(p["base_radius"])
    bh = float(np.clip(float(p["base_height"]), 0.005, 0.05))
    H = float(p["height"])
    rp = float(np.clip(float(p["pole_radius"]), 0.003, 0.012))
    Rs = float(p["shade_radius"])
    Hs = float(np.clip(float(p["shade_height"]), 0.03, 0.6 * H))
    Rt = Rs * float(np.clip(float(p["shade_top"]), 0.2, 0.9)) if p["shade"] == "cone" else Rs
    t = float(np.clip(float(p["shade_wall"]), 0.02, 0.1)) * Rs
    square = p["base_shape"] == "square"
    arm = str(p["arm"])

    if square:
        parts = [box((2 * rb, 2 * rb, bh), (0.0, 0.0, bh / 2))]
    else:
        parts = [frustum(rb, 0.93 * rb, 0.0, bh)]  # a bevelled disc

    # the shade in its own frame: the top of its cap at the origin, opening towards -z
    tc = max(1.5 * t, 0.003)
    shade = _shade_wall(Rs, Rt, Hs, t)
    # the cap closing the top stands a little proud of the wall, for the same reason
    shade.append(frustum(Rt - 0.5 * t, Rt - 0.5 * t, -tc, 0.5 * t))
    if p["bulb"]:
        rbulb = min(0.45 * Rt, 0.03, 0.35 * Hs)
        shade.append(cylinder(0.5 * rbulb, -tc - 0.3 * rbulb, -0.5 * tc, sections=24))
        shade.append(ellipsoid((0.0, 0.0, -tc - 1.2 * rbulb), (rbulb, rbulb, 1.3 * rbulb)))

    if arm == "straight":
        # the pole runs up the axis through the shade to its cap
        parts.append(cylinder(rp, bh - 0.002, H - 0.5 * tc, sections=24))
        parts += [s.apply_translation((0.0, 0.0, H)) for s in shade]
        return Assembly(parts, cyclic_z(4) if square else continuous_symmetry())

    x0 = -0.55 * rb  # the pole stands at the rear of the base
    reach = float(p["reach"])
    tilt = float(np.clip(float(p["tilt"]), 0.0, 0.9))
    if arm == "angled":
        lean = float(np.clip(float(p["lean"]), 0.0, 0.5))
        drop = float(np.clip(float(p["drop"]), 0.0, 0.4)) * H
        elbow = np.array([x0 - (H - bh) * np.tan(lean), 0.0, H])
        top = np.array([x0 + reach, 0.0, H - drop])
        path = [[x0, 0.0, bh - 0.002], elbow, top]
    else:  # hook: up, forwards, and a short stem down to the shade
        top = np.array([x0 + reach, 0.0, H - 0.02])
        path = [[x0, 0.0, bh - 0.002], [x0, 0.0, H], [x0 + reach, 0.0, H], top]
    parts += tube(np.asarray(path, dtype=np.float64), rp, sections=16)
    # tilt the shade forwards about y (its opening turns towards +x) and hang it from the
    # end of the arm, the arm's end sunk into the cap
    T = rigid(axis_angle([0.0, 1.0, 0.0], -tilt), top + np.array([0.0, 0.0, 0.5 * tc - 0.5 * t]))
    parts += [s.apply_transform(T) for s in shade]
    return Assembly(parts, no_symmetry())
