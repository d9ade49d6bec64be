"""Size caps before decoding: a payload too long for its kind, and a map larger than a user may
have or than the memory budget allows, are refused before anything is allocated for them."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.belt.recorder import Recorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import MapDelta, NavStatus, Pose, StatusCode

pytestmark = pytest.mark.timeout(60)


def delta_header(height: int, width: int, count: int = 0) -> bytes:
    """A delta's 32-byte header (``codec.HEADER``) and no cells: what a hostile peer sends."""
    return codec.HEADER.pack(codec.DELTA_MAGIC, codec.VERSION, 0, 0, height, width, 0.0, count)


def test_a_payload_longer_than_its_kind_can_be_is_refused_before_parsing():
    with pytest.raises(codec.DecodeError) as err:
        codec.decode(Pose, b"{" + b" " * codec.MAX_JSON_BYTES + b"}")
    assert err.value.code == StatusCode.OVERSIZED
    with pytest.raises(codec.DecodeError) as err:
        codec.decode(MapDelta, delta_header(10, 10) + b"\0" * (5 * 70_000))
    assert err.value.code == StatusCode.OVERSIZED


def test_the_header_says_the_map_size_without_decoding():
    assert codec.map_cells(delta_header(4096, 4096)) == 4096 * 4096
    assert codec.map_cells(b"GBMD") is None and codec.map_cells(b"{}" * 40) is None
    ok = MapDelta.from_arrays(3, (20, 30), np.array([5]), np.array([1]), time.time())
    assert codec.map_cells(codec.encode(ok)) == 600


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def test_a_33_byte_delta_declaring_a_huge_map_is_refused_and_allocates_nothing(daemon, peer):
    status: Recorder[NavStatus] = Recorder(peer, T.STATUS, "hostile")
    time.sleep(0.2)
    before = rss_mb()
    payload = delta_header(4096, 4096) + b"\0"  # 33 bytes: a 4096² map, "one" trailing byte
    assert len(payload) == 33
    for _ in range(20):
        wire.put(peer, T.MAP_DELTA, "hostile", payload)
        # The same header alone is a well-formed delta of no cells: decoded, it would make the
        # user a 4096² map. The cap refuses it first.
        wire.put(peer, T.MAP_DELTA, "hostile", payload[:32])
    refused = status.wait_for(lambda r: r.msg.code == StatusCode.OVERSIZED, 5.0)
    assert refused is not None and "max_map_cells" in refused.msg.reason
    # A 4096² map with its inflation and planner would take hundreds of MB: none was taken.
    assert rss_mb() - before < 20
    runner = daemon.call(lambda: daemon.daemon.runners.get("hostile"))
    assert runner is not None and runner.navigator.maps.map is None
    status.close()


def test_the_memory_budget_counts_every_users_map():
    from daemon.service.config import DaemonConfig
    from daemon.service.daemon import Daemon
    from daemon.service.memory_budget import BYTES_PER_CELL

    d = Daemon(DaemonConfig(memory_budget_mb=100 * BYTES_PER_CELL / 2**20 * 1.5))
    assert d._map_too_big("a", 100) is None  # 100 cells fit, 1.5× that is the budget
    assert "max_map_cells" in (d._map_too_big("a", DaemonConfig().max_map_cells + 1) or "")
    assert "memory_budget_mb" in (d._map_too_big("a", 200) or "")
    assert d._map_too_big("a", None) is None  # no header: the decoder refuses it
