"""Monitor: a thin screen panel facing +x on a stand, or an old deep-backed CRT.

The panel stands in the yz-plane, its screen (4:3, 16:10, 16:9 or 21:9) recessed 1.5 mm
behind a bezel frame whose width varies from a thin edge-to-edge rim to a broad frame,
with an optional deeper chin at the bottom. A flat panel's back is plain (a hinge block
where the stand meets it) or carries a tapered housing a few millimetres deep; a curved
panel is five flat facets turned about vertical axes on an arc, so its ends come forwards
(a curved housing follows it, each facet carrying its own slice). A CRT has a deep back
tapering to a smaller rear face (half to nine tenths of the panel's height deep) and sits
on a low swivel foot under the housing whatever the sampled stand.

Stands: a post behind the panel on a round disc or a rectangular plate; a post on a
V-shaped foot of two prongs spreading forwards; two blade legs near the panel's ends,
each on a foot bar along x; a monitor arm (a pole on a desk clamp, a C-bracket opening to
the front, behind the panel, and a bent arm to the panel's back); or no stand, the panel
resting on its bottom edge, leaning back on a kickstand. The panel tilts back by up to
0.2 rad (the kickstand's leans 0.18-0.38 rad). The largest extent (0.08-0.15 m) is the
panel's width, or the height when a tall 4:3 panel stands high; the monitor is picked by
the panel's edge or the post.

A monitor has no rotational symmetry: the stand is behind the panel and its foot reaches
forwards, so the thin panel lies well off the bounding box's centre and a half turn about
z moves it clear of itself; the bezel, the housing and the stand are on one side only, and
the panel is mirror symmetric in y at most (a mirror is no rotation).
"""

from __future__ import annotations

import itertools

import numpy as np
import trimesh

from beo_bench.geometry import axis_angle, no_symmetry
from beo_bench.objects.params import Choice, Flag, Params, Uniform
from beo_bench.objects.primitives import Assembly, frustum, hull, tube
from beo_bench.objects.registry import register_category

_E = 0.0008  # overlap of parts that meet, so that their union is one solid
_RECESS = 0.0015  # the screen lies this far behind the bezel's face
_FACETS = 5  # a curved panel's flat facets
_INSET = 0.0004  # see the bezel
_ASPECTS = {"4:3": 4 / 3, "16:10": 1.6, "16:9": 16 / 9, "21:9": 21 / 9}


def _cuboid(u0: float, u1: float, y0: float, y1: float, v0: float, v1: float) -> np.ndarray:
    """The corners of a box between two corners (any order per axis)."""
    return np.array([[u, y, v] for u in (u0, u1) for y in (y0, y1) for v in (v0, v1)], float)


def _rect(u: float, half_width: float, v0: float, v1: float) -> np.ndarray:
    """The corners of a rectangle across the panel at depth u."""
    return np.array([[u, y, v] for y in (-half_width, half_width) for v in (v0, v1)], float)


def _clip_y(pts: np.ndarray, a: float, b: float) -> np.ndarray:
    """The vertices of the convex hull of ``pts`` cut to the slab a <= y <= b: the points
    inside it plus where the segments between any two points cross its planes (interior
    segments add only interior points, which the hull drops)."""
    y = pts[:, 1]
    out = [pts[(y >= a) & (y <= b)]]
    for c in (a, b):
        i, j = np.array(list(itertools.combinations(range(len(pts)), 2))).T
        cross = (y[i] - c) * (y[j] - c) < 0
        if cross.any():
            t = ((c - y[i][cross]) / (y[j][cross] - y[i][cross]))[:, None]
            out.append(pts[i][cross] + t * (pts[j][cross] - pts[i][cross]))
    return np.concatenate(out)


