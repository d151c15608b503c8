"""Desk: a table with drawers, long along y, the user sitting at the front (+x).

Four styles of base carry a rectangular top (0.10-0.17 m long, as table.py's rectangular
tops): a plain writing desk stands on four legs with one to three shallow drawers in the
front apron; a one-pedestal desk has a cabinet of 2-4 stacked drawers under one end and
legs or a side panel at the other; a two-pedestal desk has a drawer cabinet under both ends
with the knee space between them; a panel-ended desk stands on two full-depth side panels.
Pedestal and panel desks may have a shallow centre (pencil) drawer over the knee space.
Two additions combine with the styles: a return wing (an L-shaped desk: a second, narrower
top running forwards from one end, on legs or a panel at its far end, with a modesty panel
along its outer side) and a hutch (shelves and cubbies standing on the rear of the top, open
at the front). A two-pedestal desk has no wing: it would stand in front of one pedestal's
drawers (a one-pedestal desk puts its wing at the other end for the same reason).

Drawer fronts stand 2 mm proud of their carcass with 1.8 mm grooves between them and carry
knobs, bars or a lip along the top edge, a few millimetres deep: relief a depth camera
sees. The knee space is open at the front and closed at the back: by a modesty panel (every
pedestal and panel desk, and a writing desk when ``modesty`` is set) or a writing desk's
rear apron. With its drawers and a close to square-edged top a writing desk is close to a
table (classes overlap in parts, as ModelNet's desk and table do).

A desk has no rotational symmetry. The top overhangs the base at the front (6-14 % of the
depth) but is nearly flush at the back, so the base is off the bounding box's centre; the
drawers (a writing desk's drawer box fills the front half under the top), fronts, handles
and the modesty panel are at the front or back only, and the top's aspect (depth at most
0.65 of the length) keeps quarter turns far from it. Picked by the top's edge.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.geometry import no_symmetry
from beo_bench.objects.params import Choice, Flag, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly, cylinder, hull
from beo_bench.objects.registry import register_category

_E = 0.0008  # overlap of parts that meet, so that their union is one solid
_PROUD = 0.002  # drawer fronts stand this far out of their carcass
_GAP = 0.0018  # groove between neighbouring drawer fronts


def _slab(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float) -> trimesh.Trimesh:
    """An axis-aligned box between two corners (given in any order per axis)."""
    return hull(
        np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], dtype=float)
    )


def _knob(x: float, y: float, z: float, r: float, length: float) -> trimesh.Trimesh:
    """A round knob: a short cylinder along +x from x."""
    a = np.linspace(0.0, 2 * np.pi, 10, endpoint=False)
    ring = np.stack([np.zeros_like(a), y + r * np.cos(a), z + r * np.sin(a)], axis=1)
    return hull(
        np.concatenate([ring + np.array([x - _E, 0, 0]), ring + np.array([x + length, 0, 0])])
    )


def _drawer_front(
    parts: list[trimesh.Trimesh],
    x: float,
    y0: float,
    y1: float,
    z0: float,
    z1: float,
    handle: str,
) -> None:
    """One drawer front on a carcass face at x (facing +x) and its handle."""
    parts.append(_slab(x - _E, x + _PROUD, y0, y1, z0, z1))
    xf = x + _PROUD
    w, h = y1 - y0, z1 - z0
    yc, zc = (y0 + y1) / 2, (z0 + z1) / 2
    if handle == "knob":
        r = float(np.clip(0.15 * h, 0.0015, 0.0028))
        # a wide, shallow front gets a knob near each end, as real drawers do
        ys = (y0 + 0.25 * w, y1 - 0.25 * w) if w > 3.0 * h else (yc,)
        for y in ys:
            parts.append(_knob(xf, y, zc, r, 0.003))
    elif handle == "bar":
        bw = float(np.clip(0.4 * w, 0.008, 0.03))
        bh = float(np.clip(0.15 * h, 0.0018, 0.003))
        parts.append(
            _slab(xf - _E, xf + 0.0028, yc - bw / 2, yc + bw / 2, zc - bh / 2, zc + bh / 2)
        )
    else:  # a lip along the top edge, the finger pull of a handle-less front
        lh = float(np.clip(0.2 * h, 0.0018, 0.003))
        parts.append(_slab(xf - _E, xf + 0.0025, y0 + 0.1 * w, y1 - 0.1 * w, z1 - lh, z1))


@register_category(
    "desk",
    params={
        "style": Choice(
            # the writing desk (a table with apron drawers) the most common, as close to
            # table.py's drawer tables as ModelNet's desks are to its tables
            ("writing", "one_pedestal", "two_pedestals", "panel_ends"),
            p=(0.4, 0.25, 0.2, 0.15),
        ),
        "length": Uniform(0.10, 0.17),  # y, the top's long side
        # depth (x) / length: well short of the length, never near square (that would come
        # close to a quarter-turn symmetry)
        "depth": Uniform(0.42, 0.65, ood=(0.38, 0.72)),
        "height": Uniform(0.06, 0.10),  # top surface above the floor
        "top_thickness": Uniform(0.003, 0.008),
        # front overhang of the top over the base / depth (the sides overhang half as much;
        # the back is nearly flush, the side that stands against a wall)
        "overhang": Uniform(0.06, 0.14, floor=0.03),
        "leg_style": Choice(("square", "round", "tapered")),
        "leg_thickness": Uniform(0.004, 0.008),
        "apron_height": Uniform(0.12, 0.22),  # drawer box under the top / height
        "drawers": Integer(2, 4),  # stacked in each pedestal
        "apron_drawers": Integer(1, 3),  # side by side in a writing desk's apron
        "center_drawer": Flag(0.6),  # pedestal and panel desks: over the knee space
        "pedestal_width": Uniform(0.26, 0.36),  # / length
        "end_support": Choice(("legs", "panel")),  # a one-pedestal desk's other end, a wing's
        "handle": Choice(("knob", "bar", "lip")),
        "modesty": Flag(0.4),  # a writing desk: modesty panel instead of the rear apron
        "modesty_height": Uniform(0.45, 0.8),  # / the space under the top
        "plus_y_side": Flag(0.5),  # the single pedestal's end (+y when set)
        "wing": Flag(0.25),
        "wing_length": Uniform(0.35, 0.6),  # how far the return reaches forwards / length
        "hutch": Flag(0.25),
        "hutch_height": Uniform(0.45, 0.8),  # / height
        "hutch_depth": Uniform(0.22, 0.38),  # / depth
        "hutch_cubbies": Integer(0, 3),  # dividers under the hutch's shelf
    },
    modelnet_names=("desk",),
)
def build(p: Params) -> Assembly:
    """Desk (24 parameters: style; top length, depth, height, thickness, overhang; leg
    style and thickness; apron height; drawers per pedestal, apron drawers, centre drawer;
    pedestal width; end support; handle; modesty panel and its height; pedestal side; wing
    and its length; hutch and its height, depth and cubbies)."""
    style = str(p["style"])
    handle = str(p["handle"])
    L = float(p["length"])
    D = L * float(p["depth"])
    H = float(np.clip(float(p["height"]), 0.45 * L, 0.8 * L))
    tt = float(np.clip(float(p["top_thickness"]), 0.003, 0.12 * H))
    f = D * float(np.clip(float(p["overhang"]), 0.03, 0.2))  # front overhang
    so = 0.5 * f  # side overhang
    xb, xf = -D / 2 + 0.001, D / 2 - f  # rear and front faces of the base
    ys = L / 2 - so  # outer faces of the end supports
    z_u, z_in = H - tt, H - tt / 2  # underside of the top; supports reach half-way into it
    lt = float(np.clip(float(p["leg_thickness"]), 0.003, 0.12 * D))
    at = float(np.clip(0.5 * lt, 0.002, 0.004))  # apron board thickness
    pt = float(np.clip(0.7 * lt, 0.003, 0.006))  # side / modesty panel thickness
    ah = float(np.clip(float(p["apron_height"]) * H, 0.009, 0.3 * H))  # drawer box height
    mh = float(p["modesty_height"]) * z_u
    s = 1.0 if p["plus_y_side"] else -1.0
    wing = bool(p["wing"]) and style != "two_pedestals"

    parts = [_slab(-D / 2, D / 2, -L / 2, L / 2, z_u, H)]

    def legs(x_centres: tuple[float, ...], y: float) -> None:
        """Legs of the chosen style centred at (x, y), from the floor into the top."""
        for x in x_centres:
            if p["leg_style"] == "round":
                parts.append(cylinder(lt / 2, 0.0, z_in, sections=12, center=(x, y)))
            else:
                b = 0.6 * lt if p["leg_style"] == "tapered" else lt
                parts.append(
                    hull(
                        [
                            [x + u * w / 2, y + v * w / 2, z]
                            for u in (-1, 1)
                            for v in (-1, 1)
                            for z, w in ((0.0, b), (z_in, lt))
                        ]
                    )
                )

    def leg_end(sign: float) -> float:
        """Two legs and a side apron at the +y (sign 1) or -y end; the inner face's y."""
        legs((xb + lt / 2, xf - lt / 2), sign * (ys - lt / 2))
        parts.append(
            _slab(xb + lt / 2, xf - lt / 2, sign * (ys - at), sign * ys, z_u - 0.7 * ah, z_in)
        )
        return sign * (ys - lt)

    def panel_end(sign: float) -> float:
        """A full-depth side panel at one end; the inner face's y."""
        parts.append(_slab(xb, xf, sign * (ys - pt), sign * ys, 0.0, z_in))
        return sign * (ys - pt)

    def pedestal(sign: float, width: float) -> float:
        """A drawer cabinet on a recessed plinth at one end; the inner face's y."""
        y_out, y_inner = sign * ys, sign * (ys - width)
        kick = float(np.clip(0.06 * H, 0.003, 0.006))
        xc = xf - _PROUD  # the carcass's front face
        parts.append(_slab(xb, xc, y_out, y_inner, kick, z_in))
        # the plinth is recessed at the front and sides (a toe kick)
        parts.append(
            _slab(
                xb + 0.002, xc - 0.003, y_out - sign * 0.002, y_inner + sign * 0.002, 0, kick + _E
            )
        )
        n = int(p["drawers"])
        weights = np.array([1.0] * (n - 1) + [1.4])  # a deeper file drawer at the bottom
        z_lo, z_hi = kick + _GAP, z_u - _GAP
        hs = weights / weights.sum() * (z_hi - z_lo - (n - 1) * _GAP)
        y0, y1 = sorted((y_out, y_inner))
        z = z_hi
        for h in hs:
            _drawer_front(parts, xc, y0 + _GAP, y1 - _GAP, z - h, z, handle)
            z -= h + _GAP
        return y_inner

    def drawer_box(y0: float, y1: float, fronts: int, fy0: float, fy1: float) -> None:
        """A drawer box under the top, y0..y1, at the front of the base (its depth 60 % of
        the base's), with ``fronts`` drawer fronts side by side over fy0..fy1."""
        xc = xf - _PROUD
        parts.append(_slab(xc - 0.6 * (xf - xb), xc, y0, y1, z_u - ah, z_in))
        w = (fy1 - fy0 - (fronts + 1) * _GAP) / fronts
        for k in range(fronts):
            a = fy0 + _GAP + k * (w + _GAP)
            _drawer_front(parts, xc, a, a + w, z_u - ah + _GAP, z_u - _GAP, handle)

    # --- the base: end supports, then what spans the knee space between them
    if style == "writing":
        y_lo, y_hi = leg_end(-1.0), leg_end(1.0)
        # the drawer box reaches into the side aprons; its fronts lie between the legs
        drawer_box(-(ys - at + _E), ys - at + _E, int(p["apron_drawers"]), y_lo, y_hi)
    else:
        if style == "panel_ends":
            y_lo, y_hi = panel_end(-1.0), panel_end(1.0)
        elif style == "two_pedestals":
            pw = min(float(p["pedestal_width"]), 0.3) * L
            y_lo, y_hi = pedestal(-1.0, pw), pedestal(1.0, pw)
        else:
            y_ped = pedestal(s, float(p["pedestal_width"]) * L)
            y_free = leg_end(-s) if p["end_support"] == "legs" else panel_end(-s)
            y_lo, y_hi = sorted((y_ped, y_free))
        if p["center_drawer"]:
            # a pencil drawer centred over the knee space, narrower than it
            c, half = (y_lo + y_hi) / 2, min(y_hi - y_lo, 0.45 * L) / 2
            drawer_box(c - half, c + half, 1, c - half, c + half)
        elif style == "panel_ends":
            # no pencil drawer: a two-drawer cabinet hangs under the top beside one panel
            # (a desk always has drawers)
            y_in = y_hi if s > 0 else y_lo
            y1 = y_in - s * (float(p["pedestal_width"]) * L)
            zb = z_u - 0.5 * z_u
            parts.append(_slab(xb + 0.002, xf - _PROUD, y_in + s * _E, y1, zb, z_in))
            h = (z_u - zb - 3 * _GAP) / 2
            fy0, fy1 = sorted((y_in - s * _GAP, y1 + s * _GAP))
            for k in range(2):
                z1 = z_u - _GAP - k * (h + _GAP)
                _drawer_front(parts, xf - _PROUD, fy0, fy1, z1 - h, z1, handle)
    if style == "writing" and not p["modesty"]:
        parts.append(_slab(xb, xb + at, y_lo - _E, y_hi + _E, z_u - 0.7 * ah, z_in))
    else:
        parts.append(_slab(xb, xb + pt, y_lo - _E, y_hi + _E, z_u - mh, z_in))

    # --- return wing: a narrower top running forwards from one end (the end away from a
    # single pedestal, whose drawers it would block), a modesty panel along its outer side
    # continuing the end support, and legs or a panel under its far end
    if wing:
        ws = -s if style == "one_pedestal" else s
        ww = min(0.8 * D, 0.45 * L)
        wl = float(np.clip(float(p["wing_length"]) * L, 0.4 * D, 0.175 - D))
        x_end = D / 2 + wl
        y_out, y_in = ws * L / 2, ws * (L / 2 - ww)
        parts.append(_slab(D / 2 - 0.01, x_end, y_out, y_in, z_u, H))
        xe = x_end - so  # the far end support's outer face
        parts.append(_slab(xf - lt / 2, xe - 0.5 * lt, ws * ys, ws * (ys - pt), z_u - mh, z_in))
        yi = y_in + ws * so  # inner face of the wing's supports
        if p["end_support"] == "legs":
            legs((xe - lt / 2,), ws * (ys - lt / 2))
            legs((xe - lt / 2,), yi + ws * lt / 2)
            parts.append(
                _slab(xe - at, xe, ws * (ys - lt / 2), yi + ws * lt / 2, z_u - 0.7 * ah, z_in)
            )
        else:
            parts.append(_slab(xe - pt, xe, ws * ys, yi, 0.0, z_in))

    # --- hutch: back panel, two sides, a top board and a shelf on the rear of the top, with
    # dividers making cubbies under the shelf; open at the front
    if p["hutch"]:
        hp = 0.003
        hd = float(np.clip(float(p["hutch_depth"]) * D, 0.012, 0.45 * D))
        hh = float(np.clip(float(p["hutch_height"]) * H, 0.02, 0.175 - H))
        yh = L / 2 - 0.5 * so
        x0, x1 = -D / 2, -D / 2 + hd
        z0, z1 = H - _E, H + hh
        zs = H + 0.5 * hh  # the shelf
        parts.append(_slab(x0, x0 + hp, -yh, yh, z0, z1))
        for sign in (-1.0, 1.0):
            parts.append(_slab(x0, x1, sign * yh, sign * (yh - hp), z0, z1))
        parts.append(_slab(x0, x1 + 0.002, -yh, yh, z1 - hp, z1))
        parts.append(_slab(x0 + hp - _E, x1, -yh + hp - _E, yh - hp + _E, zs - hp / 2, zs + hp / 2))
        n = int(p["hutch_cubbies"])
        for k in range(n):
            y = -yh + 2 * yh * (k + 1) / (n + 1)
            parts.append(_slab(x0 + hp - _E, x1 - 0.002, y - hp / 2, y + hp / 2, z0, zs))

    return Assembly(parts, no_symmetry())
