"""Night stand: a small bedside case - a little chest of drawers, a small table with a
drawer, or a cabinet with a door.

Three styles, as in ModelNet's night stands:

- ``drawers``: a small dresser (:mod:`beo_bench.objects.dresser` shares the geometry,
  :mod:`beo_bench.objects.cabinet`): one to three drawers, maybe with an open niche above
  or below them, on a plinth, four legs or bracket feet. At its large end it is a
  two- or three-drawer dresser: the classes overlap in shape.
- ``table``: a top on four corner legs with one drawer in a case under the top and an open
  shelf low between the legs; the shelf space is open at the front only (closed by a back
  panel, or boxed in by a back and two sides) or open all round.
- ``cabinet``: one door (hinged on either side) under a drawer or an open niche, or alone,
  on the same supports as the drawers style.

The night stand faces +x and rests on z = 0. It stands against a wall, so its back is
flat: the top overhangs the front by 3-6 mm and the sides and the back by less (a case's
top is flush at the back), the fronts and pulls stand proud of the front face, a plinth is
set back at the front only. The known trap is the table style: open between its legs, its
only front/back difference could be a thin drawer front. Here its frame of legs sits back
from the top's front edge by the overhang and the proud drawer front, off-centre under the
top, and its shelf space is closed at the back (a back panel, or a box of back and sides)
or, open all round, its shelf stops short of the front legs. So a half turn about z is no
symmetry of a table night stand, about the bounding-box centre or about the vertical axis
through its centre of mass (IoU below 0.95 either way). A case style differs from its back
as a dresser does, by a few millimetres of fronts, pulls, overhang and toe kick (IoU about
its bounding-box centre below about 0.92, about its centre of mass up to about 0.99, as
real night stands). The plan is at least 1.15 times as wide as deep, ruling out quarter
turns: a night stand has no rotational symmetry. It is picked across its depth or by the
top's edge.
"""

from __future__ import annotations

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
    fronts,
    layout_panels,
    lowest_front,
    plinth,
    top_slab,
)
from beo_bench.objects.params import Choice, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly
from beo_bench.objects.registry import register_category

# Height over the body's width: lower or taller than square, never nearly square.
PROPORTIONS = [(0.8, 0.92), (1.08, 1.35)]
MIN_DRAWER = 0.011  # the lowest drawer front (m), as the dresser's
# Support height / total height, by support (as the dresser's, but legs may be longer).
SUPPORT_HEIGHT = {"plinth": (0.05, 0.12), "legs": (0.1, 0.3), "bracket": (0.07, 0.16)}


