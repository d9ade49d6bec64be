"""A picture of one walk, in the manner of the paper's Figure 5.

Known obstacles, unknown obstacles the sensor saw and those it never saw, the inflation
by the user's radius, the path walked, start and goal — in metres, north up.
matplotlib (Agg) is imported only here, so the planner and the benchmark run without it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from daemon.planning.grid import OCCUPIED, UNKNOWN

from .courtyard import Scenario
from .walk import WalkPicture

COLOURS = {
    "free, seen": (1.0, 1.0, 1.0),
    "free, never seen": (0.93, 0.93, 0.93),
    "inflation (user's radius)": (0.78, 0.84, 0.94),
    "known obstacle": (0.15, 0.15, 0.15),
    "unknown obstacle, seen": (0.85, 0.30, 0.10),
    "unknown obstacle, never seen": (0.98, 0.75, 0.65),
}


def walk_image(scenario: Scenario, result: WalkPicture) -> np.ndarray:
    """``(h, w, 3)`` float RGB: one colour per cell class of ``COLOURS``."""
    known0 = scenario.known == OCCUPIED
    true_occ = scenario.true == OCCUPIED
    seen_occ = result.known == OCCUPIED
    classes = [
        (result.known != UNKNOWN, "free, seen"),
        (result.known == UNKNOWN, "free, never seen"),
        (result.blocked, "inflation (user's radius)"),
        (true_occ & ~known0 & ~seen_occ, "unknown obstacle, never seen"),
        (true_occ & ~known0 & seen_occ, "unknown obstacle, seen"),
        (known0, "known obstacle"),
    ]
    img = np.zeros((*scenario.shape, 3), dtype=np.float32)
    for mask, name in classes:  # later classes paint over earlier ones
        img[mask] = COLOURS[name]
    return img


def render_walk(scenario: Scenario, result: WalkPicture, out: Path | str, dpi: int = 150) -> Path:
    """Save the picture of ``result`` on ``scenario`` as a PNG; return its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    h, w = scenario.shape
    size_m = (w * scenario.cell_m, h * scenario.cell_m)
    fig, ax = plt.subplots(figsize=(8.8, 6.2), dpi=dpi)
    ax.imshow(
        walk_image(scenario, result),
        extent=(0, size_m[0], 0, size_m[1]),
        origin="upper",
        interpolation="nearest",
    )

    def xy(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cells = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
        return (cells[:, 1] + 0.5) * scenario.cell_m, (h - cells[:, 0] - 0.5) * scenario.cell_m

    px, py = xy(result.walked)
    ax.plot(px, py, color=(0.1, 0.35, 0.9), linewidth=1.8, label="path walked")
    sx, sy = xy(np.array(scenario.start))
    gx, gy = xy(np.array(scenario.goal))
    ax.plot(sx, sy, "o", color=(0.1, 0.6, 0.2), markersize=9, label="start")
    ax.plot(gx, gy, "*", color=(0.85, 0.1, 0.1), markersize=14, label="goal")
    handles = [Patch(facecolor=c, edgecolor="0.6", label=n) for n, c in COLOURS.items()]
    handles += [
        Line2D([], [], color=(0.1, 0.35, 0.9), linewidth=1.8, label="path walked"),
        Line2D([], [], marker="o", linestyle="", color=(0.1, 0.6, 0.2), label="start"),
        Line2D([], [], marker="*", linestyle="", color=(0.85, 0.1, 0.1), markersize=10,
               label="goal"),
    ]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8,
              frameon=False)
    status = "arrived" if result.arrived else result.reason
    ax.set_title(
        f"{scenario.name} {w}x{h} ({scenario.cell_m * 100:.3g} cm), "
        f"{scenario.unknown:.0%} unknown, seed {scenario.seed}: {result.mode.upper()}, "
        f"{status} in {result.steps} steps ({result.walked_m:.1f} m)",
        fontsize=9,
    )
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out)
    plt.close(fig)
    return out
