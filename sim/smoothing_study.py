"""Smoothing measured as Hong & DeSouza do: path length (their Table I) and the histogram of
turning angles (their Figure 6), for the grid path, the rubber band and the turning points.

The path is the planner's path across each seeded courtyard with every obstacle known, so the
three forms describe the same route.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from daemon.guidance.smoothing import path_length, rubber_band, turning_angles
from daemon.guidance.turning_points import turning_points
from daemon.planning import make_planner

from .courtyard import dilate, make_courtyard

BINS = np.append(np.arange(0, 95, 5), 180)
PATH_FORMS = ("raw", "band", "turning")
WALK_FORMS = ("walk_raw", "walk_band")
NAMES = {
    "raw": "grid path (8-connected)",
    "band": "rubber band",
    "turning": "turning points",
    "walk_raw": "walked, guided along the grid path",
    "walk_band": "walked, guided along the rubber band",
}


def smoothing_study(
    grids: list[int], unknowns: list[float], runs: int = 20, first_seed: int = 0
) -> dict:
    """Mean lengths per grid and density; turning-angle histograms pooled over everything.

    Path forms: the planner's path on the fully known map, its rubber band, its turning
    points. Walked forms: the belt walker's track through the same courtyard (obstacles found
    on the way), guided without and with smoothing.
    """
    from .walks import belt_walk

    forms_all = PATH_FORMS + WALK_FORMS
    hist = {f: np.zeros(len(BINS) - 1, dtype=np.int64) for f in forms_all}
    rows = []
    planner = make_planner("eds", "cpu")
    for grid in grids:
        for unknown in unknowns:
            lengths: dict[str, list[float]] = {f: [] for f in forms_all}
            for i in range(runs):
                seed = first_seed + i
                sc = make_courtyard(grid, unknown, seed=seed)
                blocked = dilate(sc.true == 1, sc.radius_cells)
                planner.plan(blocked, sc.goal)
                path = planner.path(sc.start)
                forms = {
                    "raw": path.astype(np.float64) + 0.5,
                    "band": rubber_band(path, blocked, cell_m=sc.cell_m),
                    "turning": turning_points(path, blocked),
                }
                for name, pts in forms.items():
                    lengths[name].append(path_length(pts, sc.cell_m))
                    hist[name] += np.histogram(turning_angles(pts), bins=BINS)[0]
                for name, smooth in (("walk_raw", False), ("walk_band", True)):
                    walk = belt_walk(sc, seed=seed, smooth=smooth)
                    lengths[name].append(walk.walked_m)
                    hist[name] += np.histogram(turning_angles(walk.track), bins=BINS)[0]
            row = {"grid": grid, "unknown": unknown, "runs": runs}
            row.update({f"{f}_m": float(np.mean(lengths[f])) for f in forms_all})
            rows.append(row)
    return {"rows": rows, "hist": {k: v.tolist() for k, v in hist.items()}, "bins": BINS.tolist()}


def plot_study(study: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    bins = np.array(study["bins"], dtype=float)
    labels = [
        f"{int(a)}–{int(b)}" if b < 180 else f"≥{int(a)}" for a, b in itertools.pairwise(bins)
    ]
    x = np.arange(len(labels))
    fig, axes = plt.subplots(2, 1, figsize=(10, 7.5), sharex=True)
    for ax, forms, title in (
        (axes[0], PATH_FORMS, "the path (all obstacles known)"),
        (axes[1], WALK_FORMS, "what the belt walker walked (obstacles found on the way)"),
    ):
        width = 0.8 / len(forms)
        for k, form in enumerate(forms):
            counts = np.array(study["hist"][form], dtype=float)
            share = 100.0 * counts / max(1.0, counts.sum())
            nz = counts > 0  # log axis: empty bins are left empty, not drawn
            offset = (k - (len(forms) - 1) / 2) * width
            ax.bar(x[nz] + offset, share[nz], width=width,
                   label=f"{NAMES[form]} ({int(counts.sum())} vertices)")
        ax.set_yscale("log")
        ax.set_ylabel("% of vertices (log)")
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=8)
    axes[1].set_xticks(x, labels, rotation=45, ha="right")
    axes[1].set_xlabel("turning angle at a vertex (degrees)")
    runs = study["rows"][0]["runs"] if study["rows"] else 0
    grids = sorted({r["grid"] for r in study["rows"]})
    fig.suptitle(f"Turning angles with and without smoothing ({runs} courtyards per grid and "
                 f"density, grids {grids})")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
