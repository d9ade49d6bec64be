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
from drivers.rfid.tag_payload import ObstaclePayload, encode, polygon_cells


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


def tag_memories(tag_map, occupancy: np.ndarray, cell_m: float) -> dict[str, bytes]:
    """Each UHF tag's user memory: the polygon of the obstacle piece it is fixed to (the
    piece holding the tag's cell, else the nearest within ``REACH_CELLS``), with the tag's
    own coordinates. A tag near no obstacle carries nothing. This is what the world gives
    the mock reader, as a surveyor writes it into the tags."""
    occupied = np.ascontiguousarray(np.asarray(occupancy) == OCCUPIED)
    h = occupied.shape[0]
    owner = np.full(occupied.shape, -1, dtype=np.int64)
    polygons: list[tuple[tuple[float, float], ...]] = []
    labels, n = label_components(occupied)
    for k in range(1, n + 1):
        rows, cols = np.nonzero(labels == k)
        for piece in component_pieces(~occupied, rows, cols):
            verts = _metres(piece.vertices, occupied.shape, cell_m)
            cells = polygon_cells(verts, occupied.shape, cell_m)
            owner.reshape(-1)[cells] = len(polygons)
            polygons.append(tuple((float(x), float(y)) for x, y in verts))
    out: dict[str, bytes] = {}
    for tag_id, (x, y) in zip(tag_map.uhf_ids, tag_map.uhf_xy, strict=True):
        r, c = h - 1 - int(y / cell_m), int(x / cell_m)
        r0, c0 = max(r - REACH_CELLS, 0), max(c - REACH_CELLS, 0)
        near = owner[r0 : r + REACH_CELLS + 1, c0 : c + REACH_CELLS + 1]
        rr, cc = np.nonzero(near >= 0)
        if rr.size == 0:
            continue
        i = int(np.argmin((rr + r0 - r) ** 2 + (cc + c0 - c) ** 2))
        key = int(near[rr[i], cc[i]])
        payload = ObstaclePayload(obstacle=key, x=float(x), y=float(y), vertices=polygons[key])
        out[tag_id] = encode(payload)
    return out


REACH_CELLS = 3
"""A tag is fixed to an obstacle: on its cells or beside them."""
