"""Airplane: a fuselage of revolution along x, swept wings, a tail fin and stabiliser, and
0, 2 or 4 engines hanging under the wings.

The nose points to +x and the wings span y. The fuselage is a chain of convex frustums
between circular sections along x: a rounded nose, a constant barrel and a tail cone whose
axis sweeps up to the fin. Each wing is the hull of a thin lens-shaped root section and a
smaller tip section, swept back and raised by the dihedral; the wings start inside the
fuselage, low, mid or high on it. The horizontal stabiliser sits on the tail cone or on
top of the fin (a T-tail). Engines are nacelles (frustums along x) on pylons under the
wings. Without wings it would be close to a bottle on its side (classes overlap in parts,
as in ShapeNet). The airplane is picked by its fuselage (at most about 2.5 cm thick).
An airplane has no rotational symmetry (mirror symmetry is not a rotation).
"""

from __future__ import annotations

import itertools

import numpy as np

from beo_bench.geometry import no_symmetry
from beo_bench.objects.params import Choice, Flag, Integer, Params, Uniform
from beo_bench.objects.primitives import Assembly, box, hull, mirror_y
from beo_bench.objects.registry import register_category


def _ring_x(x: float, r: float, z: float = 0.0, y: float = 0.0, sections: int = 16) -> np.ndarray:
    """A circle of radius r in the plane normal to x, centred at (x, y, z)."""
    a = np.linspace(0.0, 2 * np.pi, sections, endpoint=False)
    return np.stack([np.full_like(a, x), y + r * np.cos(a), z + r * np.sin(a)], axis=1)


def _section(
    x_le: float, chord: float, y: float, z: float, t: float, vertical: bool = False
) -> np.ndarray:
    """A lens-shaped aerofoil section: leading edge at x_le, chord towards -x, thickest
    (t) at 30% chord, a thin trailing edge. Horizontal (thickness along z, at span station
    y and height z) or, for a fin, vertical (thickness along y, at height z)."""
    pts = [
        (x_le, 0.0),
        (x_le - 0.1 * chord, 0.35 * t),
        (x_le - 0.3 * chord, 0.5 * t),
        (x_le - 0.7 * chord, 0.3 * t),
        (x_le - chord, 0.04 * t),
    ]
    out = []
    for x, half in pts:
        for s in (-1.0, 1.0):
            out.append([x, y + s * half, z] if vertical else [x, y, z + s * half])
    return np.array(out)


