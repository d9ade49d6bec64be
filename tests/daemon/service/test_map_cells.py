"""The memory budget's count of every user's map, kept as navigators take maps rather than
summed over the runners at each delta: the same answers as the sum, through new maps,
snapshots, restores and forgotten sessions."""

from __future__ import annotations

import time

import numpy as np
import pytest

from daemon.navigation import Navigator
from daemon.service.config import DaemonConfig
from daemon.service.daemon import Daemon
from daemon.service.map_cells import MapCells
from daemon.service.memory_budget import BYTES_PER_CELL
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import MapDelta, MapSnapshot


def first_delta(h: int, w: int) -> MapDelta:
    return MapDelta.from_arrays(0, (h, w), np.array([0]), np.array([1]), time.time())


def test_the_budget_counts_the_other_users_maps_as_their_navigators_take_them():
    config = DaemonConfig(backend="cpu", memory_budget_mb=100 * BYTES_PER_CELL / 2**20 * 1.5)
    d = Daemon(config)
    assert d._map_too_big("a", 100) is None  # 100 cells fit, 1.5× that is the budget
    b = Navigator("b", config.navigator_settings(), map_cells=d.map_cells.open("b"))
    b.maps.take_deltas([first_delta(6, 10)])
    assert "memory_budget_mb" in (d._map_too_big("a", 100) or "")  # 60 + 100 > 150
    assert d._map_too_big("b", 100) is None  # b's own map is the one replaced
    b.maps.take_snapshot(MapSnapshot.from_array(4, np.zeros((5, 5), np.uint8), time.time()), "b")
    assert d._map_too_big("a", 100) is None and d.map_cells.total() == 25
    b.maps.restore(np.zeros((9, 9), np.uint8), 7, None)
    assert "memory_budget_mb" in (d._map_too_big("a", 100) or "")  # 81 + 100
    d.map_cells.close("b")
    assert d._map_too_big("a", 140) is None and d.map_cells.total() == 0


def test_a_forgotten_sessions_late_map_is_cleared_and_the_next_session_counts_alone():
    cells = MapCells()
    old = cells.open("u")
    old(400)
    cleared = cells.close("u")
    assert cells.total() == 0
    new = cells.open("u")
    old(900)  # the forgotten session's last step took a map after it was closed
    new(100)
    assert cells.total() == 1000 and cells.others("u") == 900
    cleared()  # that step is over
    assert cells.total() == 100 and cells.others("u") == 0 and cells.others("v") == 100


@pytest.mark.timeout(30)
def test_a_running_daemons_count_is_the_sum_of_its_users_maps(daemon, peer):
    sizes = {"cells-a": (30, 40), "cells-b": (20, 25)}
    for user, (h, w) in sizes.items():
        wire.put(peer, T.MAP_DELTA, user, codec.encode(first_delta(h, w)))

    def counted() -> tuple[int, int]:
        maps = [r.navigator.maps.map for r in daemon.daemon.runners.values()]
        return daemon.daemon.map_cells.total(), sum(m.occupancy.size for m in maps if m)

    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        runners = daemon.call(lambda: dict(daemon.daemon.runners)) or {}
        if all(u in runners and runners[u].navigator.maps.map is not None for u in sizes):
            break
        time.sleep(0.05)
    total, summed = daemon.call(counted) or (-1, -2)
    assert total == summed and summed >= 30 * 40 + 20 * 25
