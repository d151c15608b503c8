"""Shared geometry of case furniture (dressers, night stands, desk pedestals): a carcass
with drawer and door fronts, handles, a top with an overhang, and a plinth, legs or
bracket feet under it. Not a category itself: the builders of those categories compose
these pieces.

Frame: as every builder's, +x front, +y left, +z up. A carcass is a :class:`Block` (its
bounds); its front face is the plane ``x = block.x1``, and everything on the front (fronts,
face frame, handles) stands proud of that plane, so the front of a case differs visibly
from its back.

The front is laid out in horizontal *bands* from the bottom up (:class:`Band`): a band of
one to a few drawers side by side, a door (or a pair of doors), or an open niche (the
carcass is hollow there: two sides and a back, open to the front). Two front styles, as
in real furniture (:class:`FrontStyle`):

- ``overlay``: each front is a slab on the carcass face; the gaps between fronts are
  grooves as deep as the slab is thick.
- ``framed``: the fronts sit inside a face frame (stiles, rails and mullions) that stands
  further proud of them, so each front is seen recessed in its opening.

Sizes are those of tabletop toys (a dresser 0.09-0.16 m wide), so every detail is
exaggerated to what a depth camera at about 1 m sees: grooves and proud steps of 1.5 mm
or more, handles standing 2-5 mm off the face. Parts overlap by :data:`EMBED` (never just
touch), so that their union is one solid, and no piece is thinner than :data:`MIN_WALL`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from beo_bench.objects.primitives import box, hull

EMBED = 0.0007
"""How far a part reaches into the part it is attached to (parts overlap, never touch)."""

MIN_WALL = 0.0015
"""The thinnest piece (and narrowest groove) any helper here makes."""


def along(ranges: Sequence[tuple[float, float]], u: float) -> float:
    """The value at ``u`` (0..1) along the intervals ``ranges`` laid end to end (a
    proportion drawn uniformly but kept out of the gaps between them, such as near-square
    elevations); beyond 1 (a wider ``ood`` draw) it goes on past the last interval."""
    total = sum(b - a for a, b in ranges)
    d = u * total
    for a, b in ranges:
        if d <= b - a:
            return a + d
        d -= b - a
    return ranges[-1][1] + d


@dataclass(frozen=True)
class Block:
    """An axis-aligned box by its bounds, in metres (x front, y left, z up)."""

    x0: float
    x1: float
    y0: float
    y1: float
    z0: float
    z1: float

    @property
    def depth(self) -> float:
        return self.x1 - self.x0

    @property
    def width(self) -> float:
        return self.y1 - self.y0

    @property
    def height(self) -> float:
        return self.z1 - self.z0

    def mesh(self) -> trimesh.Trimesh:
        """The box itself (a convex part)."""
        return box(
            (self.depth, self.width, self.height),
            center=((self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2, (self.z0 + self.z1) / 2),
        )


def block(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float) -> trimesh.Trimesh:
    """The box with bounds [x0, x1] x [y0, y1] x [z0, z1]."""
    return Block(x0, x1, y0, y1, z0, z1).mesh()


@dataclass(frozen=True)
class Band:
    """One horizontal band of a cabinet's front, listed from the bottom up.

    ``kind``: ``drawer`` (``columns`` drawers side by side), ``door`` (one door, or a pair
    when ``columns`` is 2) or ``open`` (a niche: no front, the carcass hollow there).
    ``weight``: the band's share of the front's height, relative to the other bands.
    """

    kind: str = "drawer"
    columns: int = 1
    weight: float = 1.0


@dataclass(frozen=True)
class FrontStyle:
    """How a cabinet's fronts look.

    ``kind``: ``overlay`` or ``framed`` (module docstring). ``thickness``: how far a front
    stands proud of the carcass face (at least :data:`MIN_WALL`). ``gap``: the groove
    between overlay fronts, or the width of a framed front's rails and mullions.
    ``margin``: the border between the fronts and the carcass's outline (the face frame's
    outer stiles and rails when framed; 0 lets overlay fronts cover the face to its edges).
    ``frame_proud``: how far a face frame stands in front of its fronts. ``handle``:
    ``knob``, ``bar``, ``recessed`` (a notch in the front's top edge) or ``none``.
    ``hinge``: the side a single door is hinged on, +1 (+y) or -1 (-y); its handle is near
    the other edge.
    """

    kind: str = "overlay"
    thickness: float = 0.002
    gap: float = 0.0018
    margin: float = 0.0
    frame_proud: float = 0.0015
    handle: str = "knob"
    hinge: int = 1


@dataclass(frozen=True)
class Panel:
    """The outline of one front on the carcass's face (y0..y1 across, z0..z1 up)."""

    y0: float
    y1: float
    z0: float
    z1: float
    kind: str = "drawer"
    hinge: int = 1  # a door's hinged side, +1 or -1

    @property
    def width(self) -> float:
        return self.y1 - self.y0

    @property
    def height(self) -> float:
        return self.z1 - self.z0


def band_ranges(
    z0: float, z1: float, bands: Sequence[Band], gap: float, margin: float
) -> list[tuple[float, float]]:
    """The (z0, z1) of each band inside [z0 + margin, z1 - margin], split by ``weight``
    with ``gap`` between neighbours."""
    inner = (z1 - z0) - 2 * margin - gap * (len(bands) - 1)
    w = np.array([max(b.weight, 1e-3) for b in bands], dtype=np.float64)
    h = inner * w / w.sum()
    out, z = [], z0 + margin
    for hk in h:
        out.append((z, z + float(hk)))
        z += float(hk) + gap
    return out


def lowest_front(case: Block, bands: Sequence[Band], style: FrontStyle) -> float:
    """The height of the lowest drawer or door that :func:`cabinet` lays out for ``bands``
    on ``case`` (a builder drops drawers until every front keeps room for a pull)."""
    margin, gap = _margin_gap(style)
    zs = band_ranges(case.z0, case.z1, bands, gap, margin)
    return min(
        (zb - za for b, (za, zb) in zip(bands, zs, strict=True) if b.kind != "open"), default=np.inf
    )


def _margin_gap(style: FrontStyle) -> tuple[float, float]:
    """The margin and gap :func:`cabinet` lays the fronts out with."""
    margin = max(style.margin, MIN_WALL) if style.kind == "framed" else max(style.margin, 0.0)
    return margin, max(style.gap, MIN_WALL)


def layout_panels(
    y0: float,
    y1: float,
    z0: float,
    z1: float,
    bands: Sequence[Band],
    gap: float,
    margin: float,
    hinge: int = 1,
) -> tuple[list[Panel], list[tuple[float, float]]]:
    """The fronts of ``bands`` on the face [y0, y1] x [z0, z1]: the panels (drawers and
    doors, ``gap`` apart and ``margin`` in from the outline) and each band's (z0, z1)."""
    zs = band_ranges(z0, z1, bands, gap, margin)
    panels: list[Panel] = []
    ya, yb = y0 + margin, y1 - margin
    for b, (za, zb) in zip(bands, zs, strict=True):
        if b.kind == "open":
            continue
        n = max(1, int(b.columns))
        w = (yb - ya - gap * (n - 1)) / n
        for k in range(n):
            ly = ya + k * (w + gap)
            # a pair of doors opens from the middle: each is hinged on its outer edge
            h = hinge if n == 1 else (-1 if k == 0 else 1)
            panels.append(Panel(ly, ly + w, za, zb, b.kind, h))
    return panels, zs


def carcass(
    case: Block, bands: Sequence[Band], zs: Sequence[tuple[float, float]], wall: float
) -> list[trimesh.Trimesh]:
    """The body of a case: solid where its bands have fronts, and around each ``open``
    band a niche of two sides and a back ``wall`` thick (its floor and ceiling are the
    solid body below and above, or the case's outline)."""
    parts: list[trimesh.Trimesh] = []
    w = max(wall, MIN_WALL)
    z = case.z0
    for b, (za, zb) in zip(bands, zs, strict=True):
        if b.kind != "open":
            continue
        if za - z > 1e-9:
            parts.append(block(case.x0, case.x1, case.y0, case.y1, z, za))
        lo, hi = za - EMBED, zb + EMBED
        parts.append(block(case.x0, case.x1, case.y0, case.y0 + w, lo, hi))
        parts.append(block(case.x0, case.x1, case.y1 - w, case.y1, lo, hi))
        parts.append(block(case.x0, case.x0 + w, case.y0, case.y1, lo, hi))
        z = zb
    if case.z1 - z > 1e-9:
        parts.append(block(case.x0, case.x1, case.y0, case.y1, z, case.z1))
    return parts


def x_frustum(
    y: float, z: float, x0: float, x1: float, r0: float, r1: float, sections: int = 8
) -> trimesh.Trimesh:
    """A round solid along x (a knob): radius r0 at x0 and r1 at x1, axis through (y, z)."""
    a = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    c, s = np.cos(a), np.sin(a)
    pts = [
        np.stack([np.full_like(a, x), y + r * c, z + r * s], axis=1)
        for x, r in ((x0, r0), (x1, r1))
    ]
    return hull(np.concatenate(pts))


def knob(y: float, z: float, x_face: float, radius: float = 0.0018) -> list[trimesh.Trimesh]:
    """A round knob on the face x = ``x_face``, widening towards its end and standing
    about 1.6 radii off the face."""
    r = max(radius, MIN_WALL / 2 + 1e-4)
    return [x_frustum(y, z, x_face - EMBED, x_face + 1.6 * r, 0.65 * r, r)]


def bar_handle(
    y: float, z: float, x_face: float, length: float, vertical: bool = False
) -> list[trimesh.Trimesh]:
    """A bar pull on the face x = ``x_face``: a rail ``length`` long (across, or up when
    ``vertical``) standing 3 mm off the face, its ends sloping back to the face (one convex
    part; a finger gap behind it would be too fine for a depth camera to see anyway)."""
    s, out = 0.0018, 0.003  # the bar's section across; how far it stands off the face
    L = max(length, 3 * s)
    pts = []
    for x, half in ((x_face - EMBED, L / 2), (x_face + out, L / 2 - 0.6 * out)):
        for a in (-half, half):
            for b in (-s / 2, s / 2):
                pts.append([x, y + b, z + a] if vertical else [x, y + a, z + b])
    return [hull(pts)]


def _pocket(panel: Panel) -> tuple[float, float, float] | None:
    """The recessed pull of a front: (y0, y1, z0) of a notch cut down from its top edge
    to the carcass face, or None when the front is too small to keep MIN_WALL-plus
    material beside and below one. Drawers get a wide notch at the centre of the top
    edge, doors a narrow one near the edge away from the hinge."""
    w, h = panel.width, panel.height
    rim = MIN_WALL + 0.0005
    if panel.kind == "door":
        pw = float(np.clip(0.15 * w, 0.004, 0.007))
        ph = float(np.clip(0.12 * h, 0.004, 0.008))
        inset = max(rim, 0.08 * w)
        yc = panel.y1 - inset - pw / 2 if panel.hinge < 0 else panel.y0 + inset + pw / 2
    else:
        pw = float(np.clip(0.3 * w, 0.006, 0.022))
        ph = float(np.clip(0.3 * h, 0.003, 0.0045))
        yc = (panel.y0 + panel.y1) / 2
    if w - pw < 2 * rim or h - ph < 2 * rim:
        return None
    return (yc - pw / 2, yc + pw / 2, panel.z1 - ph)


def _slab(
    panel: Panel, x0: float, x1: float, grow: float, pocket: tuple[float, float, float] | None
) -> list[trimesh.Trimesh]:
    """A front's slab from x0 to x1 over the panel grown by ``grow`` on every side: one
    box, or three around a notch in its top edge (the recessed pull, down to the carcass
    face)."""
    y0, y1, z0, z1 = panel.y0 - grow, panel.y1 + grow, panel.z0 - grow, panel.z1 + grow
    if pocket is None:
        return [block(x0, x1, y0, y1, z0, z1)]
    py0, py1, pz0 = pocket
    return [
        block(x0, x1, y0, y1, z0, pz0),  # below the notch
        block(x0, x1, y0, py0, pz0 - EMBED, z1),  # beside it
        block(x0, x1, py1, y1, pz0 - EMBED, z1),
    ]


def handles(panel: Panel, x_face: float, kind: str) -> list[trimesh.Trimesh]:
    """The knob(s) or bar of one front whose outer face is the plane x = ``x_face``
    (a recessed pull is a notch in the slab instead: see :func:`fronts`).

    A drawer wider than 5 cm gets two knobs (or a longer bar), placed on its centre line;
    a door gets one, near the edge away from its hinge, a bar standing upright.
    """
    w, h = panel.width, panel.height
    zc = (panel.z0 + panel.z1) / 2
    if kind == "none" or kind == "recessed":
        return []
    if panel.kind == "door":
        inset = float(np.clip(0.12 * w, 0.003, 0.006))
        y = panel.y1 - inset if panel.hinge < 0 else panel.y0 + inset
        if kind == "bar":
            return bar_handle(y, zc, x_face, float(np.clip(0.35 * h, 0.008, 0.025)), vertical=True)
        return knob(y, zc, x_face)
    r = float(np.clip(0.12 * h, 0.0014, 0.0022))
    if kind == "bar":
        return bar_handle(
            0.5 * (panel.y0 + panel.y1), zc, x_face, float(np.clip(0.4 * w, 0.008, 0.03))
        )
    yc = 0.5 * (panel.y0 + panel.y1)
    if w > 0.05:
        return [q for s in (-1, 1) for q in knob(yc + s * 0.27 * w, zc, x_face, r)]
    return knob(yc, zc, x_face, r)


def fronts(
    panels: Sequence[Panel],
    zs: Sequence[tuple[float, float]],
    case: Block,
    style: FrontStyle,
) -> list[trimesh.Trimesh]:
    """The fronts on the face x = ``case.x1``, their handles and (framed) the face frame.

    ``panels`` and ``zs`` come from :func:`layout_panels` over the same ``case`` face and
    ``style`` (gap and margin). Doors with room for it carry a raised centre panel.
    """
    xf = case.x1
    t = max(style.thickness, MIN_WALL)
    x_out = xf + t
    parts: list[trimesh.Trimesh] = []
    framed = style.kind == "framed"
    pockets = [_pocket(q) if style.handle == "recessed" else None for q in panels]
    if framed:
        # framed fronts fill their openings and reach under the frame around them; a
        # band whose fronts have no notch is one flat face behind the frame, so one slab
        # across the band does (fewer parts, the same solid)
        grow = min(style.gap, style.margin) / 2
        for za, zb in zs:
            row = [k for k, q in enumerate(panels) if abs(q.z0 - za) < 1e-9]
            if row and all(pockets[k] is None for k in row):
                parts.append(block(xf - EMBED, x_out, case.y0, case.y1, za - grow, zb + grow))
            else:
                for k in row:
                    parts += _slab(panels[k], xf - EMBED, x_out, grow, pockets[k])
    else:
        for pnl, pocket in zip(panels, pockets, strict=True):
            parts += _slab(pnl, xf - EMBED, x_out, 0.0, pocket)
    for pnl, pocket in zip(panels, pockets, strict=True):
        kind = style.handle if (style.handle != "recessed" or pocket is not None) else "knob"
        if pnl.kind == "door":
            m = max(0.004, 0.15 * min(pnl.width, pnl.height))
            if pocket is None and pnl.width > 2 * m + 0.006 and pnl.height > 2 * m + 0.006:
                # a raised centre panel, leaving the handle on the rim around it
                inset = float(np.clip(0.12 * pnl.width, 0.003, 0.006)) + 0.0025
                y0 = pnl.y0 + (m if pnl.hinge < 0 else inset)
                y1 = pnl.y1 - (inset if pnl.hinge < 0 else m)
                if y1 - y0 > 0.006:
                    parts.append(
                        block(x_out - EMBED, x_out + MIN_WALL, y0, y1, pnl.z0 + m, pnl.z1 - m)
                    )
        parts += handles(pnl, x_out, kind)
    if framed:
        parts += face_frame(panels, zs, case, style)
    return parts


def face_frame(
    panels: Sequence[Panel], zs: Sequence[tuple[float, float]], case: Block, style: FrontStyle
) -> list[trimesh.Trimesh]:
    """A face frame standing ``style.thickness + style.frame_proud`` off the face: outer
    stiles and rails ``style.margin`` wide, a rail between bands and a mullion between
    fronts side by side, each ``style.gap`` wide."""
    x0, x1 = (
        case.x1 - EMBED,
        case.x1 + max(style.thickness, MIN_WALL) + max(style.frame_proud, MIN_WALL),
    )
    m, e = max(style.margin, MIN_WALL), EMBED
    y0, y1, z0, z1 = case.y0, case.y1, zs[0][0] - m, zs[-1][1] + m
    parts = [
        block(x0, x1, y0, y0 + m + e, z0, z1),
        block(x0, x1, y1 - m - e, y1, z0, z1),
        block(x0, x1, y0, y1, z0, z0 + m + e),
        block(x0, x1, y0, y1, z1 - m - e, z1),
    ]
    for (_, za), (zb, _) in itertools.pairwise(zs):
        parts.append(block(x0, x1, y0, y1, za - e, zb + e))
    for za, zb in zs:
        row = sorted((p for p in panels if abs(p.z0 - za) < 1e-9), key=lambda p: p.y0)
        for a, b in itertools.pairwise(row):
            parts.append(block(x0, x1, a.y1 - e, b.y0 + e, za - e, zb + e))
    return parts


def cabinet(
    case: Block, bands: Sequence[Band], style: FrontStyle, wall: float = 0.003
) -> list[trimesh.Trimesh]:
    """A whole case: the carcass of ``case`` (hollow niches ``wall`` thick at its ``open``
    bands) and, on its front face x = ``case.x1``, the fronts, handles and face frame of
    ``bands`` laid out over the full face."""
    margin, gap = _margin_gap(style)
    panels, zs = layout_panels(case.y0, case.y1, case.z0, case.z1, bands, gap, margin, style.hinge)
    return carcass(case, bands, zs, max(wall, margin)) + fronts(panels, zs, case, style)


def top_slab(
    x0: float, x1: float, y0: float, y1: float, z0: float, thickness: float, bevel: float = 0.0
) -> trimesh.Trimesh:
    """A top board [x0, x1] x [y0, y1] from z0 up by ``thickness``; with ``bevel`` > 0
    its upper front and side edges are chamfered by that much (the back edge, against a
    wall, stays square)."""
    z1 = z0 + thickness
    b = float(np.clip(bevel, 0.0, min(0.6 * thickness, 0.25 * (x1 - x0))))
    if b <= 0:
        return block(x0, x1, y0, y1, z0, z1)
    pts = [[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1 - b)]
    pts += [[x, y, z1] for x in (x0, x1 - b) for y in (y0 + b, y1 - b)]
    return hull(pts)


def plinth(case: Block, recess_front: float, recess_sides: float) -> list[trimesh.Trimesh]:
    """A solid base from the floor (z = 0) up into the case's bottom, set back from the
    front by ``recess_front`` (a toe kick) and from the sides by ``recess_sides``, flush
    with the back."""
    return [
        block(
            case.x0,
            case.x1 - recess_front,
            case.y0 + recess_sides,
            case.y1 - recess_sides,
            0.0,
            case.z0 + EMBED,
        )
    ]


def leg(
    x: float,
    y: float,
    z_top: float,
    thickness: float,
    style: str,
    toward: tuple[float, float] = (0.0, 0.0),
) -> list[trimesh.Trimesh]:
    """One leg from the floor up to ``z_top`` centred on (x, y): ``square`` (straight),
    ``tapered`` (square, narrowing to 60 % at the floor, its inner faces sloping) or
    ``round`` (a cylinder narrowing to 70 %). ``toward`` is the unit (x, y) direction to
    the outer corner: a tapered leg keeps its outer faces plumb there."""
    t = max(thickness, 2 * MIN_WALL)
    if style == "round":
        a = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
        ring = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
        return [
            hull(
                np.concatenate(
                    [
                        np.array([x, y, z_top]) + 0.5 * t * ring,
                        np.array([x, y, 0.0]) + 0.35 * t * ring,
                    ]
                )
            )
        ]
    k = 0.6 if style == "tapered" else 1.0
    ox, oy = toward
    pts = []
    for z, f in ((z_top, 1.0), (0.0, k)):
        # the bottom square, f of the top's size, moved so that its outer faces stay in line
        cx, cy = x + ox * (1 - f) * t / 2, y + oy * (1 - f) * t / 2
        pts += [[cx + u * f * t / 2, cy + v * f * t / 2, z] for u in (-1, 1) for v in (-1, 1)]
    return [hull(pts)]


def corner_legs(
    case: Block, thickness: float, style: str, inset: float = 0.0, z_top: float | None = None
) -> list[trimesh.Trimesh]:
    """Four legs under the case's corners, their outer faces ``inset`` in from its
    outline, reaching up into its bottom (or to ``z_top``)."""
    t = max(thickness, 2 * MIN_WALL)
    zt = case.z0 + EMBED if z_top is None else z_top
    parts = []
    for sx, x in ((-1, case.x0 + inset + t / 2), (1, case.x1 - inset - t / 2)):
        for sy, y in ((-1, case.y0 + inset + t / 2), (1, case.y1 - inset - t / 2)):
            parts += leg(x, y, zt, t, style, (float(sx), float(sy)))
    return parts


def bracket_feet(
    case: Block,
    height: float,
    length_x: float,
    length_y: float,
    thickness: float,
    proud: float = 0.0,
) -> list[trimesh.Trimesh]:
    """Bracket feet: at each corner an L of two boards ``thickness`` thick, one along the
    front or back (``length_y`` long) and one along the side (``length_x``), full length
    at the top and cut back to 55 % at the floor (the bracket's curve, made straight). The
    front feet stand ``proud`` in front of the case's face (in line with its fronts)."""
    t = max(thickness, MIN_WALL)
    zt = case.z0 + EMBED
    parts = []
    for sx in (-1, 1):
        xo = case.x1 + proud if sx > 0 else case.x0  # the outer face of this end
        for sy in (-1, 1):
            yo = case.y1 if sy > 0 else case.y0
            # board across (along y): from the corner inwards by length_y
            pts = []
            for z, f in ((zt, 1.0), (0.0, 0.55)):
                for dx in (0.0, t):
                    for dy in (0.0, f * length_y):
                        pts.append([xo - sx * dx, yo - sy * dy, z])
            parts.append(hull(pts))
            # board along the side (along x): from the corner inwards by length_x
            pts = []
            for z, f in ((zt, 1.0), (0.0, 0.55)):
                for dx in (0.0, f * length_x):
                    for dy in (0.0, t):
                        pts.append([xo - sx * dx, yo - sy * dy, z])
            parts.append(hull(pts))
    return parts
