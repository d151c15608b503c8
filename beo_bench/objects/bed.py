"""Bed: a mattress on a base, usually with a headboard, or a bunk bed of two decks.

The bed is long along x with its head at -x, so that its foot end faces +x (the canonical
front, as ShapeNet's beds face the viewer foot first); the width runs along y. The base is
a frame on four legs, a platform on a plinth set back from its edges, or a divan box down
to the floor. The mattress is a slab with padded (rounded) top edges; pillows lie against
the headboard, under a duvet that hangs over the sides and the foot. A headboard is a
solid panel (flat or arched top, optionally between square posts), a slatted one (posts,
a top rail and vertical slats) or an upholstered one (a thick padded board with a rounded
top, sometimes wider than the bed); a footboard repeats its style, lower. A daybed has a
back along its -y long side and equal boards at both ends as arms: at its small end it is
a sofa turned by 90 degrees (the classes overlap in shape, as in ModelNet). A bunk bed is
two decks between four corner posts, with solid boards at the head, a rail at the foot,
guard rails round the upper deck and a ladder on the +y side by the foot. The bed is
picked by a board's edge or across the frame.

A bed with neither headboard nor footboard, no pillows and no daybed back or bunk is the
same after a half turn about z (everything else is symmetric end to end and side to
side), so it is declared 2-fold; its length is at least 1.25 times its width, so it is far
from 4-fold. Every other bed has no rotational symmetry, and its head end is made to hold
a visible share of its volume (a headboard thickened or pillows raised where needed) so
that a half turn about z changes it clearly.
"""

from __future__ import annotations

import numpy as np
import trimesh

from beo_bench.geometry import cyclic_z, no_symmetry
from beo_bench.objects.params import Choice, Flag, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, cylinder, hull
from beo_bench.objects.registry import register_category

# The parts at the head end, less the footboard, hold at least this share of the bed's
# volume, so that a half turn about z leaves a volume IoU well below 0.95 (about
# (1 - s) / (1 + s)); thin, low headboards alone can hold as little as 2 %.
_MIN_HEAD_SHARE = 0.05


def vol(parts: list[trimesh.Trimesh]) -> float:
    """The summed volume of ``parts`` (overlaps counted twice)."""
    return float(sum(q.volume for q in parts))