@register_category(
    "monitor",
    params={
        "aspect": Choice(("4:3", "16:10", "16:9", "21:9"), p=(0.2, 0.25, 0.4, 0.15)),
        "size": Uniform(0.08, 0.15),  # the largest extent aimed at (the panel's width)
        "panel_thickness": Uniform(0.003, 0.007),
        "bezel": Uniform(0.002, 0.008),
        "chin": Uniform(0.0, 0.012),  # extra bezel at the bottom
        "curved": Flag(0.2),
        "curvature": Uniform(1.5, 3.0),  # a curved panel's radius / its width
        "back": Choice(("flat", "housing", "crt"), p=(0.3, 0.5, 0.2)),
        "back_depth": Uniform(0.0, 1.0),  # within the back style's range of depths
        "stand": Choice(("post_round", "post_rect", "v_foot", "two_leg", "arm_clamp", "kickstand")),
        "elevation": Uniform(0.1, 0.45),  # the panel's bottom above the floor / its height
        "tilt": Uniform(0.0, 0.2),  # radians, the top leaning back
        "post_width": Uniform(0.06, 0.16),  # / panel width
        "foot_size": Uniform(0.35, 0.6),  # / panel width
        "foot_thickness": Uniform(0.002, 0.005),
    },
    shapenet_synsets=("03211117",),
    modelnet_names=("monitor",),
)
def build(p: Params) -> Assembly:
    """Monitor (15 parameters: aspect, size, panel thickness, bezel, chin; curved and its
    radius; back style and depth; stand, elevation, tilt; post width; foot size and
    thickness)."""
    back, stand = str(p["back"]), str(p["stand"])
    crt = back == "crt"
    if crt:
        stand = "swivel"
    S = float(p["size"])
    r = _ASPECTS[str(p["aspect"])]
    t = float(np.clip(float(p["panel_thickness"]), 0.003, 0.01))
    b = float(np.clip(float(p["bezel"]), 0.002, 0.012))
    chin = max(float(p["chin"]), 0.0)
    elev = {"two_leg": 0.4, "arm_clamp": 1.2, "kickstand": 0.0, "swivel": 0.12}.get(stand, 1.0)
    elev *= float(np.clip(float(p["elevation"]), 0.0, 0.7))
    # the width, narrowed where a tall panel standing high would make the height the
    # largest extent beyond the size aimed at
    W = min(S, (S / (1.0 + elev) - chin) * r)
    Hs = W / r + chin
    tilt = float(np.clip(float(p["tilt"]), 0.0, 0.3))
    if stand == "kickstand":
        tilt += 0.18
    elif crt:
        tilt *= 0.3
    ft = float(np.clip(float(p["foot_thickness"]), 0.002, 0.008))
    foot = float(np.clip(float(p["foot_size"]), 0.2, 0.8)) * W

    # --- the panel in its own frame: u along the screen's normal (+x before tilting), y
    # across, v up from the panel's bottom edge; convex pieces as point sets. The bezel
    # strips stop 0.4 mm inside the body's outline (0.8 mm for the ends of the top and
    # bottom strips and of the side strips, whose fronts are 0.2 mm back): pieces sharing
    # a face plane leave degenerate zero-volume slivers in the union once tilted, so no
    # two pieces of a facet have a face in a common plane
    u0, u1 = t / 2 - _RECESS - _E, t / 2
    y1, v1 = W / 2 - _INSET, Hs - _INSET
    local = [
        _cuboid(-t / 2, t / 2 - _RECESS, -W / 2, W / 2, 0.0, Hs),  # body, its face the screen
        _cuboid(u0, u1, -y1 + _INSET, y1 - _INSET, Hs - b, v1),  # bezel: top
        _cuboid(u0, u1, -y1 + _INSET, y1 - _INSET, _INSET, b + chin),  # bottom
    ]
    for s in (-1.0, 1.0):
        local.append(
            _cuboid(u0 - 0.0002, u1 - 0.0002, s * y1, s * (W / 2 - b), 2 * _INSET, v1 - _INSET)
        )
    u_back = -t / 2  # the back's face at the middle, where a stand meets it
    if back != "flat":
        bd = float(np.clip(float(p["back_depth"]), 0.0, 1.0))
        if crt:
            dh = Hs * (0.45 + 0.45 * bd)
            base, rear = (0.47 * W, 0.03 * Hs, 0.97 * Hs), (0.27 * W, 0.2 * Hs, 0.7 * Hs)
        else:
            dh = t * (0.6 + 1.6 * bd)
            base, rear = (0.42 * W, 0.08 * Hs, 0.92 * Hs), (0.3 * W, 0.2 * Hs, 0.75 * Hs)
        local.append(
            np.concatenate(
                [
                    _rect(-t / 2 + _E, *base),  # on the panel's back
                    _rect(-t / 2 - dh, *rear),
                ]
            )
        )
        u_back -= dh
    v_m = 0.45 * Hs  # where a post or an arm meets the back
    pw = float(np.clip(float(p["post_width"]) * W, 0.005, 0.3 * W))  # the post's width
    pd = float(np.clip(0.35 * pw, 0.004, 0.008))  # and depth
    md = pd + 0.003  # the hinge block the stand holds
    if stand in ("post_round", "post_rect", "v_foot", "arm_clamp"):
        mw, mh = max(0.2 * W, pw + 0.004), min(0.2 * W, 0.4 * Hs)
        local.append(_cuboid(u_back - md, u_back + _E, -mw / 2, mw / 2, v_m - mh / 2, v_m + mh / 2))

    # --- facets: flat, or five turned about vertical axes on an arc of radius Rc whose
    # centre is in front (the ends come forwards); each facet's pieces reach into the next
    R_tilt = axis_angle([0.0, 1.0, 0.0], -tilt)  # leans the top to -x
    if p["curved"] and not crt:
        Rc = float(np.clip(float(p["curvature"]), 1.0, 5.0)) * W
        edges = np.linspace(-W / 2, W / 2, _FACETS + 1)
        facets = [(a, bb, (a + bb) / 2 / Rc) for a, bb in itertools.pairwise(edges)]
    else:
        Rc, facets = 0.0, [(-W / 2, W / 2, 0.0)]

    def facet_of(y: float) -> tuple[float, float, float]:
        return next((f for f in facets if y <= f[1]), facets[-1])

    def to_frame(pts: np.ndarray, theta: float) -> np.ndarray:
        """Panel-frame points of a facet turned by theta to the world (before lifting)."""
        c, s = np.cos(theta), np.sin(theta)
        w = pts[:, 1] - Rc * theta  # across the facet, from its centre
        x = pts[:, 0] * c + w * s + Rc * (1 - c)
        y = -pts[:, 0] * s + w * c + Rc * s
        return np.stack([x, y, pts[:, 2]], axis=1) @ R_tilt.T

    panel = []
    for k, (a, bb, theta) in enumerate(facets):
        for j, pts in enumerate(local):
            if len(facets) > 1:
                # each piece reaches into the next facet by its own margin (0.6 mm or
                # more), so that no two pieces are cut in a common plane
                ext = 0.0006 + 0.0002 * j
                a_, b_ = (a - ext if a > -W / 2 else a), (bb + ext if bb < W / 2 else bb)
                if pts[:, 1].max() <= a_ or pts[:, 1].min() >= b_:
                    continue
                pts = _clip_y(pts, a_, b_)
                if k % 2:
                    # every other facet 0.25 mm shorter at the top and bottom, so that
                    # neighbours overlapping at a joint share no face plane either
                    pts = pts * [1.0, 1.0, 1.0 - 0.0005 / Hs] + [0.0, 0.0, 0.00025]
            panel.append(to_frame(pts, theta))

    def at(u: float, y: float, v: float) -> np.ndarray:
        """A panel-frame point in the world (before lifting)."""
        return to_frame(np.array([[u, y, v]]), facet_of(y)[2])[0]

    # --- lift the panel: its bottom edge at the stand's height (a kickstand's on the floor)
    if stand == "kickstand":
        z_p = -min(float(q[:, 2].min()) for q in panel)
    elif crt:
        z_p = float(np.clip(0.06 * Hs, 0.003, 0.006)) + max(0.004, 0.05 * Hs)
    elif stand == "two_leg":
        z_p = elev * Hs + ft + 0.002  # clear of the foot bars
    else:
        z_p = elev * Hs
    lift = np.array([0.0, 0.0, z_p])
    parts: list[trimesh.Trimesh] = [hull(q + lift) for q in panel]

    def world(u: float, y: float, v: float) -> np.ndarray:
        return at(u, y, v) + lift

    M = world(u_back - md / 2, 0.0, v_m)  # the hinge block's centre
    x_front = world(t / 2, 0.0, 0.0)[0]  # the screen's bottom edge
    x_rear = M[0] - pd / 2 - 0.004  # a foot's rear edge, behind the post at least
    if stand in ("post_round", "post_rect", "v_foot"):
        # a flat neck from the foot up into the hinge block; the foot reaches a quarter of
        # its size in front of the screen, as a real stand's does to keep it upright
        parts.append(hull(_cuboid(M[0] - pd / 2, M[0] + pd / 2, -pw / 2, pw / 2, ft - _E, M[2])))
        front = x_front + 0.25 * foot
        if stand == "post_round":
            fr = max(foot / 2, (front - x_rear) / 2)
            parts.append(frustum(fr, 0.92 * fr, 0.0, ft, sections=32, center=(front - fr, 0.0)))
        elif stand == "post_rect":
            x0 = min(x_rear, front - 0.6 * foot)
            i = min(0.001, ft / 3)  # a chamfered top edge
            parts.append(
                hull(
                    np.concatenate(
                        [
                            _cuboid(x0, front, -foot / 2, foot / 2, 0.0, ft - i),
                            _cuboid(x0 + i, front - i, -foot / 2 + i, foot / 2 - i, ft, ft),
                        ]
                    )
                )
            )
        else:
            # two prongs from a hub under the post, spreading forwards to foot/2 either side
            hub = _cuboid(M[0] - pd / 2 - 0.002, M[0] + pd / 2 + 0.002, -pw / 2, pw / 2, 0, ft)
            parts.append(hull(hub))
            prong = float(np.clip(0.06 * W, 0.004, 0.008))
            for s in (-1.0, 1.0):
                p0 = np.array([M[0], 0.0])
                p1 = np.array([front, s * foot / 2])
                n = np.array([-(p1 - p0)[1], (p1 - p0)[0]]) / np.linalg.norm(p1 - p0)
                ends = [q + k * prong / 2 * n for q in (p0, p1) for k in (-1, 1)]
                parts.append(hull([[*e, z] for e in ends for z in (0.0, ft)]))
    elif stand == "two_leg":
        # a blade down the back of each end of the panel onto a foot bar along x
        ly = (0.28 + 0.25 * float(p["foot_size"])) * W
        lw = float(np.clip(0.05 * W, 0.004, 0.008))  # blade width (y)
        lt = 0.003  # and thickness
        for s in (-1.0, 1.0):
            y = s * ly
            top = [
                world(u, y + k * lw / 2, 0.3 * Hs)
                for u in (-t / 2 + _E, -t / 2 - lt)
                for k in (-1, 1)
            ]
            xl = world(-t / 2 - lt / 2, y, 0.0)[0]
            bottom = [
                [xl + k2 * lt / 2, y + k * lw / 2, ft - _E] for k2 in (-1, 1) for k in (-1, 1)
            ]
            parts.append(hull(np.array(top + bottom)))
            fd = 0.5 * foot
            parts.append(hull(_cuboid(xl - 0.4 * fd, xl + 0.6 * fd, y - lw / 2, y + lw / 2, 0, ft)))
    elif stand == "arm_clamp":
        # a desk clamp behind the panel: a C-bracket opening to the front (the desk's edge
        # would go in the jaw), a pole on it and a bent arm to the hinge block
        ct = 0.003
        gap = float(np.clip(0.06 * W, 0.005, 0.009))
        cw = float(np.clip(0.2 * W, 0.015, 0.025))
        xc = M[0] - float(np.clip(0.8 * foot, 0.025, 0.5 * W))
        zt = 2 * ct + gap
        cy = 0.6 * cw
        parts.append(hull(_cuboid(xc - cw / 2, xc + cw / 2, -cy / 2, cy / 2, zt - ct, zt)))
        parts.append(hull(_cuboid(xc - cw / 2, xc - cw / 2 + ct, -cy / 2, cy / 2, 0.0, zt)))
        parts.append(hull(_cuboid(xc - cw / 2, xc + 0.3 * cw, -cy / 2, cy / 2, 0.0, ct)))
        rp = float(np.clip(0.04 * W, 0.003, 0.005))
        z1 = M[2] + 0.15 * Hs
        parts.append(frustum(rp, rp, zt - _E, z1 + rp, sections=12, center=(xc, 0.0)))
        elbow = [0.5 * (xc + M[0]), 0.15 * W, z1 - 0.05 * Hs]
        parts += tube([[xc, 0.0, z1], elbow, list(M)], 0.8 * rp, sections=10)
    elif stand == "kickstand":
        # a plate hinged high on the back, reaching back to the floor
        kw, kt = 0.6 * foot, 0.003
        vk = 0.55 * Hs
        top = [world(u, k * kw / 2, vk) for u in (u_back + _E, u_back - kt) for k in (-1, 1)]
        xk = min(q[0] for q in top) - 0.45 * top[0][2]
        bottom = [[xk + k2 * kt, k * kw / 2, 0.0] for k2 in (0, 1) for k in (-1, 1)]
        parts.append(hull(np.array(top + bottom + [[xk, k * kw / 2, kt] for k in (-1, 1)])))
    else:  # a CRT's swivel foot: a low disc under the housing and a neck up into it
        fh = float(np.clip(0.06 * Hs, 0.003, 0.006))
        c = world(u_back * 0.45 - t / 2 * 0.55, 0.0, 0.0)  # under the housing's middle
        dh = -t / 2 - u_back
        parts.append(frustum(0.3 * W, 0.27 * W, 0.0, fh, sections=32, center=(c[0], 0.0)))
        parts.append(
            hull(
                _cuboid(
                    c[0] - 0.12 * dh, c[0] + 0.12 * dh, -0.2 * W, 0.2 * W, fh - _E, z_p + 0.2 * Hs
                )
            )
        )
    return Assembly(parts, no_symmetry())