@register_category(
    "night_stand",
    params={
        "style": Choice(("drawers", "table", "cabinet"), p=(0.45, 0.3, 0.25)),
        # largest extent: the height or the width; its upper third is a small dresser's
        # (dresser.py starts at 0.08 m), as real two- and three-drawer chests are
        "size": Uniform(0.062, 0.115),
        "proportion": Uniform(0.0, 1.0),  # height / width, along PROPORTIONS
        # overall (top and fronts) / width; a deep night stand is 0.85, a shallow one 0.55,
        # as deep for its width as a small dresser (dresser.py: up to about 0.75)
        "depth": Uniform(0.55, 0.85),
        "drawers": Integer(1, 3),  # drawers style: the count; cabinet: >1 puts one above
        "niche": Choice(("none", "top", "bottom"), p=(0.55, 0.3, 0.15)),
        "graduation": Uniform(0.0, 0.5),  # how much deeper the bottom drawer is
        "front_style": Choice(("overlay", "framed"), p=(0.65, 0.35)),
        "front_thickness": Uniform(0.0016, 0.003),
        "handle": Choice(("knob", "bar", "recessed")),
        "hinge": Choice(("left", "right")),  # the door's hinged side
        "support": Choice(("plinth", "legs", "bracket")),
        "support_height": Uniform(0.0, 1.0),  # within SUPPORT_HEIGHT of the support
        "leg_style": Choice(("square", "tapered", "round")),
        "leg_thickness": Uniform(0.0035, 0.006),  # table style
        "drawer_height": Uniform(0.18, 0.3),  # table style: the drawer case / height
        "shelf_height": Uniform(0.12, 0.3),  # table style: the shelf / height
        "shelf_enclosure": Choice(("open", "back", "boxed")),  # table style
        "top_thickness": Uniform(0.003, 0.006),
        "overhang": Uniform(0.003, 0.006),  # beyond the fronts (sides: 60 %)
        "top_edge": Choice(("square", "bevel")),
    },
    # ShapeNet has no night-stand synset; its cabinets (02933112) go to the dresser (a
    # synset names one category: the first registered one claiming it)
    shapenet_synsets=(),
    modelnet_names=("night_stand",),
)
def build(p: Params) -> Assembly:
    """Night stand (21 parameters: style, size, proportion, depth; drawer count, niche,
    graduation; front style and thickness, handle, door hinge; support, its height, leg
    style and thickness; table style's drawer case height, shelf height and enclosure;
    top thickness, overhang and edge)."""
    table = p["style"] == "table"
    # height over the body's width (the carcass's, or the table's frame of legs), not
    # within 8 % of square, where a quarter turn about the front axis (on its side) would
    # nearly match the volume with itself
    r = along(PROPORTIONS, float(p["proportion"]))
    os_ = float(p["overhang"])
    side = (0.4 if table else 0.6) * os_  # the top's overhang at the sides
    size = float(p["size"])
    Wb = min(size - 2 * side, size / r)  # the largest extent: the top's width or the height
    W = Wb + 2 * side
    H = r * Wb
    D = float(np.clip(float(p["depth"]) * W, 0.035, 0.075))  # the top's depth in all
    t = float(p["top_thickness"])
    bevel = min(0.0015, 0.4 * t) if p["top_edge"] == "bevel" else 0.0
    ft = float(p["front_thickness"])
    if p["style"] == "table":
        parts = _table(p, W, D, H, t, bevel, ft, os_)
    else:
        parts = _case(p, W, D, H, t, bevel, ft, os_)
    return Assembly(parts, no_symmetry())


def _case(
    p: Params, W: float, D: float, H: float, t: float, bevel: float, ft: float, os_: float
) -> list[trimesh.Trimesh]:
    """The drawers and cabinet styles: a small carcass with fronts on a support."""
    framed = p["front_style"] == "framed"
    fp = 0.0015 if framed else 0.0
    Wc = W - 2 * 0.6 * os_
    support = str(p["support"])
    slo, shi = SUPPORT_HEIGHT[support]
    sh = H * (slo + float(p["support_height"]) * (shi - slo))
    # the carcass: the top's depth less its overhang and the fronts
    D = D - os_ - ft - fp
    case = Block(-D / 2, D / 2, -Wc / 2, Wc / 2, sh, H - t + EMBED)
    style = FrontStyle(
        kind="framed" if framed else "overlay",
        thickness=ft,
        gap=0.002 if framed else 0.0017,
        margin=0.002 if framed else 0.0,
        frame_proud=fp,
        handle=str(p["handle"]),
        hinge=1 if p["hinge"] == "left" else -1,
    )
    n = int(p["drawers"])
    niche = str(p["niche"])
    g = float(p["graduation"])
    bands = _bands(str(p["style"]), n, niche, g)
    # drop drawers (then the niche) until the lowest front keeps room for its pull
    while lowest_front(case, bands, style) < MIN_DRAWER and (n > 1 or niche != "none"):
        if n > 1:
            n -= 1
        else:
            niche = "none"
        bands = _bands(str(p["style"]), n, niche, g)
    parts = cabinet(case, bands, style, wall=0.0025)
    x_front = D / 2 + ft + fp
    parts.append(top_slab(-D / 2, x_front + os_, -W / 2, W / 2, H - t, t, bevel))
    if support == "plinth":
        kick = float(np.clip(0.5 * sh, 0.002, 0.005))
        parts += plinth(case, kick, min(0.0015, 0.1 * Wc))
    elif support == "legs":
        lt = float(np.clip(float(p["leg_thickness"]), 0.0035, 0.15 * Wc))
        parts += corner_legs(case, lt, str(p["leg_style"]), inset=0.0005)
    else:
        bt = 0.003
        parts += bracket_feet(
            case,
            sh,
            length_x=float(np.clip(0.3 * D, 0.007, 0.014)),
            length_y=float(np.clip(0.18 * Wc, 0.007, 0.014)),
            thickness=bt,
            proud=min(ft, bt - 0.001),
        )
    return parts


