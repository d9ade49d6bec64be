"""What the surveyor writes into the UHF tags: each known obstacle's feature points.

The known obstacles of a map are cut into the paper's convex polygons of fewer than seven
edges by the same cutter the visibility-graph planner uses
(``daemon.planning.visgraph.polygons.component_pieces``), so a polygon covers its cells'
squares and no free cell's centre. Each polygon is one obstacle; a tag sits at each of its
feature points and carries the polygon (``drivers.rfid.tag_payload``).
"""

from __future__ import annotations

import numpy as np

from daemon.planning.grid import OCCUPIED
from daemon.planning.visgraph.polygons import component_pieces, label_components
from drivers.rfid.tag_payload import ObstaclePayload, encode


def _metres(piece: np.ndarray, shape: tuple[int, int], cell_m: float) -> np.ndarray:
    """(row, col) cell coordinates (cell (r, c) is the square around (r, c)) → metres,
    rounded to the payload's centimetre and kept on the map, collinear points dropped."""
    h, w = shape
    xy = np.column_stack([(piece[:, 1] + 0.5) * cell_m, (h - piece[:, 0] - 0.5) * cell_m])
    xy = np.clip(np.round(xy, 2), 0.0, [w * cell_m, h * cell_m])
    keep = []
    for i in range(len(xy)):
        a, b, c = xy[i - 1], xy[i], xy[(i + 1) % len(xy)]
        if (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]) > 1e-9:
            keep.append(b)
    return np.array(keep)


def obstacle_payloads(occupancy: np.ndarray, cell_m: float) -> list[bytes]:
    """One payload per feature point of every obstacle polygon of ``occupancy``."""
    occupied = np.ascontiguousarray(np.asarray(occupancy) == OCCUPIED)
    labels, n = label_components(occupied)
    out: list[bytes] = []
    key = 0
    for k in range(1, n + 1):
        rows, cols = np.nonzero(labels == k)
        for piece in component_pieces(~occupied, rows, cols):
            verts = _metres(piece.vertices, occupied.shape, cell_m)
            polygon = tuple((float(x), float(y)) for x, y in verts)
            for x, y in polygon:
                out.append(encode(ObstaclePayload(obstacle=key, x=x, y=y, vertices=polygon)))
            key += 1
    return out