@register_category(
    "airplane",
    params={
        "length": Uniform(0.10, 0.18),  # fuselage, nose to tail
        "fuselage_radius": Uniform(0.045, 0.07),  # / length
        "nose_length": Uniform(0.06, 0.14),  # / length
        "tail_length": Uniform(0.2, 0.32),  # / length, the tapering tail cone
        "wing_span": Uniform(0.8, 1.15),  # / length
        "wing_sweep": Uniform(0.0, 0.6),  # radians, of the leading edge
        "wing_chord": Uniform(0.14, 0.26),  # / length, at the root
        "wing_taper": Uniform(0.25, 0.7),  # tip chord / root chord
        "wing_position": Uniform(0.4, 0.58),  # root chord's middle, / length from the tail
        "wing_mount": Choice(("low", "mid", "high"), p=(0.5, 0.2, 0.3)),
        "dihedral": Uniform(0.0, 0.1),  # radians
        "fin_height": Uniform(0.1, 0.2),  # / length
        "fin_sweep": Uniform(0.3, 0.9),  # radians, of the fin's leading edge
        "stabiliser": Flag(0.9),
        "tail_style": Choice(("conventional", "t_tail"), p=(0.7, 0.3)),
        "stabiliser_span": Uniform(0.28, 0.45),  # / wing span
        "engine_pairs": Integer(0, 2),
        "engine_radius": Uniform(0.35, 0.55),  # / fuselage radius
    },
    shapenet_synsets=("02691156",),
    modelnet_names=("airplane",),
)
def build(p: Params) -> Assembly:
    """Airplane (18 parameters: fuselage length, radius, nose and tail cone length; wing
    span, sweep, root chord, taper, position, mount height, dihedral; fin height and sweep;
    stabiliser presence, T-tail, span; engine pairs and size)."""
    L = float(p["length"])
    R = float(np.clip(float(p["fuselage_radius"]), 0.03, 0.1)) * L
    nose = float(np.clip(float(p["nose_length"]), 0.03, 0.2)) * L
    tail = float(np.clip(float(p["tail_length"]), 0.12, 0.4)) * L

    # --- fuselage (x from the tail at 0 to the nose at L): sections (x, radius, centre z);
    # the tail cone's axis rises so that its top stays nearly level
    secs = [
        (0.0, 0.22 * R, 0.6 * R),
        (0.45 * tail, 0.6 * R, 0.3 * R),
        (tail, R, 0.0),
        (L - nose, R, 0.0),
        (L - 0.55 * nose, 0.85 * R, -0.06 * R),
        (L - 0.2 * nose, 0.5 * R, -0.15 * R),
        (L, 0.12 * R, -0.25 * R),
    ]
    parts = [
        hull(np.concatenate([_ring_x(x0, r0, z0), _ring_x(x1, r1, z1)]))
        for (x0, r0, z0), (x1, r1, z1) in itertools.pairwise(secs)
    ]

    # --- wings: root inside the fuselage (from y = -0.3 R so the two halves overlap)
    span = float(np.clip(float(p["wing_span"]), 0.5, 1.5)) * L
    semi = span / 2
    chord = float(np.clip(float(p["wing_chord"]), 0.08, 0.32)) * L
    tip_chord = float(np.clip(float(p["wing_taper"]), 0.15, 1.0)) * chord
    sweep = float(np.clip(float(p["wing_sweep"]), 0.0, 0.8))
    dihedral = float(p["dihedral"])
    # the root chord stays on the barrel, clear of the nose and of the tail cone's tip
    x_mid = float(
        np.clip(float(p["wing_position"]) * L, 0.6 * tail + chord / 2, L - nose - chord / 2)
    )
    x_le = x_mid + chord / 2
    z_w = {"low": -0.55, "mid": 0.0, "high": 0.55}[str(p["wing_mount"])] * R
    t_root = float(np.clip(0.12 * chord, 0.002, 0.9 * (R - abs(z_w)) + 0.002))
    t_tip = max(0.5 * t_root * tip_chord / chord, 0.0012)
    y_root = -0.3 * R

    def le_at(y: float) -> float:
        return x_le - max(y, 0.0) * np.tan(sweep)

    def z_at(y: float) -> float:
        return z_w + max(y, 0.0) * np.tan(dihedral)

    def chord_at(y: float) -> float:
        return chord + (tip_chord - chord) * max(y, 0.0) / semi

    wing = [
        hull(
            np.concatenate(
                [
                    _section(x_le, chord, y_root, z_w, t_root),
                    _section(le_at(semi), tip_chord, semi, z_at(semi), t_tip),
                ]
            )
        )
    ]
    parts += wing + mirror_y(wing)

    # --- engines: nacelles on pylons, forward of the wing's leading edge
    pairs = int(np.clip(int(p["engine_pairs"]), 0, 2))
    re = float(np.clip(float(p["engine_radius"]), 0.25, 0.7)) * R
    ln = float(np.clip(6.0 * re, 0.1 * L, 0.25 * L))
    # span stations: clear of the fuselage, and of each other
    stations: list[float] = []
    for f in {0: [], 1: [0.36], 2: [0.3, 0.6]}[pairs]:
        y_min = stations[-1] + 2.6 * re if stations else R + 1.3 * re
        stations.append(min(max(f * semi, y_min), 0.85 * semi))
    engines = []
    for y in stations:
        t_loc = t_root + (t_tip - t_root) * y / semi
        z_low = z_at(y) - 0.5 * t_loc  # the wing's underside
        zc = z_low - 1.25 * re
        x1 = le_at(y) + 0.45 * ln  # nacelle front
        x0 = x1 - ln
        engines.append(
            hull(
                np.concatenate(
                    [
                        _ring_x(x1, 0.9 * re, zc, y),
                        _ring_x(x1 - 0.25 * ln, re, zc, y),
                        _ring_x(x0, 0.65 * re, zc, y),
                    ]
                )
            )
        )
        # the pylon: from inside the nacelle up into the wing, along the front of the chord
        c_loc = chord_at(y)
        px1 = min(x1 - 0.2 * ln, le_at(y) - 0.05 * c_loc)
        px0 = max(x0 + 0.2 * ln, le_at(y) - 0.45 * c_loc)
        pz0, pz1 = zc, z_at(y) + 0.1 * t_loc
        engines.append(
            box((px1 - px0, 0.35 * re, pz1 - pz0), center=((px0 + px1) / 2, y, (pz0 + pz1) / 2))
        )
    parts += engines + mirror_y(engines)

    # --- tail: a swept fin on the tail cone, and the horizontal stabiliser
    fh = float(np.clip(float(p["fin_height"]), 0.05, 0.3)) * L
    fin_sweep = float(np.clip(float(p["fin_sweep"]), 0.1, 1.1))
    fc = float(np.clip(0.9 * tail, 0.6 * fh, 1.4 * fh))  # root chord
    fx_le = 0.95 * tail + 0.01 * L  # fin's root leading edge, on the barrel's start
    fx_le = min(fx_le, fc + 0.02 * L)
    # the root sits below the tail cone's top line over the whole root chord
    z_root = 0.55 * R
    z_tip = z_root + fh
    ftip_le = fx_le - fh * np.tan(fin_sweep)
    ftip_c = 0.55 * fc
    ftip_le = max(ftip_le, ftip_c - 0.02 * L)  # the tip does not overhang the tail much
    ft = float(np.clip(0.1 * fc, 0.0015, 0.8 * R))
    parts.append(
        hull(
            np.concatenate(
                [
                    _section(fx_le, fc, 0.0, z_root, ft, vertical=True),
                    _section(ftip_le, ftip_c, 0.0, z_tip, 0.6 * ft, vertical=True),
                ]
            )
        )
    )

    if p["stabiliser"]:
        ss = float(np.clip(float(p["stabiliser_span"]), 0.15, 0.6)) * span / 2
        if p["tail_style"] == "t_tail":
            sc = 0.9 * ftip_c
            s_le = ftip_le - 0.05 * ftip_c
            sz = z_tip - 0.3 * ft  # inside the fin's tip
        else:
            sc = float(np.clip(0.8 * fc, 0.05 * L, 0.25 * L))
            s_le = min(fx_le + 0.05 * fc, 0.5 * tail + sc)
            s_le = max(s_le, sc - 0.02 * L)
            # on the tail cone's axis at the stabiliser's mid chord
            xm = s_le - sc / 2
            sz = float(np.interp(xm, [s[0] for s in secs[:3]], [s[2] for s in secs[:3]]))
        st = float(np.clip(0.1 * sc, 0.0012, 0.6 * R))
        s_sweep = 0.6 * sweep + 0.15
        stab = [
            hull(
                np.concatenate(
                    [
                        _section(s_le, sc, -0.2 * R, sz, st),
                        _section(
                            s_le - ss * np.tan(s_sweep),
                            0.5 * sc,
                            ss,
                            sz + ss * 0.5 * dihedral,
                            0.6 * st,
                        ),
                    ]
                )
            )
        ]
        parts += stab + mirror_y(stab)

    return Assembly(parts, no_symmetry())
