"""Bathtub: a basin open at the top, built into a block, freestanding or on claw feet.

The tub is long along y and its front (the apron of a built-in tub, the open side of a
corner one) faces +x; a single-ended tub has its backrest at -y and its drain at +y, and
taps, where there are any, stand at the +y end. Four sub-styles:

* built-in: a rectangular block with the basin hollowed out of it, an apron front under an
  overhanging lip (optionally with a raised panel), the basin set back from the front so
  that the deck along the wall (-x) is the wider one;
* corner: the same block with its front corner at -y cut off by a large chamfer and an
  oval basin turned towards it;
* freestanding: a thin shell (an oval or a rounded rectangle in plan, with a rounded
  belly) standing on the floor or on a plinth set in from its bottom;
* clawfoot: a thin shell with a rolled rim, raised on four splayed feet with ball ends,
  sometimes with the ends of its rim swept up ("slipper" tubs).

A basin's plan is a superellipse (exponent 2 for an oval, up to 4.5 for a rounded
rectangle; :class:`Plan`, shared with toilet.py); a single-ended basin is egg-shaped, wider
at the backrest, its floor shifted towards the drain so that the backrest slopes, and a
shell has its rim swept up at the backrest. A shell's wall is a ring of convex sectors,
each the hull of the whole wall cross-section (the outer profile, bulging outwards, and
inner points thickened along its normal), as in bowl.py; a block is a ring of pieces from
the basin's inside out to its plan polygon, on a slab under the basin. The union is one
solid without voids. Taps are a spout between two handles, on a block's deck or on a
shell's tap ledge (a shelf across the +y end inside the rim). The tub is picked by its wall
or rim (one finger inside the basin).

A freestanding or clawfoot tub with two equal ends and no taps is the same after a half
turn about z (its plan, plinth and feet are symmetric end to end and side to side), so it
is declared 2-fold; its length is at least 1.8 times its width, so it is far from 4-fold.
Built-in and corner tubs (apron, set-back basin, chamfer) and tubs with a backrest or taps
have no rotational symmetry; a shell's tap ledge grows where needed to hold a visible
share of its volume (a thin oval shell has little volume to spare).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import trimesh

from beo_bench.geometry import cyclic_z, no_symmetry
from beo_bench.objects.params import Choice, Flag, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, cylinder, ellipsoid, hull, tube
from beo_bench.objects.registry import register_category

# Neighbouring sectors of a wall overlap by this angle (as in primitives.revolve_shell), so
# that their union is one solid rather than pieces touching along a face.
_OVERLAP = 1e-3
# angular sectors of a wall or block
_SECTORS = 20
# A shell's tap ledge and mixer hold at least this share of its volume, so that a half
# turn about z visibly changes a tub with two equal ends (volume IoU well below 0.95).
_MIN_TAP_SHARE = 0.07


class Plan:
    """A basin's plan outline at one height: a superellipse with half-axes (ax, ay) and
    exponent n, egg-shaped (wider towards -y by ``egg`` of ax at the -y end), turned by
    ``rot`` about its centre (cx, cy)."""

    def __init__(
        self,
        ax: float,
        ay: float,
        n: float = 2.0,
        egg: float = 0.0,
        cx: float = 0.0,
        cy: float = 0.0,
        rot: float = 0.0,
    ) -> None:
        self.ax, self.ay, self.n, self.egg = ax, ay, n, egg
        self.cx, self.cy, self.rot = cx, cy, rot

    def points(
        self, theta: np.ndarray | float, inset_x: float = 0.0, inset_y: float = 0.0
    ) -> np.ndarray:
        """Points (k, 2) of the outline at parameters ``theta``, its half-axes reduced by
        the insets (the inner surface of a wall)."""
        t = np.atleast_1d(np.asarray(theta, dtype=np.float64))
        c, s = np.cos(t), np.sin(t)
        e = 2.0 / self.n
        u = np.sign(c) * np.abs(c) ** e
        v = np.sign(s) * np.abs(s) ** e
        ax, ay = self.ax - inset_x, self.ay - inset_y
        x = ax * u * (1.0 + self.egg * (-v))  # wider towards -y (v = -1)
        y = ay * v
        cr, sr = np.cos(self.rot), np.sin(self.rot)
        return np.stack([self.cx + cr * x - sr * y, self.cy + sr * x + cr * y], axis=1)

    def scaled(self, s: float, dy: float = 0.0) -> Plan:
        """The outline scaled by ``s`` about its centre, moved by dy along y."""
        return Plan(s * self.ax, s * self.ay, self.n, self.egg, self.cx, self.cy + dy, self.rot)


def sector_angles(sectors: int) -> np.ndarray:
    """The bounding angles (sectors, 2) of each sector, widened by the overlap."""
    a = 2 * np.pi * np.arange(sectors) / sectors
    return np.stack([a - _OVERLAP, a + 2 * np.pi / sectors + _OVERLAP], axis=1)


def wall_sections(
    levels: Sequence[tuple[Plan, float]],
    thickness: float,
    sectors: int = 24,
    rim_rise: Callable[[np.ndarray], np.ndarray] | None = None,
    roll: float = 0.0,
) -> np.ndarray:
    """The points (sectors, k, 3) of each sector of :func:`basin_wall` (the hull of each
    row is one piece), for a caller to add its own (toilet.py puts a seat on them).

    A thin wall through the outer outlines ``levels`` (plan, z) from the bottom up,
    thickened inwards by ``thickness`` along the normal (the horizontal inset grows where
    the wall leans); ``rim_rise(theta)`` raises the top outline (a swept-up rim). One
    convex piece per sector holds the whole profile, as in bowl.py: the outside keeps its
    outward-bulging profile and the inside becomes a straight chord, the wall thickest at
    mid-height. A ``roll`` > 0 puts a rolled rim of that radius on the top, its centre on
    the top outline (which is then the roll's axis, not the wall's outside), rounded over
    both faces of the wall. The bottom is open (add a floor)."""
    a = sector_angles(sectors).ravel()
    rings = []
    for k, (plan, z) in enumerate(levels):
        # the inset that gives ``thickness`` across the steeper of the adjacent segments
        lo, hi = levels[max(k - 1, 0)], levels[min(k + 1, len(levels) - 1)]
        dz = hi[1] - lo[1]
        ix = thickness * np.hypot(1.0, (hi[0].ax - lo[0].ax) / dz)
        iy = thickness * np.hypot(1.0, (hi[0].ay - lo[0].ay) / dz)
        zz = np.full(len(a), z)
        if rim_rise is not None and k == len(levels) - 1:
            zz = zz + rim_rise(a)
        for xy in (plan.points(a), plan.points(a, ix, iy)):
            rings.append(np.column_stack([xy, zz]).reshape(sectors, 2, 3))
    if roll > 0:
        plan, z = levels[-1]
        rise = rim_rise(a) if rim_rise is not None else 0.0
        for q in np.linspace(-np.pi / 2, 1.5 * np.pi, 6, endpoint=False):
            xy = plan.points(a, -roll * np.cos(q), -roll * np.cos(q))
            rings.append(np.column_stack([xy, z + rise + roll * np.sin(q)]).reshape(sectors, 2, 3))
    return np.concatenate(rings, axis=1)  # (sectors, 2 * (2 * levels + roll points), 3)


def basin_wall(
    levels: Sequence[tuple[Plan, float]],
    thickness: float,
    sectors: int = 24,
    rim_rise: Callable[[np.ndarray], np.ndarray] | None = None,
    roll: float = 0.0,
) -> list[trimesh.Trimesh]:
    """A thin wall of convex sectors (see :func:`wall_sections`)."""
    return [hull(q) for q in wall_sections(levels, thickness, sectors, rim_rise, roll)]


def basin_floor(plan: Plan, z0: float, z1: float, sectors: int = 24) -> trimesh.Trimesh:
    """A solid slab with the outline ``plan`` from z0 to z1."""
    xy = plan.points(np.linspace(0.0, 2 * np.pi, sectors, endpoint=False))
    return hull(np.concatenate([np.column_stack([xy, np.full(len(xy), z)]) for z in (z0, z1)]))


def _ray_hit(poly: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Where the ray from c (inside the convex polygon ``poly``) along d leaves it."""
    best = np.inf
    for k in range(len(poly)):
        p, q = poly[k], poly[(k + 1) % len(poly)]
        e = q - p
        den = d[0] * (-e[1]) - d[1] * (-e[0])
        if abs(den) < 1e-15:
            continue
        w = p - c
        t = (w[0] * (-e[1]) - w[1] * (-e[0])) / den
        u = (d[0] * w[1] - d[1] * w[0]) / den
        if t > 0 and -1e-9 <= u <= 1 + 1e-9:
            best = min(best, t)
    return c + best * d