def _pad(
    x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, r: float, bottom: bool = False
) -> np.ndarray:
    """Corners of a slab whose top face (and bottom face, if ``bottom``) is inset by ``r``:
    a padded mattress, pillow or duvet."""
    r = min(r, 0.3 * (x1 - x0), 0.3 * (y1 - y0), 0.45 * (z1 - z0))
    zb = z0 + r if bottom else z0
    pts = [[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (zb, z1 - r)]
    pts += [[x, y, z1] for x in (x0 + r, x1 - r) for y in (y0 + r, y1 - r)]
    if bottom:
        pts += [[x, y, z0] for x in (x0 + r, x1 - r) for y in (y0 + r, y1 - r)]
    return np.array(pts)


def _board(
    style: str,
    x0: float,
    x1: float,
    y0: float,
    y1: float,
    z_rail: float,
    z_top: float,
    arched: bool,
    posts: bool,
    slats: int,
) -> list[trimesh.Trimesh]:
    """A head-, foot- or back-board across y in [y0, y1], from the floor to ``z_top``,
    ``x1 - x0`` thick. ``z_rail`` is the height of the mattress top (where a slatted board's
    slats start)."""
    t = x1 - x0
    xc = (x0 + x1) / 2
    w = y1 - y0
    yc = (y0 + y1) / 2
    out = []
    ps = float(np.clip(1.3 * t, 0.004, 0.009))  # square posts, a little thicker than the board
    post_top = z_top + (0.15 * ps if posts else 0.0)  # posts stand proud of the board
    if style == "slatted" or (posts and style == "panel"):
        for y in (y0 + ps / 2, y1 - ps / 2):
            out.append(box((ps, ps, post_top), center=(xc, y, post_top / 2)))
    if style == "slatted":
        rail = float(np.clip(0.18 * (z_top - z_rail), 0.003, 0.008))
        inner = w - 2 * ps
        # a top rail and a bottom rail (hidden behind the mattress) between the posts
        out.append(box((t, inner + 0.002, rail), center=(xc, yc, z_top - rail / 2)))
        out.append(box((t, inner + 0.002, rail), center=(xc, yc, z_rail - rail / 2)))
        n = max(slats, 2)
        sw = float(np.clip(0.45 * inner / n, 0.002, 0.008))
        gap = (inner - n * sw) / (n + 1)
        for k in range(n):
            y = y0 + ps + gap + k * (sw + gap) + sw / 2
            out.append(
                box((0.7 * t, sw, z_top - z_rail), center=(xc, y, (z_top + z_rail) / 2 - 0.001))
            )
        return out
    if style == "upholstered":
        # a padded board with a rounded top: a slab under a round bolster along y
        r = t / 2
        out.append(box((t, w, z_top - r), center=(xc, yc, (z_top - r) / 2)))
        a = np.linspace(0.0, np.pi, 7)
        arc = [[xc + r * np.cos(u), y, z_top - r + r * np.sin(u)] for u in a for y in (y0, y1)]
        out.append(
            hull(np.array(arc + [[x, y, z_top - r - 0.001] for x in (x0, x1) for y in (y0, y1)]))
        )
        return out
    # panel: a flat top, or one raised towards the middle (an arch of three straight runs)
    if arched:
        rise = 0.25 * (z_top - z_rail)
        ys = np.array([y0, y0 + 0.2 * w, yc - 0.1 * w, yc + 0.1 * w, y1 - 0.2 * w, y1])
        zs = z_top - rise + rise * np.array([0.0, 0.75, 1.0, 1.0, 0.75, 0.0])
        pts = [[x, y, z] for x in (x0, x1) for y, z in zip(ys, zs, strict=True)]
        pts += [[x, y, 0.0] for x in (x0, x1) for y in (y0, y1)]
        out.append(hull(pts))
    else:
        out.append(box((t, w, z_top), center=(xc, yc, z_top / 2)))
    return out


@register_category(
    "bed",
    params={
        # a daybed (a back along one long side and arms at the ends) is the sofa of beds:
        # one bed in five, so that the bed-sofa confusion of chapter 4 comes from shape
        "style": Choice(("standard", "daybed", "bunk"), p=(0.62, 0.22, 0.16)),
        "length": Uniform(0.11, 0.175),  # x, boards included
        # length / width; at least 1.25 so no bed is nearly 4-fold, also on the ood split
        "aspect": Uniform(1.25, 2.1, ood=(1.25, 2.4)),
        "base": Choice(("legs", "plinth", "box"), p=(0.4, 0.3, 0.3)),
        "base_height": Uniform(0.01, 0.026),  # top of the frame above the floor
        "mattress": Uniform(0.006, 0.015),  # mattress thickness
        "headboard": Choice(("none", "panel", "slatted", "upholstered"), p=(0.2, 0.35, 0.2, 0.25)),
        "headboard_height": Uniform(0.02, 0.05),  # above the mattress
        "headboard_thickness": Uniform(0.003, 0.008),
        "arched": Flag(0.3),  # a panel's top
        "posts": Flag(0.4),  # square posts at a panel's ends
        "slats": Integer(3, 7),
        "wings": Uniform(0.0, 0.08),  # an upholstered board's overhang each side / width
        "footboard": Flag(0.35),  # only with a headboard
        "footboard_height": Uniform(0.0, 0.5),  # above the mattress / headboard's
        "pillows": Flag(0.6),
        "duvet": Flag(0.45),  # with pillows
        "leg_thickness": Uniform(0.003, 0.007),
        "deck_gap": Uniform(0.5, 0.62),  # a bunk's upper deck height / length
    },
    shapenet_synsets=("02818832",),
    modelnet_names=("bed",),
)
def build(p: Params) -> Assembly:
    """Bed (19 parameters: standard, daybed or bunk; length, aspect; base style and height;
    mattress thickness; headboard style, height, thickness, arched top, posts, slat count,
    wings; footboard and its height; pillows; duvet; leg thickness; a bunk's deck height)."""
    style = str(p["style"])
    L = float(p["length"])
    aspect = max(float(p["aspect"]), 1.25)
    if style == "daybed":
        aspect = max(aspect, 1.6)  # daybeds are single beds
    W = L / aspect
    bh = float(np.clip(float(p["base_height"]), 0.007, 0.4 * W))
    mt = float(np.clip(float(p["mattress"]), 0.004, 0.6 * bh + 0.006))
    lt = float(np.clip(float(p["leg_thickness"]), 0.0025, 0.08 * W))
    hb_style = str(p["headboard"])
    if style != "standard" and hb_style == "none":
        hb_style = "panel"  # a daybed's arms and a bunk's ends are boards
    hh = float(np.clip(float(p["headboard_height"]), 0.012, 0.6 * L))
    tb = float(np.clip(float(p["headboard_thickness"]), 0.0025, 0.012))
    footboard = bool(p["footboard"]) and hb_style != "none"
    if style == "daybed":
        footboard = True
    # a footboard stands at least 4 mm above the mattress (a slatted one needs room for
    # its rails)
    fh = max(float(np.clip(float(p["footboard_height"]), 0.0, 0.5)) * hh, 0.004)
    if hb_style == "slatted":
        fh = max(fh, 0.01)
    if style == "daybed":
        fh = hh  # arms of equal height
    pillows = bool(p["pillows"])
    duvet = pillows and bool(p["duvet"])
    arched, posts = bool(p["arched"]), bool(p["posts"])
    slats = int(p["slats"])

    if style == "bunk":
        return _bunk(p, L, W, bh, mt, tb, pillows)

    x_head = -L / 2 + (tb if hb_style != "none" else 0.0)  # the mattress's head end
    x_foot = L / 2 - (tb if footboard else 0.0)
    z_top = bh + mt  # the mattress top
    sym: list[trimesh.Trimesh] = []  # base and mattress (end to end symmetric if plain)

    # --- base: the frame's footprint spans the whole length between the boards
    ft = float(np.clip(0.35 * bh, 0.003, 0.007))  # frame thickness
    fx0, fx1 = -L / 2 + 0.001, L / 2 - 0.001
    base = str(p["base"])
    if base == "box":
        sym.append(box((fx1 - fx0, W, bh), center=(0.0, 0.0, bh / 2)))
    else:
        sym.append(box((fx1 - fx0, W, ft), center=(0.0, 0.0, bh - ft / 2)))
        if base == "plinth":
            inset = float(np.clip(0.12 * W, 0.003, 0.01))
            sym.append(
                box(
                    (fx1 - fx0 - 2 * inset, W - 2 * inset, bh - ft + 0.001),
                    center=(0.0, 0.0, (bh - ft + 0.001) / 2),
                )
            )
        else:
            # four legs just inside the corners, round when thin and square when thick
            m = 0.6 * lt
            zl = bh - ft + 0.001
            for x in (fx0 + m, fx1 - m):
                for y in (-W / 2 + m, W / 2 - m):
                    if lt < 0.0045:
                        sym.append(cylinder(lt / 2, 0.0, zl, sections=10, center=(x, y)))
                    else:
                        sym.append(box((lt, lt, zl), center=(x, y, zl / 2)))
    # the mattress, sunk 0.5 mm into the frame and the boards
    sym.append(
        hull(_pad(x_head - 0.0005, x_foot + 0.0005, -W / 2, W / 2, bh - 0.0005, z_top, 0.3 * mt))
    )

    head: list[trimesh.Trimesh] = []  # head-end parts (and a daybed's back)
    foot: list[trimesh.Trimesh] = []
    wing = float(np.clip(float(p["wings"]), 0.0, 0.1)) * W if hb_style == "upholstered" else 0.0

    def boards(t: float) -> None:
        head.clear()
        foot.clear()
        if hb_style == "none":
            return
        head.extend(
            _board(
                hb_style,
                -L / 2,
                -L / 2 + t,
                -W / 2 - wing,
                W / 2 + wing,
                z_top,
                z_top + hh,
                arched,
                posts,
                slats,
            )
        )
        if footboard:
            foot.extend(
                _board(
                    hb_style,
                    L / 2 - t,
                    L / 2,
                    -W / 2 - wing,
                    W / 2 + wing,
                    z_top,
                    z_top + fh,
                    arched,
                    posts,
                    slats,
                )
            )

    boards(tb)
    if style == "daybed":
        # a back along the -y side, the whole length, as tall as the arms and overlapping
        # them by half a millimetre
        head.append(
            box(
                (L, tb + 0.0005, z_top + hh),
                center=(0.0, -W / 2 - tb / 2 + 0.00025, (z_top + hh) / 2),
            )
        )

    # --- pillows against the headboard, and a duvet from them to the foot
    soft: list[trimesh.Trimesh] = []
    n_pillows = 1 if W < 0.075 else 2
    pl = float(np.clip(0.18 * L, 0.015, 0.03))  # along x
    gap = 0.001
    pw = (W - 0.006 - (n_pillows - 1) * gap) / n_pillows * (0.8 if n_pillows == 1 else 1.0)

    def make_soft(ph: float) -> None:
        soft.clear()
        if not pillows:
            return
        x0 = x_head - 0.0005 if hb_style != "none" else x_head + 0.002
        y_lo = -(n_pillows * pw + (n_pillows - 1) * gap) / 2
        for k in range(n_pillows):
            y0 = y_lo + k * (pw + gap)
            soft.append(
                hull(
                    _pad(x0, x0 + pl, y0, y0 + pw, z_top - 0.001, z_top + ph, 0.4 * ph, bottom=True)
                )
            )
        if duvet:
            dt = 0.002
            drop = 0.6 * mt
            xd = x0 + pl + 0.003
            soft.append(
                hull(
                    _pad(
                        xd, x_foot + dt, -W / 2 - dt, W / 2 + dt, z_top - drop, z_top + dt, 0.6 * dt
                    )
                )
            )
            # the turned-down edge, a roll across the bed at the duvet's head end
            soft.append(
                hull(
                    _pad(
                        xd - 0.001,
                        xd + 0.006,
                        -W / 2 - dt,
                        W / 2 + dt,
                        z_top - 0.001,
                        z_top + 2.2 * dt,
                        1.2 * dt,
                    )
                )
            )

    ph = float(np.clip(0.065 * L, 0.006, 0.011))
    make_soft(ph)

    # --- make the head end heavy enough that a half turn shows (see _MIN_HEAD_SHARE). A
    # half turn puts a board's part below the mattress top onto the base's other end, so
    # only the part above it counts (a share of its height, roughly of its volume).
    asym = hb_style != "none" or pillows or style == "daybed"
    if asym and style == "standard":
        for _ in range(6):
            above_h, above_f = hh / (z_top + hh), fh / (z_top + fh)
            total = vol(sym) + vol(head) + vol(foot) + vol(soft)
            pillow_v = vol(soft[:n_pillows]) if pillows else 0.0
            board_v = above_h * vol(head) - above_f * vol(foot)
            need = _MIN_HEAD_SHARE * total - (board_v + pillow_v)
            if need <= 0:
                break
            if hb_style != "none":
                if tb < 0.012 - 1e-9:
                    # the boards' volume grows about linearly with their thickness
                    tb = min(tb + need * tb / max(board_v, 1e-9), 0.012)
                else:
                    # thick enough: raise the headboard instead (its part above the
                    # mattress grows with its height)
                    hh = min(hh * (1.0 + need / max(above_h * vol(head), 1e-9)), 0.5 * L)
                boards(tb)
                x_head = -L / 2 + tb  # the pillows stay against the thicker board
                make_soft(ph)
            else:
                ph = min(ph * (1.0 + need / max(pillow_v, 1e-9)), 0.016)
                make_soft(ph)

    parts = sym + head + foot + soft
    return Assembly(parts, no_symmetry() if asym else cyclic_z(2))


def _bunk(
    p: Params, L: float, W: float, bh: float, mt: float, tb: float, pillows: bool
) -> Assembly:
    """Two decks between four corner posts; solid boards at the head, one rail at the
    foot, guard rails round the upper deck and a ladder on the +y side near the foot."""
    ps = float(np.clip(1.4 * tb, 0.0045, 0.008))  # corner posts
    ft = float(np.clip(0.3 * bh, 0.003, 0.006))
    z_low = bh
    z_up = max(float(p["deck_gap"]) * L, z_low + mt + 0.03)
    rail_h = float(np.clip(0.09 * L, 0.009, 0.016))  # guard rail above the upper mattress
    z_post = z_up + mt + rail_h + 0.003
    parts: list[trimesh.Trimesh] = []
    for x in (-L / 2 + ps / 2, L / 2 - ps / 2):
        for y in (-W / 2 + ps / 2, W / 2 - ps / 2):
            parts.append(box((ps, ps, z_post), center=(x, y, z_post / 2)))
    inner_x = L - 2 * ps
    rt = 0.7 * ps  # rail thickness
    for z in (z_low, z_up):
        # a frame slab between the posts and the mattress on it
        parts.append(box((inner_x + 0.002, W, ft), center=(0.0, 0.0, z - ft / 2)))
        parts.append(
            hull(
                _pad(
                    -L / 2 + ps - 0.0005,
                    L / 2 - ps + 0.0005,
                    -W / 2 + 0.001,
                    W / 2 - 0.001,
                    z - 0.0005,
                    z + mt,
                    0.3 * mt,
                )
            )
        )
        # head: a solid board from the frame to well above the mattress
        zb = z + mt + (rail_h if z == z_up else 0.6 * rail_h + 0.006)
        zb = min(zb, z_post if z == z_up else z_up - ft - 0.004)
        parts.append(
            box(
                (0.8 * ps, W - 2 * ps + 0.002, zb - (z - ft)),
                center=(-L / 2 + ps / 2, 0.0, (zb + z - ft) / 2),
            )
        )
        # foot: one rail just above the mattress
        zr = z + mt + 0.004
        parts.append(box((rt, W - 2 * ps + 0.002, rt), center=(L / 2 - ps / 2, 0.0, zr)))
        if pillows:
            ph = float(np.clip(0.065 * L, 0.006, 0.011))
            pl = float(np.clip(0.18 * L, 0.015, 0.03))
            x0 = -L / 2 + ps - 0.0005
            parts.append(
                hull(
                    _pad(
                        x0,
                        x0 + pl,
                        -0.4 * W,
                        0.4 * W,
                        z + mt - 0.001,
                        z + mt + ph,
                        0.4 * ph,
                        bottom=True,
                    )
                )
            )
    # guard rails round the upper deck: full along -y, on +y from the head to the ladder
    zg = z_up + mt + rail_h - rt / 2
    lw = float(np.clip(0.3 * L, 0.03, 0.045))  # ladder width along x
    x_lad1 = L / 2 - ps - 0.004  # the ladder's foot-end rail
    x_lad0 = x_lad1 - lw
    parts.append(box((inner_x + 0.002, rt, rt), center=(0.0, -W / 2 + ps / 2, zg)))
    parts.append(
        box(
            (x_lad0 + L / 2 - ps + 0.002, rt, rt),
            center=((x_lad0 - L / 2 + ps) / 2, W / 2 - ps / 2, zg),
        )
    )
    # the ladder: two rails outside the +y side, from the floor to the guard rail's height,
    # touching the upper frame's side; rungs between them
    lr = float(np.clip(0.8 * rt, 0.0025, 0.005))
    y_l = W / 2 + lr / 2 - 0.0005
    z_l = zg + rt / 2
    for x in (x_lad0, x_lad1):
        parts.append(box((lr, lr, z_l), center=(x, y_l, z_l / 2)))
    # the ladder meets the upper frame through a block at each rail
    for x in (x_lad0, x_lad1):
        parts.append(box((lr, lr + 0.001, ft), center=(x, W / 2 - 0.0005 + lr / 2, z_up - ft / 2)))
    # and the guard rail's free end meets the ladder's head-end rail through a short bar
    y_g = W / 2 - ps / 2
    parts.append(box((lr, y_l - y_g, rt), center=(x_lad0, (y_l + y_g) / 2, zg)))
    n_rungs = max(int((z_up - 0.01) / 0.02), 2)
    for k in range(n_rungs):
        z = 0.012 + k * (z_up - 0.012) / n_rungs
        parts.append(box((lw + lr, 0.8 * lr, 0.8 * lr), center=((x_lad0 + x_lad1) / 2, y_l, z)))
    # legs under the lower frame are the posts themselves; nothing else touches the floor
    return Assembly(parts, no_symmetry())
