"""Table: a flat top (rectangular, square, round or oval) on legs or on a pedestal.

Legs are square, round or splayed posts under the top, inset from its edge; a rectangular
or square table may have an apron (a skirt under the top's edges) and a lower shelf, and a
rectangular one a drawer case under the top, with one to three drawer fronts
and knobs on both long sides (a through-drawer table, as farmhouse and library tables have):
a writing desk (desk.py) with its drawers on one side only is its nearest neighbour, as
ModelNet's desks are its tables'. A
pedestal is a central column on a disc or on feet. The top is a thin slab, so the table is
picked by the top's edge (or the pedestal). Close to a box when the legs are short and to a
stool with a round top (classes overlap in parts, as in ShapeNet).

The symmetry group follows the plan view: a round top on a pedestal with a disc base is
continuous about z; a round top on n legs or feet is n-fold; a square top (legs or a
four-footed pedestal) 4-fold; a rectangular or oval top 2-fold. The aspect of a
rectangular or oval top is at least 1.3 so that no instance is nearly 4-fold, and legs and
feet under a round top are kept thick enough to break its continuous symmetry visibly.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.geometry import axis_angle, continuous_symmetry, cyclic_z
from beo_bench.objects.params import Choice, Flag, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, cylinder, frustum, hull
from beo_bench.objects.registry import register_category

# Legs or feet under a round top hold at least this share of the top's volume, so that
# rotating the table by an angle outside its n-fold group changes it visibly (volume IoU
# below 0.95) instead of being nearly continuous.
_MIN_LEG_SHARE = 0.09


@register_category(
    "table",
    params={
        "top_shape": Choice(("rect", "square", "round", "oval"), p=(0.35, 0.15, 0.3, 0.2)),
        "top_size": Uniform(0.09, 0.16),  # length along x, or diameter
        # length / width of a rectangular or oval top; never near 1 (that would be nearly
        # 4-fold symmetric without being declared so), also on the ood split
        "aspect": Uniform(1.3, 1.9, ood=(1.3, 2.3)),
        "height": Uniform(0.06, 0.12),
        "top_thickness": Uniform(0.004, 0.012),
        "support": Choice(("legs", "pedestal"), p=(0.65, 0.35)),
        "legs": Integer(3, 4),  # legs or feet under a round top (4 under the others)
        "leg_style": Choice(("square", "round", "splayed")),
        "leg_thickness": Uniform(0.004, 0.01),
        "leg_inset": Uniform(0.03, 0.2),  # / half the top size, from the edge
        "apron": Flag(0.5),
        "shelf": Flag(0.25),
        "pedestal_radius": Uniform(0.005, 0.012),
        "base_style": Choice(("disc", "feet")),
        "base_radius": Uniform(0.3, 0.45),  # / top size
        # a rectangular table on legs may have a drawer case under its top (a farmhouse or
        # writing table; its long sides are the apron there): close to desk.py's writing desk
        "drawer_case": Flag(0.6),
        "drawers": Integer(1, 3),  # drawer fronts along each long side
        "drawer_height": Uniform(0.16, 0.26),  # the case's height / the table's
    },
    shapenet_synsets=("04379243",),
    modelnet_names=("table",),
)
def build(p: Params) -> Assembly:
    """Table (18 parameters: top shape, size, aspect, thickness; height; legs or pedestal;
    leg count, style, thickness, inset; apron; shelf; pedestal radius, base style and
    radius; a drawer case, its drawer count and height)."""
    shape = str(p["top_shape"])
    size, h = float(p["top_size"]), float(p["height"])
    tt = float(np.clip(float(p["top_thickness"]), 0.002, 0.25 * h))
    aspect = float(p["aspect"]) if shape in ("rect", "oval") else 1.0
    hx, hy = size / 2, size / 2 / aspect  # half extents of the top
    z_under = h - tt  # underside of the top
    z_in = h - 0.5 * tt  # supports reach half-way into the top
    round_top = shape == "round"
    n = int(p["legs"]) if round_top else 4

    if round_top or shape == "oval":
        top = frustum(hx, hx, z_under, h, sections=48, scale=(1.0, 1.0 / aspect))
    else:
        top = box((2 * hx, 2 * hy, tt), center=(0.0, 0.0, h - tt / 2))
    parts = [top]

    if p["support"] == "pedestal":
        pr = float(np.clip(float(p["pedestal_radius"]), 0.003, 0.4 * hy))
        br = float(np.clip(float(p["base_radius"]) * size, 2 * pr, 0.95 * hx))
        bh = float(np.clip(0.08 * h, 0.004, 0.008))  # base thickness
        parts.append(cylinder(pr, 0.5 * bh, z_in, sections=24))
        if p["base_style"] == "disc":
            parts.append(frustum(br, 0.8 * br, 0.0, bh, sections=48))
            if round_top:
                return Assembly(parts, continuous_symmetry())
            return Assembly(parts, cyclic_z(4 if shape == "square" else 2))
        # feet: n tapered spokes from a hub, at least fw wide and high; under a round top
        # they hold _MIN_LEG_SHARE of the rest's volume (a spoke is about 0.8 br fw^2)
        parts.append(cylinder(1.3 * pr, 0.0, 1.5 * bh, sections=24))
        fw = 1.2 * pr
        if round_top:
            rest = sum(q.volume for q in parts)
            fw = max(fw, float(np.sqrt(_MIN_LEG_SHARE * rest / (0.8 * n * br))))
        fw = min(fw, 0.5 * br)
        fh = max(bh, fw)
        for k in range(n):
            Rz = axis_angle([0.0, 0.0, 1.0], 2 * np.pi * k / n)
            pts = np.array(
                [
                    [x, sy * fw / 2, z]
                    for x, zt in ((0.0, fh), (br, 0.6 * fh))
                    for sy in (-1, 1)
                    for z in (0.0, zt)
                ]
            )
            parts.append(hull(pts @ Rz.T))
        return Assembly(parts, cyclic_z(n if round_top else (4 if shape == "square" else 2)))

    # --- legs
    style = str(p["leg_style"])
    lt = float(np.clip(float(p["leg_thickness"]), 0.002, 0.3 * hy))
    if round_top:
        # thick enough that the legs hold _MIN_LEG_SHARE of the top's volume (a leg's
        # volume is about fill * lt^2 * height)
        fill = {"square": 1.0, "round": np.pi / 4, "splayed": 0.73}[style]
        lt = max(lt, float(np.sqrt(_MIN_LEG_SHARE * top.volume / (fill * n * z_in))))
    inset = float(np.clip(float(p["leg_inset"]), 0.0, 0.4))
    if shape in ("rect", "square"):
        # legs under the corners, inset from both edges by the same distance
        m = inset * hy + lt / 2
        feet_xy = [(sx * (hx - m), sy * (hy - m)) for sx in (-1, 1) for sy in (-1, 1)]
    elif shape == "oval":
        # on the ellipse shrunk by the inset, towards the ends of the long axis
        c, s = 0.8, 0.6
        feet_xy = [
            (sx * c * (hx * (1 - inset) - lt), sy * s * (hy * (1 - inset) - lt))
            for sx in (-1, 1)
            for sy in (-1, 1)
        ]
    else:
        rr = hx * (1 - inset) - lt / 2
        a0 = np.pi / 4 if n == 4 else 0.0
        feet_xy = [
            (rr * np.cos(a0 + 2 * np.pi * k / n), rr * np.sin(a0 + 2 * np.pi * k / n))
            for k in range(n)
        ]
    splay = 0.12 * h if style == "splayed" else 0.0

    def leg_at(xy: tuple[float, float], z: float) -> np.ndarray:
        """Centre of a leg at height z (splayed legs move outwards towards the floor)."""
        v = np.array(xy)
        out = v / np.linalg.norm(v) * splay * (1.0 - z / z_in)
        return np.array([*(v + out), z])

    for xy in feet_xy:
        # under a round top each leg turns with its polar angle, so the n-fold rotation
        # maps leg onto leg exactly
        Rz = axis_angle([0.0, 0.0, 1.0], float(np.arctan2(xy[1], xy[0])) if round_top else 0.0)
        sq = np.array([[u, v, 0.0] for u in (-0.5, 0.5) for v in (-0.5, 0.5)]) @ Rz.T
        if style == "round":
            parts.append(cylinder(lt / 2, 0.0, z_in, sections=12, center=xy))
        else:
            b = leg_at(xy, 0.0)
            bottom = 0.7 if style == "splayed" else 1.0
            parts.append(
                hull(np.concatenate([[xy[0], xy[1], z_in] + lt * sq, b + bottom * lt * sq]))
            )

    if shape in ("rect", "square"):
        lx, ly = abs(feet_xy[0][0]), abs(feet_xy[0][1])
        if p["apron"]:
            # a skirt between the legs' outer faces, hanging under the top
            ah = float(np.clip(0.15 * h, 0.005, 0.015)) + 0.5 * tt  # up into the top
            at = 0.5 * lt
            za = z_in - ah / 2
            for s in (-1, 1):
                parts.append(box((2 * lx, at, ah), center=(0.0, s * (ly + lt / 2 - at / 2), za)))
                parts.append(box((at, 2 * ly, ah), center=(s * (lx + lt / 2 - at / 2), 0.0, za)))
        if shape == "rect" and p["drawer_case"]:
            parts += _drawer_case(p, lx, ly, lt, h, tt, z_in)
        if p["shelf"]:
            # a thin board low between the legs, reaching to the legs' centre lines
            zs = 0.25 * h
            corner = leg_at(feet_xy[3], zs)
            st = float(np.clip(0.6 * tt, 0.002, 0.006))
            parts.append(box((2 * corner[0], 2 * corner[1], st), center=(0.0, 0.0, zs)))

    sym = cyclic_z(n) if round_top else cyclic_z(4 if shape == "square" else 2)
    return Assembly(parts, sym)


_FRONT = 0.002  # drawer fronts stand this far out of the apron (a depth camera sees it)
_GAP = 0.0018  # groove between neighbouring fronts
_E = 0.0006  # overlap of parts that meet, so that their union is one solid


def _drawer_case(
    p: Params, lx: float, ly: float, lt: float, h: float, tt: float, z_in: float
) -> list[trimesh.Trimesh]:
    """A drawer case between the legs, under the top, with ``drawers`` fronts and knobs on
    each long side (+y and -y). The fronts of the two sides are each other's images under
    the half turn about z, so the table keeps its declared 2-fold group."""
    dh = float(np.clip(float(p["drawer_height"]) * h, 0.008, 0.35 * h))
    yf = ly + lt / 2  # the legs' outer faces: the case's, and the apron's, long sides
    z0 = z_in - dh
    parts = [box((2 * lx, 2 * yf - _E, dh), center=(0.0, 0.0, z0 + dh / 2))]
    n = int(p["drawers"])
    span = 2 * lx - lt  # between the legs' inner faces
    w = (span - (n - 1) * _GAP) / n
    fz0, fz1 = z0 + 0.0012, z_in - 0.5 * tt - 0.0012  # the fronts end under the top
    knob = float(np.clip(0.25 * (fz1 - fz0), 0.0022, 0.004))
    for s in (-1, 1):
        for k in range(n):
            xc = -span / 2 + w / 2 + k * (w + _GAP)
            parts.append(
                box(
                    (w, _FRONT + _E, fz1 - fz0),
                    center=(xc, s * (yf + (_FRONT - _E) / 2), (fz0 + fz1) / 2),
                )
            )
            parts.append(
                box(
                    (knob, knob + _E, knob),
                    center=(xc, s * (yf + _FRONT + (knob - _E) / 2), (fz0 + fz1) / 2),
                )
            )
    return parts
