"""Chen et al.'s visibility graph with A* behind guidebelt's planner interface (``"visgraph"``).

``plan`` cuts the blocked map into the paper's obstacle polygons (``polygons.py``) and keeps
their feature points; ``path(start)`` attaches the start and the goal and runs A* with the
Euclidean heuristic over the points of visibility (``graph.py``), then turns the any-angle
path into grid cells (``raster.py``). The polygons, their points and every visibility judged
between two points stay while the map stands, so a new start or goal rebuilds nothing.

``update`` applies the cells and cuts again only the blocks of the map that hold a changed cell
(``PolygonMap``); the points and the visibility cache are rebuilt whenever a polygon changed
(a changed polygon can hide or reveal any pair). ``UpdateStats`` of ``update``:
``iterations`` = blocks cut again, ``cells_touched`` = cells written.

Bad input answers as ``cpu/astar.py`` does (and EDS): a goal or start blocked, outside the
map or cut off gives an empty ``(0, 2)`` path and ``INF``; a start on the goal gives the goal
alone at cost 0; an update with a cell outside the map is an IndexError and applies nothing;
an update before ``plan`` is a RuntimeError, a query before it answers no path.

Narrow doors. A passage whose free cells touch only corner to corner is shut by the polygons
(their outward offset covers the shared corner), and the grid's 8-connected path through it
is lost: the graph then has no path while the grid has one. With ``fallback=True`` (the
registry's default) the planner then answers the grid's A* path (``cpu/astar.py``) and counts
it in ``fallbacks``; with ``fallback=False`` it answers no path. ``sim/visgraph_study.py``
measures how often that happens on the courtyard walks.

``cost_at(cell)`` is the cost, in the grid's 10/14 units, of the cells ``path(cell)`` gives
(the navigator sums the same); ``costs_within`` gives the grid's exact costs of a window, for
the escape from the inflation margin. The Euclidean length of the last polygon path, in cells, is
``last_length``; ``search_stats`` holds the last search (nodes expanded, visibility judgements,
wall time).
"""

from __future__ import annotations

import time

import numpy as np

from ..grid import INF, Cell, checked_plan_input, checked_update_input, in_bounds, path_cost
from ..interface import GlobalPlanner, UpdateStats
from . import graph as vg
from .polygons import MAX_EDGES, PolygonMap
from .raster import rasterise

_EMPTY = np.empty((0, 2), dtype=np.int32)


