"""Chair: a slab seat on legs (or a swivel base), a back leaning at the rear, optional arms.

The chair faces +x: the seat front is at +x and the back rises from the rear edge (-x),
tilted backwards. The back is a solid panel or a frame of two posts holding vertical slats
or horizontal rails. Legs are square, round or splayed posts under the seat corners, or a
swivel column on a five-spoke star. Without a back a chair would be a stool; with a wide low
seat and arms it is close to a one-seat sofa (classes overlap in parts, as in ShapeNet).
The chair is picked by its thin back (or the seat edge). A chair has no rotational symmetry.
"""

from __future__ import annotations

import numpy as np

from beo_bench.geometry import axis_angle, no_symmetry
from beo_bench.objects.params import Choice, Flag, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, cylinder, hull
from beo_bench.objects.registry import register_category


@register_category(
    "chair",
    params={
        "seat_width": Uniform(0.045, 0.07),  # y
        "seat_depth": Uniform(0.04, 0.065),  # x
        "seat_height": Uniform(0.035, 0.06),  # top of the seat above the floor
        "seat_thickness": Uniform(0.004, 0.009),
        "back_height": Uniform(0.035, 0.07),  # along the back, above the seat
        "back_tilt": Uniform(0.0, 0.3),  # radians, leaning backwards
        "back_style": Choice(("solid", "vertical_slats", "horizontal_rails")),
        "slats": Integer(2, 5),
        "back_thickness": Uniform(0.003, 0.006),
        "back_width": Uniform(0.75, 1.0),  # / seat width (full width when there are arms)
        "leg_style": Choice(("square", "round", "splayed", "swivel"), p=(0.3, 0.25, 0.3, 0.15)),
        "leg_thickness": Uniform(0.003, 0.007),
        "leg_inset": Uniform(0.0, 0.15),  # / half the seat size, from the seat edge
        "arms": Flag(0.35),
        "arm_height": Uniform(0.015, 0.03),  # above the seat
        "stretchers": Flag(0.4),
    },
    shapenet_synsets=("03001627",),
    modelnet_names=("chair",),
)
def build(p: Params) -> Assembly:
    """Chair (16 parameters: seat width, depth, height, thickness; back height, tilt, style,
    slat count, thickness, width; leg style, thickness, inset; arms and their height;
    stretchers)."""
    w, d = float(p["seat_width"]), float(p["seat_depth"])
    sh, st = float(p["seat_height"]), float(p["seat_thickness"])
    bh, bt = float(p["back_height"]), float(p["back_thickness"])
    tilt = float(p["back_tilt"])
    lt = float(np.clip(float(p["leg_thickness"]), 0.0015, 0.25 * min(w, d)))
    # arms rest on the back, so with arms the back spans the whole seat
    bw = w if p["arms"] else w * float(np.clip(float(p["back_width"]), 0.5, 1.0))

    parts = [box((d, w, st), center=(0.0, 0.0, sh - st / 2))]

    # --- back: built in its own frame (a across, v up along the back) and tilted about the
    # seat's rear top edge; every piece starts inside the seat (v < 0) so it is fused to it
    R = axis_angle([0.0, 1.0, 0.0], -tilt)  # rotating about y by -tilt leans the top to -x
    pivot = np.array([-d / 2 + bt / 2, 0.0, sh])

    def back_box(y0: float, y1: float, v0: float, v1: float, t: float = bt) -> None:
        c = pivot + R @ np.array([0.0, (y0 + y1) / 2, (v0 + v1) / 2])
        parts.append(box((t, y1 - y0, v1 - v0), center=c, rotation=R))

    v_in = -0.6 * st  # how far the back reaches down into the seat
    if p["back_style"] == "solid":
        back_box(-bw / 2, bw / 2, v_in, bh)
    else:
        pw = float(np.clip(0.12 * bw, 0.004, 0.008))  # post width
        back_box(-bw / 2, -bw / 2 + pw, v_in, bh)
        back_box(bw / 2 - pw, bw / 2, v_in, bh)
        inner = bw - 2 * pw
        rail = float(np.clip(0.18 * bh, 0.005, 0.012))
        n = int(p["slats"])
        if p["back_style"] == "vertical_slats":
            back_box(-bw / 2, bw / 2, bh - rail, bh)  # top rail
            sw = 0.55 * inner / n
            gap = (inner - n * sw) / (n + 1)
            for k in range(n):
                y0 = -inner / 2 + gap + k * (sw + gap)
                back_box(y0, y0 + sw, v_in / 2, bh - rail / 2, 0.7 * bt)
        else:
            # horizontal rails on the upper part of the back, the top one at the top
            rh = float(np.clip(0.5 * (0.65 * bh) / n, 0.003, rail))
            for k in range(n):
                v1 = bh - k * (0.65 * bh - rh) / max(n - 1, 1)
                back_box(-bw / 2 + pw / 2, bw / 2 - pw / 2, v1 - rh, v1, 0.8 * bt)

    # --- legs (or a swivel base)
    style = p["leg_style"]
    top = sh - 0.4 * st  # legs reach into the seat
    if style == "swivel":
        col_r = float(np.clip(0.9 * lt, 0.003, 0.007))
        arm_r = 0.55 * min(w, d) * 1.1  # star radius
        spoke_h = float(np.clip(0.12 * sh, 0.003, 0.007))
        caster = float(np.clip(0.08 * sh, 0.002, 0.005))
        parts.append(cylinder(col_r, caster, top, sections=16))
        parts.append(cylinder(1.6 * col_r, caster, caster + 1.5 * spoke_h, sections=16))
        for k in range(5):
            a = 2 * np.pi * k / 5
            c, s = np.cos(a), np.sin(a)
            Rz = axis_angle([0.0, 0.0, 1.0], a)
            parts.append(
                box(
                    (arm_r, 0.8 * spoke_h + 0.002, spoke_h),
                    center=(c * arm_r / 2, s * arm_r / 2, caster + spoke_h / 2),
                    rotation=Rz,
                )
            )
            # a caster under the end of each spoke, overlapping the spoke
            parts.append(
                cylinder(
                    0.5 * spoke_h + 0.001,
                    0.0,
                    caster + 0.5 * spoke_h,
                    sections=10,
                    center=(c * 0.93 * arm_r, s * 0.93 * arm_r),
                )
            )
    else:
        inset = float(p["leg_inset"])
        lx = d / 2 - inset * d / 2 - lt / 2
        ly = w / 2 - inset * w / 2 - lt / 2
        splay = 0.15 * sh if style == "splayed" else 0.0

        def leg_at(sx: float, sy: float, z: float) -> np.ndarray:
            """Centre of a leg at height z (splayed legs move outwards towards the floor)."""
            f = 1.0 - z / top
            return np.array([sx * (lx + f * splay), sy * (ly + f * splay), z])

        for sx in (-1.0, 1.0):
            for sy in (-1.0, 1.0):
                if style == "round":
                    parts.append(cylinder(lt / 2, 0.0, top, sections=12, center=(sx * lx, sy * ly)))
                elif style == "square":
                    parts.append(box((lt, lt, top), center=(sx * lx, sy * ly, top / 2)))
                else:
                    b = leg_at(sx, sy, 0.0)
                    sq = np.array([[u, v] for u in (-0.5, 0.5) for v in (-0.5, 0.5)])
                    pts = [[sx * lx + lt * u, sy * ly + lt * v, top] for u, v in sq]
                    pts += [[b[0] + 0.7 * lt * u, b[1] + 0.7 * lt * v, 0.0] for u, v in sq]
                    parts.append(hull(pts))
        if p["stretchers"]:
            # an H: one stretcher along each side, one across between them
            zs = 0.3 * sh
            tk = 0.7 * lt
            for sy in (-1.0, 1.0):
                back, front = leg_at(-1.0, sy, zs), leg_at(1.0, sy, zs)
                parts.append(box((front[0] - back[0], tk, tk), center=(back + front) / 2))
            right, left = leg_at(1.0, -1.0, zs), leg_at(1.0, 1.0, zs)
            # across between the side stretchers' centre lines, so it overlaps both
            parts.append(box((tk, left[1] - right[1], tk), center=(0.0, 0.0, zs + 0.3 * tk)))

    # --- arms: a rest from the back to the front, on a post standing on the seat
    if p["arms"]:
        ah = float(np.clip(float(p["arm_height"]), 0.008, 0.9 * bh))
        at = float(np.clip(0.6 * lt + 0.002, 0.003, 0.007))  # width of the rest
        rt = 0.004  # thickness of the rest
        z_top = sh + ah
        # the rear end goes half a back thickness into the (tilted) back at the rest's top
        x_rear = -d / 2 - ah * np.tan(tilt) + 0.5 * bt
        x_front = d / 2 + 0.002
        for s in (-1.0, 1.0):
            y = s * (w / 2 - at / 2)
            parts.append(
                box((x_front - x_rear, at, rt), center=((x_front + x_rear) / 2, y, z_top - rt / 2))
            )
            post_h = ah + 0.5 * st  # from half-way into the seat up to the rest
            parts.append(
                box(
                    (at, at, post_h), center=(d / 2 - at / 2 - 0.002, y, sh - 0.5 * st + post_h / 2)
                )
            )

    return Assembly(parts, no_symmetry())
