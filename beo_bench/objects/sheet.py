"""A contact sheet: several instances per category, shaded, in one PNG a person can read.

Drawn with matplotlib (no GL needed), in a fixed 3/4 view from the front-left-above so the
canonical +x front faces the viewer; every object is scaled to its own cell with its size
printed underneath.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from beo_bench.objects.objectset import ObjectSet

_LIGHT = np.array([0.4, -0.3, 0.85]) / np.linalg.norm([0.4, -0.3, 0.85])


HEAD_IN = 0.9
"""Inches above the first row of pictures: the title's band and the row's size labels."""


def contact_sheet(
    path: str | Path,
    objects: ObjectSet,
    per_category: int = 6,
    categories: Sequence[str] | None = None,
    columns: int = 8,
) -> Path:
    """Draw ``per_category`` instances of each category into ``path``: a category per row,
    wrapped onto further rows after ``columns`` instances (a one-class sheet of 16 is two
    rows of 8)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    cats = list(categories or objects.categories)
    cols = min(per_category, columns)
    wraps = -(-per_category // cols)  # rows a category takes
    nrows = wraps * len(cats)
    fig = plt.figure(figsize=(1.9 * cols + 1.2, 1.9 * nrows), dpi=90)
    cmap = matplotlib.colormaps["tab10"]
    for r, cat in enumerate(cats):
        n = min(per_category, objects.count(cat))
        for c in range(n):
            inst = objects.get(cat, c)
            m = inst.mesh
            cell = (r * wraps + c // cols) * cols + c % cols + 1
            ax = fig.add_subplot(nrows, cols, cell, projection="3d")
            tri = m.vertices[m.faces]
            shade = 0.35 + 0.65 * np.clip(m.face_normals @ _LIGHT, 0, 1)
            base = np.array(cmap(r % 10)[:3])
            colors = np.clip(base[None] * shade[:, None] + 0.15 * shade[:, None], 0, 1)
            ax.add_collection3d(Poly3DCollection(tri, facecolors=colors, linewidths=0))
            h = m.extents.max() / 2
            ax.set(xlim=(-h, h), ylim=(-h, h), zlim=(-h, h))
            ax.set_box_aspect((1, 1, 1))
            ax.view_init(elev=22, azim=-35)  # camera front-left-above: +x front visible
            ax.set_axis_off()
            ex = m.extents * 100
            ax.set_title(f"{ex[0]:.0f}x{ex[1]:.0f}x{ex[2]:.0f} cm", fontsize=7, pad=-4)
            if c == 0:
                ax.text2D(
                    -0.18,
                    0.5,
                    cat,
                    transform=ax.transAxes,
                    rotation=90,
                    va="center",
                    ha="center",
                    fontsize=11,
                    weight="bold",
                )
    # The title and the first row's size labels in inches from the top, whatever the
    # figure's height: the title's band (0.2-0.5 in) ends above the labels, which sit just
    # over the first row of axes (at HEAD_IN); suptitle's default y, a fraction of a tall
    # sheet's height, put it on them.
    height = 1.9 * nrows
    fig.suptitle(
        f"beo-bench object library: split {objects.split!r}, first {per_category} instances "
        "per category",
        fontsize=12,
        y=1 - 0.35 / height,
        va="center",
    )
    fig.subplots_adjust(
        left=0.04, right=0.99, top=1 - HEAD_IN / height, bottom=0.01, wspace=0.02, hspace=0.15
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