class VisGraphPlanner(GlobalPlanner):
    backend = "cpu"

    def __init__(
        self, heuristic: bool = True, fallback: bool = True, extra_cells: float = 0.0
    ) -> None:
        self.use_h = bool(heuristic)
        self.fallback = bool(fallback)
        self.name = "visgraph-cpu" + ("" if heuristic else "-dijkstra")
        self.polygons = PolygonMap(extra_cells)
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)
        self._blocked = np.zeros((0, 0), dtype=bool)
        self._version = 0
        self._cached: tuple[tuple[Cell, int], np.ndarray, int] | None = None
        self._grid = None  # the A* of the fallback, made when first needed
        self._grid_version = -1
        self.fallbacks = 0
        """Path reads answered by the grid's A* because the graph had no path."""
        self.last_fell_back = False
        self.last_length = float("inf")
        """Euclidean length (cells) of the last polygon path; inf if none or fallen back."""
        self.search_stats: UpdateStats | None = None

    @property
    def goal(self) -> Cell:
        return self._goal

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    # -- the map ----------------------------------------------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        """Store the map and goal and cut it into polygons (blocks seen before keep theirs).
        The same map with another goal keeps everything: polygons, points and judgements."""
        t0 = time.perf_counter()
        blocked, shape, goal = checked_plan_input(blocked, goal)
        if shape == self._shape and np.array_equal(blocked, self._blocked):
            # The same map, a new goal: the polygons, points and judgements stand (§4.4).
            self._goal = goal
            self._version += 1
            return UpdateStats(0, 0, (time.perf_counter() - t0) * 1e3)
        self._shape, self._goal = shape, goal
        self._blocked = blocked.copy()
        self._version += 1
        self._rebuild()
        return UpdateStats(self.polygons.cut, int(blocked.size), (time.perf_counter() - t0) * 1e3)

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        """Apply ``blocked[cells] = blocked`` and cut again what the change reaches."""
        t0 = time.perf_counter()
        cells, values = checked_update_input(self._shape, cells, blocked)
        flat = self._blocked.reshape(-1)
        moved = cells[flat[cells] != values]
        flat[cells] = values
        cut = 0
        if moved.size:
            self._version += 1
            self._rebuild()
            cut = self.polygons.cut
        return UpdateStats(cut, int(cells.size), (time.perf_counter() - t0) * 1e3)

    def blocked(self) -> np.ndarray:
        return self._blocked.copy()

    def _rebuild(self) -> None:
        """Polygons (cut again in the blocks that changed), their index, nodes and cache."""
        pieces = self.polygons.build(self._blocked)
        count = len(pieces)
        px = np.zeros((count, MAX_EDGES))
        py = np.zeros((count, MAX_EDGES))
        pn = np.zeros(count, dtype=np.int64)
        bbox = np.zeros((count, 4))
        for i, piece in enumerate(pieces):
            k = len(piece.vertices)
            px[i, :k], py[i, :k], pn[i] = piece.vertices[:, 0], piece.vertices[:, 1], k
            bbox[i] = (px[i, :k].min(), px[i, :k].max(), py[i, :k].min(), py[i, :k].max())
        h, w = self._shape
        th, tw = (h + 1) // vg.TILE + 2, (w + 1) // vg.TILE + 2
        starts, items = vg.build_index(px, py, pn, bbox, th, tw)
        keep = vg.vertices_outside(px, py, pn, bbox, starts, items, th, tw, h, w)
        keep[np.arange(MAX_EDGES)[None, :] >= pn[:, None]] = False
        poly_of, k_of = np.nonzero(keep)
        m = poly_of.size + 2  # the feature points, then S, then G
        self._px, self._py, self._pn, self._bbox = px, py, pn, bbox
        self._starts, self._items, self._th, self._tw = starts, items, th, tw
        self._vx = np.concatenate([px[poly_of, k_of], [0.0, 0.0]])
        self._vy = np.concatenate([py[poly_of, k_of], [0.0, 0.0]])
        self._vpoly = np.concatenate([poly_of, [-1, -1]]).astype(np.int64)
        self._vk = np.concatenate([k_of, [0, 0]]).astype(np.int64)
        self._vis = np.zeros((m, m), dtype=np.int8)
        self._stamp = np.zeros(max(count, 1), dtype=np.int64)
        self._epoch = np.zeros(1, dtype=np.int64)
        self._g = np.empty(m)
        self._parent = np.empty(m, dtype=np.int64)

    @property
    def nodes(self) -> np.ndarray:
        """The feature points that are nodes of the graph, ``(n, 2)`` (row, col)."""
        return np.stack([self._vx[:-2], self._vy[:-2]], axis=1)

    def pieces(self) -> list[np.ndarray]:
        """The obstacle polygons, each ``(k, 2)`` counter-clockwise in (row, col)."""
        return [p.vertices for p in self.polygons.pieces]

    # -- searches ---------------------------------------------------------------------------

    def polygon_path(
        self, start: Cell, whole_graph: bool = False
    ) -> tuple[np.ndarray, float, np.ndarray]:
        """A* over the points of visibility from ``start``: (points (k, 2), length, stats).

        Points are (row, col) in cells; (empty, inf) when the graph has no path.
        ``whole_graph`` first judges every pair of nodes, as a planner does that builds the
        whole visibility graph for each start and goal (the paper's Dijkstra baseline)."""
        s, goal = len(self._vx) - 2, len(self._vx) - 1
        self._vx[s], self._vy[s] = start
        self._vx[goal], self._vy[goal] = self._goal
        for node in (s, goal):  # the old S and G's judgements are void
            self._vis[node, :] = vg.UNKNOWN
            self._vis[:, node] = vg.UNKNOWN
        stats = np.zeros(vg.STATS, dtype=np.int64)
        if whole_graph:
            vg.full_graph(
                self._vx, self._vy, self._vpoly, self._vk, self._vis, self._px, self._py,
                self._pn, self._bbox, self._starts, self._items, self._th, self._tw,
                self._stamp, self._epoch, stats,
            )  # fmt: skip
        length = vg.search(
            self._vx, self._vy, self._vpoly, self._vk, self._vis, self._px, self._py,
            self._pn, self._bbox, self._starts, self._items, self._th, self._tw, self._stamp,
            self._epoch, s, goal, self.use_h, self._g, self._parent, stats,
        )  # fmt: skip
        if not np.isfinite(length):
            return np.empty((0, 2)), float("inf"), stats
        chain = [goal]
        while chain[-1] != s:
            chain.append(int(self._parent[chain[-1]]))
        idx = np.array(chain[::-1])
        return np.stack([self._vx[idx], self._vy[idx]], axis=1), float(length), stats

    def _grid_path(self, start: Cell) -> np.ndarray:
        from ..cpu.astar import AStarPlanner

        if self._grid is None:
            self._grid = AStarPlanner()
        if self._grid_version != self._version:
            self._grid.plan(self._blocked, self._goal)
            self._grid_version = self._version
        return self._grid.path(start)

    def _search(self, start: Cell) -> tuple[np.ndarray, int]:
        start = (int(start[0]), int(start[1]))
        if self._shape == (0, 0) or not in_bounds(self._shape, start):
            return _EMPTY, int(INF)
        key = (start, self._version)
        if self._cached is not None and self._cached[0] == key:
            return self._cached[1], self._cached[2]
        t0 = time.perf_counter()
        self.last_fell_back, self.last_length = False, float("inf")
        path, expanded, tests = _EMPTY, 0, 0
        if not (self._blocked[start] or self._blocked[self._goal]):
            if start == self._goal:
                path, self.last_length = np.array([start], dtype=np.int32), 0.0
            else:
                points, length, stats = self.polygon_path(start)
                expanded, tests = int(stats[vg.EXPANDED]), int(stats[vg.TESTS])
                if len(points):
                    path, self.last_length = rasterise(points), length
                elif self.fallback:
                    path = self._grid_path(start)
                    if len(path):
                        self.fallbacks += 1
                        self.last_fell_back = True
        cost = path_cost(path) if len(path) else int(INF)
        self.search_stats = UpdateStats(expanded, tests, (time.perf_counter() - t0) * 1e3)
        self._cached = (key, path, cost)
        return path, cost

    def path(self, start: Cell) -> np.ndarray:
        return self._search(start)[0].copy()

    def cost_at(self, cell: Cell) -> int:
        return self._search(cell)[1]

    def costs_within(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """The grid's exact cost-to-goal over a window (``AStarPlanner.costs_within``): what
        the escape from the inflation margin ranks its exits by (``escape.py``). A grid cost,
        not a polygon one: reading ``cost_at`` cell by cell would run a search per cell, and
        every exit the grid can use gets a path here too (the graph's or the fallback's)."""
        if self._shape == (0, 0):
            raise RuntimeError("call plan(blocked, goal) before costs_within")
        self._grid_path(self._goal)  # brings the grid planner up to this map
        return self._grid.costs_within(r0, r1, c0, c1)

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell
    ) -> tuple[UpdateStats, np.ndarray]:
        """``update`` then ``path``: ``iterations`` expanded, ``cells_touched`` judgements."""
        t0 = time.perf_counter()
        self.update(cells, blocked)
        path = self.path(start)
        stats = self.search_stats
        expanded, tests = (stats.iterations, stats.cells_touched) if stats else (0, 0)
        return UpdateStats(expanded, tests, (time.perf_counter() - t0) * 1e3), path
