"""Sofa: a long upholstered base with seat cushions, a back along the rear, 0-2 arms.

The sofa faces +x and is long along y: the back rises from the rear (-x) edge, tilted
backwards, and the arms close the ends (+y first: a one-armed sofa has its arm on +y).
The base stands on short legs or directly on the floor (a plinth). Seat cushions (and
optionally back cushions) are separate slabs with rounded top edges and small gaps between
them. A one-seat sofa is close to an armchair (classes overlap in parts, as in ShapeNet).
The sofa is picked by an arm or by the back. A sofa has no rotational symmetry (the back
is on one side only; with one arm it is not even mirror-symmetric).
"""

from __future__ import annotations

import numpy as np

from beo_bench.geometry import axis_angle, no_symmetry
from beo_bench.objects.params import Choice, Flag, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, frustum, hull
from beo_bench.objects.registry import register_category


def _cushion(
    x0: float,
    x1: float,
    y0: float,
    y1: float,
    z0: float,
    z1: float,
    round_: float,
    round_x0: bool = True,
) -> np.ndarray:
    """Corners of a slab whose top face is inset by ``round_`` (a rounded, padded look),
    except along the x0 edge when ``round_x0`` is False (an edge pressed against the back:
    a groove there could close into a hidden cavity under a back cushion)."""
    r = min(round_, 0.3 * (x1 - x0), 0.3 * (y1 - y0), 0.5 * (z1 - z0))
    pts = [[x, y, z0] for x in (x0, x1) for y in (y0, y1)]
    pts += [[x, y, z1 - r] for x in (x0, x1) for y in (y0, y1)]
    pts += [[x, y, z1] for x in (x0 + (r if round_x0 else 0.0), x1 - r) for y in (y0 + r, y1 - r)]
    return np.array(pts)


