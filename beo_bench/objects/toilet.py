"""Toilet: a bowl with a seat ring, with a close-coupled tank, a cistern panel or a pipe.

The toilet faces +x: the bowl's front is at +x and the tank (or panel, or flush pipe)
stands behind it at -x; the width runs along y. The bowl's plan is an egg, wider at the
back, round or elongated (superellipse plans as in bathtub.py, whose wall and floor
helpers it shares); under the rim a thin wall narrows to the bowl's floor. A floor-standing
bowl sits on a tapered pedestal set towards the back, with a rear body sloping up to a
deck at rim height behind the seat; a wall-hung bowl has no pedestal, its rounded
underside and rear body cantilevered from a cistern panel (a flush plate with two buttons
on its front) that stands on the floor. Tanks: a close-coupled tank with a lid and a
button or lever stands on the deck; a cistern panel stands behind a wall-hung or a
back-to-wall bowl; a tankless bowl has a flush pipe rising from the deck. The seat ring
(closed or open at the front) lies on the rim, hinged at the back, with its lid down, up
(leaning back on the tank, panel or pipe) or missing. With the bowl open, each convex
sector of its wall also holds the seat above it (the bowl's inside then runs straight from
its floor up to the seat's hole), half the pieces of a separate ring; with the lid down
the bowl under it is filled solid, so that the seat and lid close no hidden cavity.

Every part is built in a real toilet's size (metres) and the whole is scaled to the drawn
largest extent, so that proportions stay real; thicknesses are set in the scaled size
(at least 2 mm). A toilet is picked by its tank or panel, or by the bowl's rim. It has no
rotational symmetry: the tank, panel or pipe, the rear body and the egg-shaped bowl are
all at one end.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.geometry import no_symmetry
from beo_bench.objects.bathtub import Plan, basin_floor, basin_wall, sector_angles, wall_sections
from beo_bench.objects.params import Choice, Flag, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, cylinder, hull, tube
from beo_bench.objects.registry import register_category

_SECTORS = 16


def _rings_hull(rings: list[tuple[Plan, float]], sectors: int = _SECTORS) -> trimesh.Trimesh:
    """The convex hull of outlines (plan, z): a solid bowl, pedestal or underside."""
    a = np.linspace(0.0, 2 * np.pi, sectors, endpoint=False)
    return hull(
        np.concatenate([np.column_stack([pl.points(a), np.full(sectors, z)]) for pl, z in rings])
    )


def _egg(ax: float, ay: float, n: float, egg: float, cx: float) -> Plan:
    """A plan long along x, centred at (cx, 0), wider towards -x: the bathtub's Plan (long
    along its y, wider at -y) turned by -90 degrees."""
    return Plan(ax, ay, n, egg, cx, 0.0, -np.pi / 2)


def _chamfered(x0: float, x1: float, hw: float, z0: float, z1: float, c: float) -> trimesh.Trimesh:
    """A box x0..x1, -hw..hw, z0..z1 with its vertical edges chamfered by c."""
    xy = [(x, s * (hw - c)) for x in (x0, x1) for s in (-1, 1)]
    xy += [(x, s * hw) for x in (x0 + c, x1 - c) for s in (-1, 1)]
    return hull([(x, y, z) for x, y in xy for z in (z0, z1)])


@register_category(
    "toilet",
    params={
        "tank": Choice(("close_coupled", "panel", "none"), p=(0.58, 0.27, 0.15)),
        "wall_hung": Flag(0.6),  # with a panel; otherwise a back-to-wall floor bowl
        "size": Uniform(0.065, 0.095),  # the largest extent
        # in a real toilet's metres (the whole is scaled to ``size``)
        "bowl_length": Uniform(0.42, 0.53),  # the rim's length: round to elongated
        "bowl_width": Uniform(0.33, 0.39),
        "egg": Uniform(0.06, 0.2),  # how much wider the rim is at the back
        "squareness": Uniform(2.0, 2.8),  # the rim plan's superellipse exponent
        "rim_height": Uniform(0.37, 0.43),
        "bowl_depth": Uniform(0.35, 0.5),  # the open bowl's depth / rim height
        "pedestal": Uniform(0.45, 0.7),  # the pedestal's width / the bowl's
        "seat": Choice(("closed", "open_front"), p=(0.8, 0.2)),
        "lid": Choice(("down", "up", "none"), p=(0.45, 0.35, 0.2)),
        "tank_height": Uniform(0.28, 0.42),  # above the deck
        "tank_width": Uniform(0.85, 1.15),  # / the bowl's width
        "tank_depth": Uniform(0.14, 0.22),
        "flush": Choice(("button", "lever")),
        "panel_height": Uniform(0.75, 1.0),
        "wall": Uniform(0.0022, 0.003),  # the bowl's wall, in the scaled size
    },
    modelnet_names=("toilet",),
)
def build(p: Params) -> Assembly:
    """Toilet (18 parameters: close-coupled tank, panel or none; wall-hung; size; bowl
    length, width, egg, squareness, rim height, depth; pedestal width; seat style; lid down,
    up or none; tank height, width and depth; flush button or lever; panel height; wall)."""
    tank = str(p["tank"])
    wall_hung = tank == "panel" and bool(p["wall_hung"])
    Lb = float(np.clip(float(p["bowl_length"]), 0.38, 0.6))
    Wb = float(np.clip(float(p["bowl_width"]), 0.3, 0.45))
    Wb = min(Wb, 0.85 * Lb)  # the bowl is always longer than wide
    zr = float(np.clip(float(p["rim_height"]), 0.33, 0.47))
    th = float(np.clip(float(p["tank_height"]), 0.2, 0.5))
    tw = float(np.clip(float(p["tank_width"]), 0.75, 1.25)) * Wb
    td = float(np.clip(float(p["tank_depth"]), 0.11, 0.26))
    ph = float(np.clip(float(p["panel_height"]), 0.65, 1.1))
    pd = 0.16  # a panel's depth
    gap = 0.05  # from the back of the rim to the tank's or panel's front (the hinge)
    lid = str(p["lid"])
    seat_t, lid_t = 0.028, 0.024

    # --- the scale: the largest real extent maps to ``size``
    depth = Lb + gap + {"close_coupled": td, "panel": pd, "none": 0.06}[tank]
    height = {
        "close_coupled": zr + th + lid_t + 0.02,
        "panel": ph,
        "none": zr + 0.33,
    }[tank]
    if lid == "up":
        height = max(height, zr + seat_t + 0.95 * Lb)
    k = float(np.clip(float(p["size"]), 0.04, 0.14)) / max(depth, height, tw)
    mm = 0.001 / k  # one scaled millimetre in real metres
    t = float(np.clip(float(p["wall"]), 0.002, 0.005)) * 1000 * mm
    seat_t, lid_t = max(seat_t, 2.2 * mm), max(lid_t, 2.0 * mm)

    # --- the bowl: its rim's back at x = 0, front at x = Lb
    n = float(np.clip(float(p["squareness"]), 2.0, 3.2))
    egg = float(np.clip(float(p["egg"]), 0.0, 0.25))
    rim = _egg(Wb / 2, Lb / 2, n, egg, Lb / 2)
    bd = float(np.clip(float(p["bowl_depth"]), 0.25, 0.55)) * zr
    zw = zr - bd  # the open bowl's floor
    levels = [(rim.scaled(0.62), zw), (rim.scaled(0.93), zw + 0.55 * bd), (rim, zr)]
    z_seat = zr + seat_t
    hole = Plan(rim.ax - 0.055, rim.ay - 0.055, n, egg, rim.cx, 0.0, rim.rot)
    parts: list[trimesh.Trimesh] = []
    open_front = p["seat"] == "open_front"
    if lid == "down":
        # solid, up into the seat's hole under the lid
        parts.append(_rings_hull([*levels, (hole, z_seat - 0.5 * mm)]))
    else:
        # with the bowl open, each sector of its wall also holds the seat ring above it
        # (a sector's hull then runs the bowl's inside straight from its floor up to the
        # seat's hole): half the pieces of a separate ring, and no seams between the two
        seat_on = None
        if open_front:
            seat_on = np.abs(2 * np.pi * (np.arange(_SECTORS) + 0.5) / _SECTORS - np.pi / 2) > 0.35
        a = sector_angles(_SECTORS).ravel()
        seat = [
            np.column_stack([pl.points(a), np.full(len(a), z)]).reshape(_SECTORS, 2, 3)
            for pl, z in ((rim, z_seat), (hole, z_seat), (hole, zr - 0.5 * mm))
        ]
        for j, q in enumerate(wall_sections(levels, t, _SECTORS)):
            on = seat_on is None or seat_on[j]
            parts.append(hull(np.concatenate([q, *(r[j] for r in seat)]) if on else q))
        parts.append(basin_floor(levels[0][0], zw, zw + 1.5 * t, _SECTORS))

    # --- below the bowl: a pedestal (floor-standing) or a rounded underside (wall-hung),
    # and the rear body from the bowl's back to the deck behind the seat
    x_back = -gap  # the tank's or panel's front, or the end of a tankless deck
    if tank == "none":
        x_back = -gap - 0.015  # room for the pipe behind the hinge
    bottom = levels[0][0]
    rw = 0.36 * Wb  # the rear body's half-width at the deck
    # the deck stands 1 mm below the rim: level with it, its front corners would graze the
    # rim's curve and leave slivers in the union
    z_deck = zr - 1.0 * mm
    if wall_hung:
        zu = 0.55 * zw  # the underside's lowest point
        under = _egg(0.5 * Wb / 2, 0.32 * Lb, 2.4, 0.0, 0.42 * Lb)
        parts.append(_rings_hull([(under, zu), (bottom.scaled(0.96), zw + 0.75 * t)]))
        top_rect = [(x, s * rw, z_deck) for x in (x_back - pd / 2, 0.5 * t) for s in (-1, 1)]
        low_rect = [
            (x, s * 0.8 * rw, zu + 0.02) for x in (x_back - pd / 2, 0.3 * Lb) for s in (-1, 1)
        ]
        parts.append(hull(top_rect + low_rect))
    else:
        pw = float(np.clip(float(p["pedestal"]), 0.35, 0.8)) * Wb / 2
        foot = _egg(pw, 0.34 * Lb, 3.0, 0.0, 0.44 * Lb)
        parts.append(_rings_hull([(foot, 0.0), (bottom.scaled(0.96), zw + 0.75 * t)]))
        # the deck reaches under most of a tank, or into a panel; at the floor the rear
        # body starts further forward, so that its back slopes
        x_deck = {"close_coupled": x_back - 0.85 * td, "panel": x_back - pd / 2, "none": x_back}[
            tank
        ]
        x_floor = {"close_coupled": x_back - 0.4 * td, "panel": x_back - pd / 2, "none": x_back}[
            tank
        ]
        top_rect = [(x, s * rw, z_deck) for x in (x_deck, 0.5 * t) for s in (-1, 1)]
        low_rect = [(x, s * pw, 0.0) for x in (x_floor, 0.45 * Lb) for s in (-1, 1)]
        parts.append(hull(top_rect + low_rect))

    # --- behind: the tank, the panel or the flush pipe
    x_front = x_back  # what a raised lid leans on
    if tank == "close_coupled":
        c = 0.15 * td
        z_top = zr + th
        parts.append(_chamfered(x_back - td, x_back, tw / 2, z_deck - 0.5 * mm, z_top, c))
        o = 1.2 * mm  # the lid's overhang
        parts.append(
            _chamfered(x_back - td - o, x_back + o, tw / 2 + o, z_top - 0.5 * mm, z_top + lid_t, c)
        )
        if p["flush"] == "button":
            parts.append(
                cylinder(
                    0.18 * td,
                    z_top + lid_t - 0.5 * mm,
                    z_top + lid_t + 1.8 * mm,
                    sections=16,
                    center=(x_back - td / 2, 0.0),
                )
            )
        else:
            # a lever on the front face by the +y corner
            lz = z_top - 0.05
            parts.append(
                box((2.5 * mm, 0.09, 2.2 * mm), center=(x_back + 0.8 * mm, tw / 2 - c - 0.055, lz))
            )
            parts.append(
                cylinder(
                    1.6 * mm,
                    z_top - 0.05 - 1.6 * mm,
                    z_top - 0.05 + 1.6 * mm,
                    sections=10,
                    center=(x_back + 0.8 * mm, tw / 2 - c - 0.01),
                )
            )
    elif tank == "panel":
        pw_ = max(tw, 1.05 * Wb)
        parts.append(box((pd, pw_, ph), center=(x_back - pd / 2, 0.0, ph / 2)))
        # a flush plate, proud of the panel, with two buttons proud of the plate
        zc = min(0.86 * ph, ph - 0.12)
        plate_w, plate_h = 0.22, 0.15
        parts.append(box((2.0 * mm, plate_w, plate_h), center=(x_back + 0.5 * mm, 0.0, zc)))
        for s in (-1, 1):
            parts.append(
                box(
                    (1.6 * mm, 0.4 * plate_w, 0.7 * plate_h),
                    center=(x_back + 1.8 * mm, s * 0.23 * plate_w, zc),
                )
            )
    else:
        # a flush pipe from the deck up to a valve, then back to the wall
        r = max(0.016, 1.6 * mm)
        xp = x_back + r + 0.5 * mm
        zt = zr + 0.28
        x_front = xp + r  # a raised lid leans on the pipe
        parts += tube([[xp, 0.0, zr - 0.01], [xp, 0.0, zt], [xp - 0.07, 0.0, zt]], r, sections=10)
        parts.append(box((0.06, 0.05, 0.07), center=(xp, 0.0, zt - 0.06)))
        parts += tube(
            [[xp, 0.01, zt - 0.06], [xp + 0.02, 0.09, zt - 0.07]], max(0.009, 1.5 * mm), sections=8
        )

    # --- the seat ring on the rim (open at the front, or closed) under a lid that is down;
    # the hinge at the back
    if lid == "down":
        ring_w = rim.ax - hole.ax
        seat_parts = basin_wall([(rim, zr - 0.5 * mm), (rim, z_seat)], ring_w, _SECTORS)
        if open_front:
            # drop the sectors round the front (+x: the plan's local +y, at theta = pi / 2)
            mid = 2 * np.pi * (np.arange(_SECTORS) + 0.5) / _SECTORS
            seat_parts = [
                q for q, m in zip(seat_parts, mid, strict=True) if abs(m - np.pi / 2) > 0.35
            ]
        parts += seat_parts
    x_h = 0.5 * t  # the hinge's axis, over the back of the rim
    # the hinge: two round posts through the seat's back into the deck (round, so that no
    # face of theirs lies in the plane of the deck's or the wall's)
    hr = max(0.014, 1.6 * mm)
    for s in (-1, 1):
        parts.append(
            cylinder(
                hr, z_deck - 1.0 * mm, z_seat + 1.2 * mm, sections=10, center=(0.0, s * 0.2 * Wb)
            )
        )

    a = np.linspace(0.0, 2 * np.pi, _SECTORS, endpoint=False)
    lid_xy = rim.points(a)
    if lid == "down":
        parts.append(
            hull(
                np.concatenate(
                    [
                        np.column_stack([lid_xy, np.full(_SECTORS, z)])
                        for z in (z_seat - 0.5 * mm, z_seat + lid_t)
                    ]
                )
            )
        )
    elif lid == "up":
        # turned up about the hinge and leaning back onto the tank, panel or pipe (its top
        # edge half a millimetre into it)
        length = float(lid_xy[:, 0].max())
        sin_lean = (x_h - x_front - lid_t + 0.5 * mm) / length
        lean = float(np.clip(np.arcsin(np.clip(sin_lean, 0.0, 1.0)), 0.02, 0.3))
        u = np.array([-np.sin(lean), np.cos(lean)])  # along the lid, from the hinge up
        nrm = np.array([-np.cos(lean), -np.sin(lean)])  # its (former) top face's normal
        pts = []
        for w in (0.0, lid_t):
            for x, y in lid_xy:
                d = x - x_h
                xz = np.array([x_h, z_seat]) + d * u + w * nrm
                pts.append([xz[0], y, xz[1]])
        parts.append(hull(pts))

    for q in parts:
        q.apply_scale(k)
    return Assembly(parts, no_symmetry())
