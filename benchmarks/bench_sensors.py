"""Sensor figures (docs/sensors.md): each model against its published measurements, the
plots docs/sensors.md shows, and each sensor's capture time as a ratio to the ideal render
of the same scene, measured in the same run.

Writes docs/images/sensors_validation.png and docs/images/sensors_scene.png.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from harness import paired_median_times, report

from beo_bench.objects import ObjectSet
from beo_bench.scenes.camera import Intrinsics
from beo_bench.scenes.isolated import IsolatedRenderer
from beo_bench.scenes.pickconfig import PickConfig
from beo_bench.scenes.sensors import d435 as d435_mod
from beo_bench.scenes.sensors import kinect_v1 as kin
from beo_bench.scenes.sensors import make_sensor
from beo_bench.scenes.sensors.validation import Bench, shadow_width_px
from beo_bench.scenes.tabletop import TabletopScenes

IMAGES = Path(__file__).resolve().parent.parent / "docs" / "images"
VGA = Intrinsics(640, 480, 45.0)
DISTANCES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
ANGLES = (0, 30, 45, 70, 75)
LATERAL_ANGLES = (0, 30, 45, 60, 70, 75)
D4_SUBPIXEL = 0.08


def kinect_figures(rng: np.random.Generator) -> dict[str, object]:
    axial: dict[int, list[float]] = {}
    lateral: list[float] = []
    with Bench(make_sensor("kinect-v1", VGA)) as b:
        worst = 0.0
        for a in ANGLES:
            axial[a] = []
            for z in DISTANCES:
                s = b.plane(z, a, rng, captures=6).sigma
                curve = float(kin.axial_sigma(np.array(z), np.array(math.radians(a))))
                axial[a].append(s)
                worst = max(worst, abs(s / curve - 1))
        report(
            "kinect-v1 axial sigma vs Nguyen eq. 1, worst deviation",
            100 * worst,
            "%",
            "<= 10%",
            worst <= 0.10,
            f"{len(ANGLES) * len(DISTANCES)} planes, 0.5-3 m, 0-75 deg",
        )
        scale = b.sensor.f / kin.NATIVE_FOCAL_PX
        worst = 0.0
        for a in LATERAL_ANGLES:
            m = b.edge(1.0, a, rng, captures=6)
            lateral.append(m)
            curve = float(kin.lateral_sigma_px(np.array(math.radians(a)))) * scale
            worst = max(worst, abs(m / curve - 1))
        report(
            "kinect-v1 lateral sigma vs Nguyen eq. 2, worst deviation",
            100 * worst,
            "%",
            "<= 10%",
            worst <= 0.10,
            f"edges at 1 m, {LATERAL_ANGLES[0]}-{LATERAL_ANGLES[-1]} deg",
        )
        left, right = b.step(0.6, 1.0, rng)
        pred = shadow_width_px(b.sensor, kin.BASELINE, 0.6, 1.0)
        report(
            "kinect-v1 shadow left of a box (0.6 m on 1 m), width error",
            abs(left - pred),
            "px",
            "<= 2 px",
            abs(left - pred) <= 2.0,
            f"{left:.1f} px vs {pred:.1f}; right {right:.1f}",
        )
    return {"axial": axial, "lateral": lateral, "scale": scale}


def d435_figures(rng: np.random.Generator) -> dict[str, object]:
    sigma_d: list[float] = []
    fills: dict[int, float] = {}
    with Bench(make_sensor("d435", VGA)) as b:
        s = b.sensor
        for z in DISTANCES:
            # the distance spread moves the disparity over +-1 px: an average over where it
            # falls between whole pixels (SGBM's error depends on it)
            rms = b.plane(z, 0, rng, captures=12, spread=z / (s.f * d435_mod.BASELINE)).rms
            sigma_d.append(rms * s.f * d435_mod.BASELINE / z**2)
        worst = max(abs(x / D4_SUBPIXEL - 1) for x in sigma_d)
        report(
            "d435 sigma_d from RMS error z^2 sigma_d/(f b), worst vs 0.08 px",
            100 * worst,
            "%",
            "<= 25%",
            worst <= 0.25,
            "sigma_d " + ", ".join(f"{x:.3f}" for x in sigma_d),
        )
        for a in (0, 45, 60, 75, 82):
            fills[a] = b.plane(1.0, a, rng, captures=2).fill
        report(
            "d435 fill rate, lit plane at 1 m",
            100 * fills[0],
            "%",
            ">= 99%",
            fills[0] >= 0.99,
            "at 45/60/75/82 deg: " + ", ".join(f"{100 * fills[a]:.1f}%" for a in (45, 60, 75, 82)),
        )
        left, right = b.step(0.6, 1.0, rng, captures=2)
        pred = shadow_width_px(s, d435_mod.BASELINE, 0.6, 1.0)
        report(
            "d435 invalid band left of a box (0.6 m on 1 m), width error",
            abs(left - pred),
            "px",
            "<= 2 px",
            abs(left - pred) <= 2.0,
            f"{left:.1f} px vs {pred:.1f}; right {right:.1f}",
        )
    return {"sigma_d": sigma_d, "fills": fills}


def speed(rng: np.random.Generator) -> dict[str, np.ndarray]:
    scenes = TabletopScenes(PickConfig(objects=ObjectSet("test"), num_objects=(3, 4)))
    scenes.reset(seed=11)
    r = scenes._bound_renderer()
    data, cam = scenes.scene.data, scenes.cam  # type: ignore[union-attr]
    images = {"ideal": r.render(data, cam).depth}
    for name, target in (("kinect-v1", 2.0), ("d435", 10.0)):
        sensor = make_sensor(name, scenes.config.intrinsics)
        sensor.capture(r, data, cam, rng)  # its scratch arrays, once
        t, ideal = paired_median_times(
            lambda s=sensor: s.capture(r, data, cam, rng), lambda: r.render(data, cam), 25
        )
        images[name] = sensor.capture(r, data, cam, rng).depth
        report(
            f"{name} capture / ideal render, 640x480 tabletop",
            t / ideal,
            "x",
            f"<= {target:g}x",
            t / ideal <= target,
            f"{1e3 * t:.1f} ms vs {1e3 * ideal:.1f} ms",
        )
    scenes.close()
    iso = IsolatedRenderer(Intrinsics(128, 128, 45.0))
    inst = ObjectSet("test").get("chair", 0)
    view = iso.rig.sample(np.random.default_rng(3), np.zeros(3))
    iso.render(inst, view)
    rr = iso._renderer
    d = iso._models[inst.key][1]
    sensor = make_sensor("d435", iso.intrinsics)
    sensor.capture(rr, d, view, rng)
    t, ideal = paired_median_times(
        lambda: sensor.capture(rr, d, view, rng), lambda: rr.render(d, view), 60
    )
    report(
        "d435 capture / ideal render, 128x128 isolated view",
        t / ideal,
        "x",
        "<= 5x",
        t / ideal <= 5.0,
        f"{1e3 * t:.2f} ms vs {1e3 * ideal:.2f} ms",
    )
    iso.close()
    return images


def plots(k: dict[str, object], d: dict[str, object], images: dict[str, np.ndarray]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    zs = np.linspace(0.45, 3.1, 100)
    axial = k["axial"]
    assert isinstance(axial, dict)
    for i, a in enumerate(ANGLES):
        c = f"C{i}"
        curve = kin.axial_sigma(zs, np.full_like(zs, math.radians(a)))
        ax[0].plot(zs, 1e3 * curve, c, lw=1, label=f"Nguyen eq. 1, {a} deg")
        ax[0].plot(DISTANCES, 1e3 * np.array(axial[a]), c + "o", ms=4)
    ax[0].set(xlabel="distance (m)", ylabel="axial sigma (mm)", title="kinect-v1 axial noise")
    ax[0].legend(fontsize=7)
    th = np.linspace(0, 75, 100)
    scale = float(k["scale"])  # type: ignore[arg-type]
    ax[1].plot(th, scale * kin.lateral_sigma_px(np.radians(th)), "k", lw=1, label="Nguyen eq. 2")
    ax[1].plot(LATERAL_ANGLES, k["lateral"], "o", label="measured (edge at 1 m)")
    ax[1].set(
        xlabel="angle (deg)",
        ylabel="lateral sigma (px at 640x480, 45 deg)",
        title="kinect-v1 lateral noise",
    )
    ax[1].legend(fontsize=8)
    f, b = VGA.focal, d435_mod.BASELINE
    sd = np.array(d["sigma_d"])  # type: ignore[arg-type]
    ax[2].plot(zs, 1e3 * zs**2 * D4_SUBPIXEL / (f * b), "k", lw=1, label="z^2 0.08 px / (f b)")
    ax[2].plot(DISTANCES, 1e3 * np.array(DISTANCES) ** 2 * sd / (f * b), "o", label="measured RMS")
    ax[2].set(xlabel="distance (m)", ylabel="RMS depth error (mm)", title="d435 on a lit plane")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    IMAGES.mkdir(parents=True, exist_ok=True)
    fig.savefig(IMAGES / "sensors_validation.png", dpi=90)
    plt.close(fig)

    fig, ax = plt.subplots(1, 3, figsize=(15, 4))
    valid = images["ideal"][images["ideal"] > 0]
    lo, hi = float(np.percentile(valid, 1)), float(np.percentile(valid, 99))
    for a, (name, img) in zip(ax, images.items(), strict=True):
        shown = np.where(img > 0, img, np.nan)
        a.imshow(shown, cmap="viridis", vmin=lo, vmax=hi)
        a.set_title(f"{name} ({100 * np.mean(img > 0):.0f}% of pixels with depth)")
        a.axis("off")
    fig.tight_layout()
    fig.savefig(IMAGES / "sensors_scene.png", dpi=80)
    plt.close(fig)


def main() -> None:
    rng = np.random.default_rng(0)
    k = kinect_figures(rng)
    d = d435_figures(rng)
    images = speed(rng)
    plots(k, d, images)
    print(f"  wrote {IMAGES / 'sensors_validation.png'} and sensors_scene.png")