def block_around(
    poly: np.ndarray, bottom: tuple[Plan, float], top: tuple[Plan, float], sectors: int = 24
) -> list[trimesh.Trimesh]:
    """The solid between a straight-walled basin's inside (its outlines at the bottom and
    the top) and the vertical faces of the convex plan polygon ``poly`` (counter-clockwise),
    one piece per sector: the basin's inner edges, the polygon's boundary between the rays
    through them from the top's centre, and any polygon corner in between, from the
    basin's floor up to its rim. The floor under the basin is not included."""
    (pb, zb), (pt, zt) = bottom, top
    c = np.array([pt.cx, pt.cy])
    corner_ang = np.arctan2(poly[:, 1] - c[1], poly[:, 0] - c[0])
    A = sector_angles(sectors)
    inner_b = pb.points(A.ravel()).reshape(sectors, 2, 2)
    inner_t = pt.points(A.ravel()).reshape(sectors, 2, 2)
    parts = []
    for j in range(sectors):
        dirs = inner_t[j] - c
        ang = np.arctan2(dirs[:, 1], dirs[:, 0])
        span = (ang[1] - ang[0]) % (2 * np.pi)
        rim = [_ray_hit(poly, c, dirs[0]), _ray_hit(poly, c, dirs[1])]
        rim += [
            poly[i] for i in range(len(poly)) if 0 < (corner_ang[i] - ang[0]) % (2 * np.pi) < span
        ]
        rim_xy = np.array(rim)
        pts = [
            np.column_stack([inner_b[j], np.full(2, zb)]),
            np.column_stack([inner_t[j], np.full(2, zt)]),
        ]
        pts += [np.column_stack([rim_xy, np.full(len(rim_xy), z)]) for z in (zb, zt)]
        parts.append(hull(np.concatenate(pts)))
    return parts


