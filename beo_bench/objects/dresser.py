"""Dresser: a chest of drawers - a carcass with 2-12 drawers in 1-3 columns under a top.

Three forms, by height over width: low wide dressers (often three columns of drawers, and
optionally a mirror in a moulded frame, rectangular or arched, on posts at the back edge of
the top), chests about as tall as wide (but never within 7 % of square in elevation), and
tall narrow chests (one column). A one-column chest may have its top row split into two or
three small drawers (the "2 over 3" of real chests). Drawers are graduated (deeper towards
the floor) and are either overlay fronts with grooves between them or fronts recessed in a
face frame; their pulls are knobs, bars or notches cut into the fronts' top edges. The
carcass stands on a plinth with a toe kick, on four legs (square, tapered or round), or on
bracket feet. Built by :mod:`beo_bench.objects.cabinet`, which the night stand shares: a
small two-drawer dresser is close to a night stand (ModelNet10's classes overlap in shape,
not only in name). ShapeNet has no dresser synset; its cabinets (02933112) are the
nearest.

The dresser faces +x and rests on z = 0, long along y. Its back is flat (it stands against a
wall): the top overhangs the fronts by 3-7 mm and the sides by 60 % of that, but not the
back; the fronts (1.6-3 mm) and pulls stand proud of the front face, a plinth is set back
at the front only, and a mirror stands at the back. So a half turn about z moves all of
that to the wrong side, and a dresser has no rotational symmetry (about the bounding-box
centre the half turn keeps a volume IoU of at most about 0.9). The difference is a few
millimetres of surface relief, as on real dressers: in volume the closed case is close to
its half turn about the vertical axis through its centre of mass (IoU up to about 0.99).
Its plan is at least 1.3 times as wide as deep, so a quarter turn is no symmetry either.
It is picked across its depth (under 7.5 cm) or by the mirror frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from beo_bench.geometry import no_symmetry
from beo_bench.objects.cabinet import (
    EMBED,
    Band,
    Block,
    FrontStyle,
    along,
    block,
    bracket_feet,
    cabinet,
    corner_legs,
    lowest_front,
    plinth,
    top_slab,
)
from beo_bench.objects.params import Choice, Flag, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly, hull, tube
from beo_bench.objects.registry import register_category

# Height (floor to the top's upper face) over the carcass's width of each form. A chest
# is never within 7 % of square in elevation: a quarter turn about the front axis (the
# chest on its side) would be nearly a symmetry of its volume.
FORMS = {"low": [(0.45, 0.78)], "chest": [(0.78, 0.93), (1.07, 1.25)], "tall": [(1.3, 1.8)]}
# The most drawer columns a form has (a tall chest is one column of drawers).
MAX_COLUMNS = {"low": 3, "chest": 2, "tall": 1}
# Support height / total height (below the mirror), by support.
SUPPORT_HEIGHT = {"plinth": (0.05, 0.12), "legs": (0.1, 0.28), "bracket": (0.07, 0.16)}
MIN_DRAWER = 0.011  # the lowest drawer front (m): a groove and a pull still fit
MAX_DRAWER = 0.03  # the deepest (30 cm in real size)
MIRROR_TUBE = 0.0018  # radius of the mirror frame's round moulding
MIRROR_GAP = 0.003  # between the top and the mirror frame


@register_category(
    "dresser",
    params={
        # largest extent: the width or the height; its lower third is a large night stand's
        # (night_stand.py reaches 0.115 m)
        "size": Uniform(0.08, 0.155),
        "form": Choice(("low", "chest", "tall"), p=(0.45, 0.3, 0.25)),
        "proportion": Uniform(0.0, 1.0),  # height / width within the form's range
        # / width (the carcass is 3-6 cm deep); with its top and fronts a small chest is as
        # deep for its width (up to about 0.75) as a shallow night stand
        "depth": Uniform(0.35, 0.65),
        "columns": Integer(1, 3),  # at most MAX_COLUMNS of the form
        "rows": Integer(2, 6),  # as many as fit at MIN_DRAWER, at most 12 drawers
        "top_split": Flag(0.4),  # one column: the top row split into 2-3 small drawers
        "graduation": Uniform(0.0, 0.6),  # how much deeper the bottom drawer is than the top
        "front_style": Choice(("overlay", "framed"), p=(0.6, 0.4)),
        "front_thickness": Uniform(0.0016, 0.003),  # how far fronts stand proud
        "handle": Choice(("knob", "bar", "recessed")),
        "support": Choice(("plinth", "legs", "bracket")),
        "support_height": Uniform(0.0, 1.0),  # within SUPPORT_HEIGHT of the support
        "leg_style": Choice(("square", "tapered", "round")),
        "top_thickness": Uniform(0.003, 0.007),
        "overhang": Uniform(0.003, 0.007),  # top beyond the fronts (sides: 60 %)
        "top_edge": Choice(("square", "bevel")),
        "mirror": Flag(0.45),  # on low dressers only
        "mirror_height": Uniform(0.6, 1.1),  # / the dresser's height
        "mirror_width": Uniform(0.5, 0.85),  # / the dresser's width
        "mirror_shape": Choice(("rect", "arched")),
    },
    shapenet_synsets=("02933112",),
    modelnet_names=("dresser",),
)
def build(p: Params) -> Assembly:
    """Dresser (21 parameters: size, form and proportion, depth; drawer columns, rows, top
    split, graduation; front style and thickness, handle; support, its height, leg style;
    top thickness, overhang and edge; mirror, its height, width and shape)."""
    q = plan(p)
    case, D, H, t = q.case, q.case.depth, q.H, q.t
    parts = cabinet(case, q.bands, q.style)
    x_front = D / 2 + q.style.thickness + q.style.frame_proud  # the fronts' (or frame's) face

    # --- top: flush at the back, over the fronts and sides
    bevel = min(0.0015, 0.4 * t) if p["top_edge"] == "bevel" else 0.0
    parts.append(top_slab(-D / 2, x_front + q.overhang, -q.W / 2, q.W / 2, H - t, t, bevel))

    # --- support
    support, sh, Wc = str(p["support"]), case.z0, case.width
    if support == "plinth":
        # a toe kick at the front, set in a little at the sides, flush at the back
        kick = float(np.clip(0.5 * sh, 0.002, 0.005))
        parts += plinth(case, kick, min(0.0015, 0.1 * Wc))
    elif support == "legs":
        lt = float(np.clip(0.09 * D, 0.004, 0.0065))
        parts += corner_legs(case, lt, str(p["leg_style"]), inset=0.0005)
    else:
        bt = 0.003
        parts += bracket_feet(
            case,
            sh,
            length_x=float(np.clip(0.3 * D, 0.007, 0.016)),
            length_y=float(np.clip(0.16 * Wc, 0.008, 0.02)),
            thickness=bt,
            proud=min(q.style.thickness, bt - 0.001),
        )

    if q.mirror:
        parts += _mirror(p, q.W, D, H, q.mirror)
    return Assembly(parts, no_symmetry())


@dataclass(frozen=True)
class Plan:
    """A dresser's main dimensions and its drawers, before any geometry is made."""

    W: float  # overall width (the top's)
    H: float  # floor to the top's upper face
    t: float  # top thickness
    overhang: float  # the top's overhang beyond the fronts
    mirror: float  # the mirror's height / H (0: no mirror)
    case: Block  # the carcass: front face at case.x1, on its support from case.z0
    style: FrontStyle
    bands: list[Band]  # rows of drawers from the bottom up

    @property
    def drawers(self) -> int:
        return sum(b.columns for b in self.bands if b.kind == "drawer")