def _bands(style: str, n: int, niche: str, g: float) -> list[Band]:
    """The front's bands from the bottom up: ``n`` drawers graduated by ``g`` (drawers
    style) or a door under a drawer (``n`` > 1), and an open niche at ``niche``."""
    if style == "drawers":
        bands = [Band("drawer", 1, 1.0 + g * (n - 1 - k) / max(n - 1, 1)) for k in range(n)]
        if niche == "top":
            bands.append(Band("open", 1, 1.2))
        elif niche == "bottom":
            bands.insert(0, Band("open", 1, 1.4))
        return bands
    bands = [Band("door", 1, 2.6)]
    if n > 1:
        bands.append(Band("drawer", 1, 1.0))
    elif niche != "none":
        bands.append(Band("open", 1, 1.3))
    return bands


def _table(
    p: Params, W: float, D: float, H: float, t: float, bevel: float, ft: float, os_: float
) -> list[trimesh.Trimesh]:
    """The table style: four corner legs under the top, a drawer case under the top
    between them, a shelf low down."""
    lt = float(np.clip(float(p["leg_thickness"]), 0.0035, 0.12 * W))
    ob = 0.4 * os_  # the top's overhang at the back and the sides (the front: os_)
    # the frame of legs: its front face at x = xl1, the drawer front proud of it
    xl0, xl1 = -D / 2 + ob, D / 2 - ft - os_
    hw = W / 2 - ob
    z_under = H - t
    frame = Block(xl0, xl1, -hw, hw, 0.0, z_under)
    parts = corner_legs(frame, lt, str(p["leg_style"]), z_top=z_under + EMBED)
    # the drawer case: flush with the legs' outer faces, a drawer front on its face
    hd = float(np.clip(float(p["drawer_height"]) * H, 0.012, 0.35 * H))
    case = Block(xl0, xl1, -hw, hw, z_under - hd, z_under + EMBED)
    parts.append(case.mesh())
    style = FrontStyle(thickness=ft, handle=str(p["handle"]))
    # one drawer between the front legs, 1.7 mm in from them and from the case's edges
    panels, zs = layout_panels(
        -hw + lt, hw - lt, case.z0, case.z1 - EMBED, [Band()], 0.0017, 0.0017
    )
    parts += fronts(panels, zs, case, style)
    # the shelf, from the back legs' back faces (flush), reaching into the legs
    zs0 = float(p["shelf_height"]) * H
    st = float(np.clip(0.8 * t, 0.003, 0.005))
    enclosure = str(p["shelf_enclosure"])
    # an open-all-round shelf is set back from the front legs' faces (it is seen to end
    # there from the front, and the half turn does not match it with itself)
    x_shelf = xl1 - (0.0 if enclosure != "open" else 0.5 * lt)
    parts.append(block(xl0, x_shelf, -hw + 0.0005, hw - 0.0005, zs0, zs0 + st))
    pt = 0.002  # panel thickness
    if enclosure in ("back", "boxed"):
        parts.append(block(xl0, xl0 + pt, -hw + 0.0005, hw - 0.0005, zs0, case.z0 + EMBED))
    if enclosure == "boxed":
        for s in (-1, 1):
            y0, y1 = sorted((s * hw, s * (hw - pt)))
            parts.append(block(xl0 + 0.0005, xl1 - 0.0005, y0, y1, zs0, case.z0 + EMBED))
    parts.append(top_slab(xl0 - ob, D / 2, -W / 2, W / 2, z_under, t, bevel))
    return parts