@register_category(
    "sofa",
    params={
        "length": Uniform(0.10, 0.16),  # y, arms included
        "seat_depth": Uniform(0.04, 0.065),  # x, in front of the back
        "base_height": Uniform(0.018, 0.03),  # upholstered base under the cushions
        "cushion_thickness": Uniform(0.005, 0.012),
        "back_height": Uniform(0.025, 0.05),  # above the seat
        "back_thickness": Uniform(0.01, 0.02),
        "back_tilt": Uniform(0.0, 0.25),  # radians, leaning backwards
        "arms": Choice(("none", "one", "two"), p=(0.15, 0.2, 0.65)),
        "arm_height": Uniform(0.008, 0.03),  # above the seat
        "arm_width": Uniform(0.008, 0.02),
        "arm_style": Choice(("square", "rolled")),
        "legs": Flag(0.6),
        "leg_height": Uniform(0.004, 0.012),
        "cushions": Integer(1, 3),
        "back_cushions": Flag(0.4),
    },
    shapenet_synsets=("04256520",),
    modelnet_names=("sofa",),
)
def build(p: Params) -> Assembly:
    """Sofa (15 parameters: length, seat depth, base height, cushion thickness; back
    height, thickness, tilt; arm count, height, width, style; legs and their height;
    seat cushion count; back cushions)."""
    L, sd = float(p["length"]), float(p["seat_depth"])
    bt = float(p["back_thickness"])
    bh = float(np.clip(float(p["back_height"]), 0.012, None))
    tilt = float(p["back_tilt"])
    ct = float(np.clip(float(p["cushion_thickness"]), 0.003, None))
    n_arms = {"none": 0, "one": 1, "two": 2}[str(p["arms"])]
    aw = float(np.clip(float(p["arm_width"]), 0.005, 0.2 * L))
    lh = float(p["leg_height"]) if p["legs"] else 0.0
    z0 = lh  # underside of the base
    z_base = z0 + float(np.clip(float(p["base_height"]), 0.008, None))
    z_seat = z_base + ct
    D = bt + sd  # total depth; the rear of the back's foot is at x = 0

    parts = [box((D, L, z_base - z0), center=(D / 2, 0.0, (z0 + z_base) / 2))]

    # --- back: a tilted slab in its own frame (v up along the back) pivoting on the base's
    # rear top edge, reaching down into the base so that it is fused to it
    R = axis_angle([0.0, 1.0, 0.0], -tilt)  # rotating about y by -tilt leans the top to -x
    top_v = z_seat - z_base + bh
    v_in = -0.5 * (z_base - z0)
    c = np.array([bt / 2, 0.0, z_base]) + R @ np.array([0.0, 0.0, (v_in + top_v) / 2])
    parts.append(box((bt, L, top_v - v_in), center=c, rotation=R))

    # --- arms at the ends: +y first
    sides = [1.0, -1.0][:n_arms]
    ah = float(np.clip(float(p["arm_height"]), 0.004, 0.9 * bh))
    z_arm = z_seat + ah
    for s in sides:
        yc = s * (L / 2 - aw / 2)
        if p["arm_style"] == "rolled":
            # a lower block under a round roll that overhangs outwards; the roll's axis is
            # along x (a hull of two rings)
            rr = 0.6 * aw
            zc = z_arm - rr
            parts.append(box((D, aw, zc - z0), center=(D / 2, yc, (z0 + zc) / 2)))
            a = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
            ring = np.stack(
                [np.zeros_like(a), yc + s * 0.15 * aw + rr * np.cos(a), zc + rr * np.sin(a)], axis=1
            )
            x_rear = bt / 2
            parts.append(
                hull(
                    np.concatenate(
                        [
                            ring + np.array([x_rear, 0.0, 0.0]),
                            ring + np.array([D + 0.1 * rr, 0.0, 0.0]),
                        ]
                    )
                )
            )
        else:
            parts.append(
                box((D + 0.002, aw, z_arm - z0), center=(D / 2 + 0.001, yc, (z0 + z_arm) / 2))
            )

    # --- seat cushions between the arms, with small gaps; they sink into the base a bit
    # and into the arms (no coplanar contact faces), or stop 1 mm short of an armless end
    y_lo = -L / 2 + (aw - 0.0005 if n_arms == 2 else 0.001)
    y_hi = L / 2 - (aw - 0.0005 if n_arms >= 1 else 0.001)
    n = int(p["cushions"])
    gap = 0.0015
    cw = (y_hi - y_lo - (n - 1) * gap) / n
    rnd = 0.3 * ct
    # the cushions' rear face goes into the back at every height up to the seat (the
    # tilted back's front face leans back as it rises), leaving no groove behind them
    v_seat = (ct - bt / 2 * np.sin(tilt)) / np.cos(tilt)
    x0 = min(bt, bt / 2 + bt / 2 * np.cos(tilt) - v_seat * np.sin(tilt)) - 0.001
    for k in range(n):
        y0 = y_lo + k * (cw + gap)
        parts.append(
            hull(_cushion(x0, D + 0.001, y0, y0 + cw, z_base - 0.001, z_seat, rnd, round_x0=False))
        )
        if p["back_cushions"]:
            # in the back's frame (u across its thickness, towards +x; v up along it):
            # from inside the back to cbt in front of it, padded on the front face, and
            # reaching down to the seat cushion's top
            cbt = 0.6 * bt
            v0 = ct - (bt / 2 + cbt) * np.sin(tilt) - 0.001
            pts = _cushion(v0, ct + 0.85 * bh, y0, y0 + cw, bt / 2 - 0.002, bt / 2 + cbt, 0.3 * cbt)
            local = pts[:, [2, 1, 0]]  # (v, y, u) -> (u, y, v)
            parts.append(hull(np.array([bt / 2, 0.0, z_base]) + local @ R.T))

    # --- legs: short posts under the base's corners, tapering towards the floor and
    # reaching into the base
    if p["legs"]:
        lr = float(np.clip(0.05 * D, 0.002, 0.005))
        m = 1.5 * lr
        for x in (m, D - m):
            for y in (-L / 2 + m, L / 2 - m):
                parts.append(frustum(0.7 * lr, lr, 0.0, lh + 0.002, sections=12, center=(x, y)))

    return Assembly(parts, no_symmetry())
