"""Hong & DeSouza's Table I and Figure 6 beside EDS, and the dynamic trials' table.

Table I: on the courtyard and four indoor layouts (``building`` floor plans, seeds 0–3:
corridors, rooms and doors, like the paper's Figure 5), fully known, inflated by the user's
radius, the length of each path from the scenario's start to its goal:

- ``harmonic``: the descent over the harmonic field (the paper's "harmonic path");
- ``band``: that path after the paper's rubber band (``harmonic/rubber_band.py``, "optimized");
- ``eds``: EDS's grid path (8-connected, shortest in 10/14 units);
- ``eds_turning``: EDS's path after guidance's turning points (any-angle shortcuts): what the
  belt actually guides along.

Figure 6: the histogram of turning angles (degrees, the angle between consecutive segments at
every vertex, ``guidance.smoothing.turning_angles``) of each path type over all five maps.

The dynamic trials (``sim/movers.py``) are run by ``guidebelt walks --movers N``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time

import numpy as np

from daemon.guidance.smoothing import path_length, smooth_path, turning_angles
from daemon.guidance.turning_points import turning_points
from daemon.planning import make_planner

from .courtyard import dilate
from .scenarios import make_scenario

MAPS = (("courtyard", 100, 0), ("building", 200, 0), ("building", 200, 1), ("building", 200, 2),
        ("building", 200, 3))  # fmt: skip
"""(scenario, grid, seed): 10 m courtyard and 20 m floor plans, both at 0.1 m cells."""
KINDS = ("harmonic", "band", "eds", "eds_turning")
BINS = np.array([0, 5, 10, 15, 20, 25, 30, 40, 50, 60, 70, 90, 180])
PAPER_TABLE_I = {"harmonic": (2.34, 3.80, 2.85, 3.22), "band": (2.34, 3.72, 2.75, 3.26)}
"""Table I of the paper, metres, its scenes 1–4 (not our maps: their lengths are beside ours
for the ratio band / harmonic, which is what carries over)."""


def map_paths(name: str, grid: int, seed: int, backend: str = "cpu") -> dict:
    scenario = make_scenario(name, grid, 0.0, seed)
    blocked = dilate(scenario.true == 1, scenario.radius_cells)
    harmonic = make_planner("harmonic", backend)
    harmonic.plan(blocked, scenario.goal)
    eds = make_planner("eds", "cpu")
    eds.plan(blocked, scenario.goal)
    h_path = harmonic.path(scenario.start)
    e_path = eds.path(scenario.start)
    t0 = time.perf_counter()
    band = smooth_path("harmonic", h_path, blocked, scenario.cell_m, field=harmonic.field())
    band_ms = (time.perf_counter() - t0) * 1e3
    return {
        "map": f"{name}-{seed}", "cell_m": scenario.cell_m, "band_ms": round(band_ms, 2),
        "points": {
            "harmonic": h_path.astype(np.float64) + 0.5,
            "band": band,
            "eds": e_path.astype(np.float64) + 0.5,
            "eds_turning": turning_points(e_path, blocked),
        },
    }  # fmt: skip


def study(backend: str = "cpu") -> dict:
    rows, angles = [], {k: [] for k in KINDS}
    for name, grid, seed in MAPS:
        m = map_paths(name, grid, seed, backend)
        row = {"map": m["map"], "band_ms": m["band_ms"]}
        for kind in KINDS:
            pts = m["points"][kind]
            row[f"{kind}_m"] = round(path_length(pts, m["cell_m"]), 2) if len(pts) else None
            angles[kind].extend(turning_angles(pts).tolist())
        rows.append(row)
    hist = {k: np.histogram(np.array(v), bins=BINS)[0].tolist() for k, v in angles.items()}
    share = {k: round(float(np.mean(np.array(v) > 30)), 3) if v else None
             for k, v in angles.items()}  # fmt: skip
    return {"rows": rows, "bins_deg": BINS.tolist(), "histograms": hist,
            "share_over_30deg": share, "paper_table_i": PAPER_TABLE_I}  # fmt: skip


def plot(result: dict, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(KINDS), figsize=(4 * len(KINDS), 3.2), sharey=True)
    labels = [f"{a}-{b}" for a, b in itertools.pairwise(BINS)]
    titles = {"harmonic": "harmonic path", "band": "rubber band (paper)",
              "eds": "EDS grid path", "eds_turning": "EDS turning points"}  # fmt: skip
    for ax, kind in zip(axes, KINDS, strict=True):
        counts = np.array(result["histograms"][kind], dtype=float)
        ax.bar(range(len(counts)), counts / max(1.0, counts.sum()), color="tab:blue")
        ax.set_xticks(range(len(counts)), labels, rotation=70, fontsize=7)
        ax.set_title(titles[kind], fontsize=9)
        ax.set_xlabel("turning angle (deg)", fontsize=8)
    axes[0].set_ylabel("share of vertices")
    fig.suptitle("Turning angles, courtyard + 4 floor plans (Hong & DeSouza Fig. 6 beside EDS)",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description="Table I and Figure 6, harmonic beside EDS")
    parser.add_argument("--backend", default="cpu")
    parser.add_argument("--json", default=None)
    parser.add_argument("--png", default=None)
    a = parser.parse_args()
    result = study(a.backend)
    print(json.dumps(result, indent=1))
    if a.json:
        with open(a.json, "w") as f:
            f.write(json.dumps(result, indent=1) + "\n")
    if a.png:
        plot(result, a.png)


if __name__ == "__main__":
    main()