def _fit(plan: Plan, poly: np.ndarray, margins: np.ndarray) -> float:
    """The largest scale of ``plan`` about its centre that keeps it at least ``margins``
    (one per polygon edge) inside the convex polygon (counter-clockwise)."""
    xy = plan.points(np.linspace(0.0, 2 * np.pi, 64, endpoint=False))
    c = np.array([plan.cx, plan.cy])
    v = xy - c
    s = np.inf
    for k in range(len(poly)):
        p, q = poly[k], poly[(k + 1) % len(poly)]
        e = (q - p) / np.linalg.norm(q - p)
        nrm = np.array([e[1], -e[0]])  # outward normal of a counter-clockwise polygon
        room = (p - c) @ nrm - margins[k]  # distance from the centre to the shrunk edge
        reach = v @ nrm
        if reach.max() > 0:
            s = min(s, room / reach.max())
    return float(s)


def _taps(x: float, y: float, z: float, toward: float, size: float) -> list[trimesh.Trimesh]:
    """A mixer standing at (x, y) on a deck at height z: a spout on a stem, arching over
    towards ``toward`` (the sign of y it reaches to), between two handles along x."""
    r = float(np.clip(0.06 * size, 0.0018, 0.0026))
    h = float(np.clip(0.1 * size, 0.008, 0.013))
    reach = 1.1 * h
    parts = [cylinder(1.25 * r, z - 0.001, z + 0.003, sections=12, center=(x, y))]
    path = [
        [x, y, z + 0.002],
        [x, y, z + h],
        [x, y + toward * 0.5 * reach, z + 1.15 * h],
        [x, y + toward * reach, z + 0.9 * h],
        [x, y + toward * reach, z + 0.65 * h],
    ]
    parts += tube(path, r, sections=8)
    for s in (-1.0, 1.0):
        hx = x + s * 3.2 * r
        parts.append(cylinder(r, z - 0.001, z + 0.35 * h, sections=10, center=(hx, y)))
        parts.append(
            cylinder(1.4 * r, z + 0.35 * h, z + 0.35 * h + 0.002, sections=10, center=(hx, y))
        )
    return parts