def plan(p: Params) -> Plan:
    """The dimensions and drawer layout of the dresser with parameters ``p``."""
    form = str(p["form"])
    r = along(FORMS[form], float(p["proportion"]))  # height / the carcass's width
    mirror = bool(p["mirror"]) and form == "low"
    mk = float(p["mirror_height"]) if mirror else 0.0
    os_ = float(p["overhang"])
    side = 0.6 * os_  # the top's overhang at the sides
    # the largest extent is the width (the top's) or the height (with a mirror: in all)
    size = float(p["size"])
    Wc = min(size - 2 * side, size / r)
    if mirror:
        extra = MIRROR_GAP + 2 * MIRROR_TUBE  # above the top, besides the mirror itself
        Wc = min(Wc, (size - extra) / (r * (1.0 + mk)))
    W = Wc + 2 * side
    H = r * Wc
    framed = p["front_style"] == "framed"
    # the carcass: flush with the top at the back, the top overhanging the sides and the
    # fronts (an overhang of at least 3 mm keeps a half turn about z from matching the
    # bulk of the case with itself: see the module docstring); 3-6 cm deep
    D = float(np.clip(float(p["depth"]) * W, 0.03, 0.06))
    t = float(p["top_thickness"])
    slo, shi = SUPPORT_HEIGHT[str(p["support"])]
    sh = H * (slo + float(p["support_height"]) * (shi - slo))
    case = Block(-D / 2, D / 2, -Wc / 2, Wc / 2, sh, H - t + EMBED)

    # --- drawers: rows x columns (the top row maybe split), graduated towards the floor
    style = FrontStyle(
        kind="framed" if framed else "overlay",
        thickness=float(p["front_thickness"]),
        gap=0.0022 if framed else 0.0017,
        margin=0.0022 if framed else 0.0,
        frame_proud=0.0015 if framed else 0.0,
        handle=str(p["handle"]),
    )
    cols = min(int(p["columns"]), MAX_COLUMNS[form])
    usable = case.height - 2 * style.margin
    rows_fit = max(1, int((usable + style.gap) // (MIN_DRAWER + style.gap)))
    # no drawer deeper than MAX_DRAWER (or lower than MIN_DRAWER), at most 12 drawers
    rows_min = max(
        1 if cols > 1 else 2, int(np.ceil((usable + style.gap) / (MAX_DRAWER + style.gap)))
    )
    rows = int(np.clip(int(p["rows"]), rows_min, max(rows_min, min(rows_fit, 12 // cols))))
    split = 2 if Wc < 0.11 else 3
    split = split if cols == 1 and p["top_split"] else 0
    g = float(p["graduation"])
    bands = _bands(rows, cols, split, g)
    # graduated and split drawers are lower than the average: drop rows (then the split)
    # until the lowest front keeps MIN_DRAWER, keeping two drawers at least
    while lowest_front(case, bands, style) < MIN_DRAWER:
        if rows > (1 if cols > 1 else 2):
            rows -= 1
        elif split:
            split = 0
        else:
            break
        bands = _bands(rows, cols, split, g)
    return Plan(W, H, t, os_, mk, case, style, bands)


def _bands(rows: int, cols: int, split: int, g: float) -> list[Band]:
    """Rows of ``cols`` drawers from the bottom up, each ``g`` (at the bottom) to 0 (at
    the top) deeper than the top one, the top row split into ``split`` lower drawers when
    there are at least two rows."""
    bands = []
    for k in range(rows):
        wgt = 1.0 + g * (rows - 1 - k) / max(rows - 1, 1)
        if k == rows - 1 and split and rows >= 2:
            bands.append(Band("drawer", split, 0.75 * wgt))
        else:
            bands.append(Band("drawer", cols, wgt))
    return bands


def _mirror(p: Params, W: float, D: float, H: float, mk: float) -> list[trimesh.Trimesh]:
    """A mirror at the top's back edge: a glass panel in a round moulded frame (a tube
    along its outline, rectangular or with an arched top) held up by a post at each side."""
    rt = MIRROR_TUBE
    pw = 0.003  # posts' width
    mh = mk * H
    mw = float(np.clip(float(p["mirror_width"]) * W, 0.02, W - 2 * (rt + pw)))
    xm = -D / 2 + rt  # the frame's centre plane, its back flush with the dresser's
    z0 = H + MIRROR_GAP + rt  # bottom of the frame's centre line
    hw = mw / 2
    if p["mirror_shape"] == "arched":
        rise = min(0.35 * hw, 0.4 * mh)
        a = np.linspace(0.0, np.pi, 9)
        arc = [(hw * np.cos(q), z0 + mh - rise + rise * np.sin(q)) for q in a]
        outline = [(hw, z0), *arc, (-hw, z0)]
    else:
        outline = [(hw, z0), (hw, z0 + mh), (-hw, z0 + mh), (-hw, z0)]
    path = np.array([[xm, y, z] for y, z in [*outline, outline[0]]])
    parts = tube(path, rt, sections=8)
    # the glass: the outline's convex hull, thinner than the frame (so it looks set in)
    glass = np.array([[xm + dx, y, z] for y, z in outline for dx in (-0.7 * rt, 0.45 * rt)])
    parts.append(hull(glass))
    # posts from into the top up past the frame's mid-height, overlapping its sides
    ztop = z0 + 0.55 * mh
    for s in (-1, 1):
        yi = s * (hw + 0.4 * rt)
        ya, yb = sorted((yi, yi + s * pw))
        parts.append(block(-D / 2, -D / 2 + 2 * rt, ya, yb, H - EMBED - 0.001, ztop))
    return parts