@register_category(
    "bathtub",
    params={
        "style": Choice(
            ("built_in", "corner", "freestanding", "clawfoot"), p=(0.33, 0.14, 0.28, 0.25)
        ),
        "length": Uniform(0.1, 0.165),  # y
        # length / width; at least 1.8 so that no tub is nearly 4-fold, also on the ood split
        "aspect": Uniform(1.8, 2.4, ood=(1.8, 2.7)),
        "height": Uniform(0.26, 0.36),  # rim height / length (feet included)
        "wall": Uniform(0.0024, 0.0036),
        "squareness": Uniform(2.0, 4.5),  # the plan's superellipse exponent
        "ends": Choice(("double", "single"), p=(0.45, 0.55)),
        "backrest": Uniform(0.5, 1.0),  # how strongly a single end differs
        "belly": Uniform(0.72, 0.88),  # the bottom's scale / the rim's
        "depth": Uniform(0.72, 0.9),  # a block's basin depth / its height
        "deck": Uniform(0.004, 0.009),  # a block's narrowest deck
        "setback": Uniform(0.004, 0.012),  # a block's extra deck along the wall
        "apron_panel": Flag(0.5),
        "corner_depth": Uniform(0.62, 0.9),  # a corner tub's depth / length
        "corner_cut": Uniform(0.4, 0.6),  # the chamfer / the depth
        "plinth": Flag(0.5),  # freestanding
        "foot_height": Uniform(0.14, 0.26),  # clawfoot: / the height
        "roll": Uniform(1.1, 1.7),  # a clawfoot rim's roll radius / the wall
        "end_rise": Uniform(0.0, 0.2),  # a clawfoot rim swept up at both ends / the height
        "taps": Flag(0.5),
    },
    shapenet_synsets=("02808440",),
    modelnet_names=("bathtub",),
)
def build(p: Params) -> Assembly:
    """Bathtub (20 parameters: built-in, corner, freestanding or clawfoot; length, aspect,
    height, wall, plan squareness; single or double ends and the backrest's strength;
    belly; a block's basin depth, deck, setback and apron panel; a corner tub's depth and
    chamfer; plinth; clawfoot feet height, rim roll and end rise; taps)."""
    style = str(p["style"])
    L = float(p["length"])
    W = L / max(float(p["aspect"]), 1.8)
    H = float(np.clip(float(p["height"]), 0.18, 0.45)) * L
    t = float(np.clip(float(p["wall"]), 0.0022, 0.005))
    n = float(np.clip(float(p["squareness"]), 2.0, 6.0))
    single = p["ends"] == "single"
    br = float(np.clip(float(p["backrest"]), 0.2, 1.2)) if single else 0.0
    belly = float(np.clip(float(p["belly"]), 0.6, 0.92))
    taps = bool(p["taps"])
    S = _SECTORS
    if style in ("built_in", "corner"):
        return _block_tub(p, style, L, W, H, n, br, belly, taps, S)

    # --- a shell: bottom, lower belly, rim; a backrest makes the plan an egg and moves
    # the bottom towards the drain
    clawfoot = style == "clawfoot"
    if clawfoot:
        n = min(n, 3.2)  # claw-foot tubs have rounded ends
    z_b = float(np.clip(float(p["foot_height"]), 0.08, 0.35)) * H if clawfoot else 0.0
    plinth = not clawfoot and bool(p["plinth"])
    if plinth:
        z_b = float(np.clip(0.12 * H, 0.004, 0.008))
    rr = float(np.clip(float(p["roll"]), 0.8, 2.0)) * t if clawfoot else 0.0
    # the rim's outline: the outer width includes a clawfoot's roll
    top = Plan(W / 2 - rr, L / 2 - rr, n, 0.12 * br)
    # the bottom moves towards the drain, never so far that the wall overhangs there
    shift = br * min(0.1, 0.97 - belly) * top.ay
    levels = [
        (top.scaled(belly, dy=shift), z_b),
        (top.scaled(0.5 + 0.5 * belly, dy=0.6 * shift), z_b + 0.3 * (H - z_b)),
        (top, H - rr),
    ]
    rise_ends = float(np.clip(float(p["end_rise"]), 0.0, 0.3)) * H if clawfoot else 0.0

    def rim_rise(theta: np.ndarray) -> np.ndarray:
        v = np.sin(theta)  # -1 at the -y end
        return rise_ends * v**4 + 0.22 * br * H * np.maximum(-v, 0.0) ** 3

    # a clawfoot's rim is rolled: the roll's axis runs round the wall's top outline
    parts = basin_wall(levels, t, S, rim_rise, roll=rr)
    floor_t = float(np.clip(1.2 * t, 0.003, 0.005))
    parts.append(basin_floor(levels[0][0], z_b, z_b + floor_t, S))
    top_z = H - rr

    if clawfoot:
        # four feet: a tapering leg from under the bottom's edge out to a ball on the floor
        base = levels[0][0]
        fr = float(np.clip(0.1 * W, 0.003, 0.006))
        # by the ends of the long axis, symmetric end to end and side to side
        for u in (np.pi / 2 - 0.55, np.pi / 2 + 0.55, -np.pi / 2 - 0.55, -np.pi / 2 + 0.55):
            edge = base.points(u)[0]
            inward = np.array([base.cx, base.cy]) - edge
            inward /= np.linalg.norm(inward)
            tip = edge - 0.6 * fr * inward  # splayed outwards
            top_c = edge + 1.2 * fr * inward
            q = np.linspace(0, 2 * np.pi, 8, endpoint=False)
            ring_top = np.column_stack(
                [
                    top_c[0] + fr * np.cos(q),
                    top_c[1] + fr * np.sin(q),
                    np.full(8, z_b + 0.6 * floor_t),
                ]
            )
            ring_bot = np.column_stack(
                [
                    tip[0] + 0.55 * fr * np.cos(q),
                    tip[1] + 0.55 * fr * np.sin(q),
                    np.full(8, 0.8 * fr),
                ]
            )
            parts.append(hull(np.concatenate([ring_top, ring_bot])))
            parts.append(ellipsoid((tip[0], tip[1], 0.8 * fr), (0.8 * fr,) * 3, 1))
    elif plinth:
        # a plinth set in from the bottom's edge, reaching into the floor
        parts.append(basin_floor(levels[0][0].scaled(0.86), 0.0, z_b + 0.5 * floor_t, S))

    if taps:
        # a tap ledge across the +y end, inside the rim's outline (through the middle of
        # the wall or the roll), level with the rim's lowest point along it; the mixer on
        # it. The ledge grows until it and the mixer hold _MIN_TAP_SHARE of the tub's
        # volume: a narrow oval end would otherwise leave the tub nearly 2-fold.
        rest = float(sum(q.volume for q in parts))
        a = np.linspace(np.pi / 2 - 1.5, np.pi / 2 + 1.5, 61)
        inset = 0.0 if clawfoot else t / 2
        xy = top.points(a, inset, inset)
        for grow in np.linspace(0.0, 1.0, 6):
            ledge = float(np.clip((0.11 + 0.13 * grow) * L, 0.011, 0.04))
            y_cut = float(xy[:, 1].max()) - ledge
            keep = xy[:, 1] >= y_cut
            ends = xy[keep][[0, -1]]
            ends[:, 1] = y_cut  # the ledge's straight inner edge
            zt = top_z + rr + float(rim_rise(a[keep]).min())
            zl = zt - float(np.clip((1.6 + 1.2 * grow) * t, 0.004, 0.008))
            outline = np.concatenate([xy[keep], ends])
            shelf = hull(
                np.concatenate(
                    [np.column_stack([outline, np.full(len(outline), z)]) for z in (zl, zt)]
                )
            )
            mixer = _taps(0.0, y_cut + min(ledge / 2, 0.008), zt, -1.0, L)
            extra = shelf.volume + sum(q.volume for q in mixer)
            if extra >= _MIN_TAP_SHARE * (rest + extra):
                break
        parts += [shelf, *mixer]

    symmetric = not single and not taps
    return Assembly(parts, cyclic_z(2) if symmetric else no_symmetry())


def _block_tub(
    p: Params,
    style: str,
    L: float,
    W: float,
    H: float,
    n: float,
    br: float,
    belly: float,
    taps: bool,
    S: int,
) -> Assembly:
    """A built-in or corner tub: a block (its plan a rectangle, or one with its front
    corner at -y chamfered) with the basin hollowed out of it, an apron lip at the front."""
    deck = float(np.clip(float(p["deck"]), 0.003, 0.015))
    setback = float(np.clip(float(p["setback"]), 0.002, 0.02))
    tap_deck = max(deck, 0.011) if taps else deck
    if style == "corner":
        D = float(np.clip(float(p["corner_depth"]), 0.5, 1.0)) * L
        cut = float(np.clip(float(p["corner_cut"]), 0.25, 0.7)) * D
        poly = np.array(
            [
                [-D / 2, -L / 2],
                [D / 2 - cut, -L / 2],
                [D / 2, -L / 2 + cut],
                [D / 2, L / 2],
                [-D / 2, L / 2],
            ]
        )
        margins = np.array([deck, deck, deck, tap_deck, deck + setback])
        # an oval turned towards the chamfer, centred on the polygon's centroid
        c = poly.mean(axis=0)
        rot = -0.35 * np.arctan2(cut, cut)  # a fraction of the chamfer's 45-degree turn
        plan = Plan(0.5 * D, 0.5 * L, min(n, 3.0), 0.12 * br, c[0], c[1], rot)
        s = _fit(plan, poly, margins)
        top = plan.scaled(s)
    else:
        D = W
        poly = np.array([[-D / 2, -L / 2], [D / 2, -L / 2], [D / 2, L / 2], [-D / 2, L / 2]])
        x0, x1 = -D / 2 + deck + setback, D / 2 - deck
        y0, y1 = -L / 2 + deck, L / 2 - tap_deck
        ax, ay = (x1 - x0) / 2, (y1 - y0) / 2
        # an egg is wider than ax at the backrest end: keep it inside the deck
        top = Plan(ax, ay, n, 0.12 * br, (x0 + x1) / 2, (y0 + y1) / 2)
        xy = top.points(np.linspace(0.0, 2 * np.pi, 96, endpoint=False))
        top.ax *= ax / float(np.abs(xy[:, 0] - top.cx).max())
    depth = float(np.clip(float(p["depth"]), 0.5, 0.92)) * H
    z_f = H - depth
    shift = br * min(0.1, 0.97 - belly) * top.ay
    parts = block_around(poly, (top.scaled(belly, dy=shift), z_f), (top, H), S)
    parts.append(
        hull(
            np.concatenate(
                [np.column_stack([poly, np.full(len(poly), z)]) for z in (0.0, z_f + 0.0005)]
            )
        )
    )
    # the apron: a lip overhanging the front face under the deck's edge, and optionally a
    # raised panel on the face below it
    lip = float(np.clip(0.1 * H, 0.003, 0.005))
    front = [
        (k, poly[k], poly[(k + 1) % len(poly)])
        for k in range(len(poly))
        if poly[k][0] > -D / 2 + 1e-9 and poly[(k + 1) % len(poly)][0] > -D / 2 + 1e-9
    ]
    fronts = {k for k, _, _ in front}
    m_k = len(poly)
    ex = 0.0025  # how far the lip stands out
    for k, a0, a1 in front:
        e = (a1 - a0) / np.linalg.norm(a1 - a0)
        nrm = np.array([e[1], -e[0]])
        # along a run of front faces the lips reach past their ends to meet at the corner
        b0 = a0 - (ex * e if (k - 1) % m_k in fronts else 0.0)
        b1 = a1 + (ex * e if (k + 1) % m_k in fronts else 0.0)
        q = [b0 - 0.002 * nrm, b1 - 0.002 * nrm, b1 + ex * nrm, b0 + ex * nrm]
        parts.append(hull([[x, y, z] for x, y in q for z in (H - lip, H)]))
        if p["apron_panel"] and abs(e[1]) > 0.99:
            # a raised panel 1.8 mm proud of the face, inset from its ends and edges
            m = float(np.clip(0.08 * L, 0.005, 0.01))
            lo, hi = min(a0[1], a1[1]) + m, max(a0[1], a1[1]) - m
            z0, z1 = 0.006, H - lip - 0.004
            parts.append(
                box(
                    (0.0028, hi - lo, z1 - z0),
                    center=(a0[0] + 0.0004, (lo + hi) / 2, (z0 + z1) / 2),
                )
            )
    if taps:
        xy = top.points(np.linspace(0.0, 2 * np.pi, 96, endpoint=False))
        k = int(np.argmax(xy[:, 1]))
        parts += _taps(float(xy[k, 0]), (xy[k, 1] + L / 2) / 2, H, -1.0, L)
    return Assembly(parts, no_symmetry())
