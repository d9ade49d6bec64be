"""The RFID node over real zenoh sessions on loopback: mock reader (pty) → node → Pose."""

from __future__ import annotations

import asyncio
import contextlib
import math
import socket
import threading
import time

import numpy as np
import pytest

from drivers.rfid.mock_reader import MockReader
from drivers.rfid.node import RfidNode
from drivers.rfid.rssi import ReadModel
from drivers.rfid.tag_payload import ObstacleBook
from drivers.rfid.tags import generate
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Pose, RfidStats
from protocol.session import loopback, open_session
from sim.tag_payloads import tag_memories


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.timeout(30)
def test_node_publishes_poses_at_10_hz_or_more(tmp_path) -> None:
    occ = np.zeros((50, 50), dtype=np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1
    occ[10:20, 10:30] = 1
    tag_map = generate(occ, 0.1, lf_layout="floor", seed=5)
    truth = (2.53, 1.37)  # standing still, between floor tags' lattice lines
    model = ReadModel.for_tags(tag_map, seed=6)

    port = free_port()
    node_session = open_session(loopback(listen_port=port))
    client = open_session(loopback(connect_port=port))
    poses: list[tuple[float, Pose]] = []
    stats: list[RfidStats] = []
    lock = threading.Lock()

    def on_pose(sample) -> None:
        pose = Pose.model_validate_json(sample.payload.to_bytes())  # the daemon's own check
        with lock:
            poses.append((time.monotonic(), pose))

    def on_stats(sample) -> None:
        with lock:
            stats.append(codec.decode(RfidStats, sample.payload.to_bytes()))

    subs = [
        wire.declare_subscriber(client, T.POSE, on_pose, "alice"),
        wire.declare_subscriber(client, T.RFID_STATS, on_stats, "alice"),
    ]
    mock = MockReader(model, lambda t: truth, link=str(tmp_path / "ttyRFID")).start()
    node = RfidNode(node_session, "alice", tag_map, mock.path, rate_hz=20.0)

    async def main() -> None:
        task = asyncio.create_task(node.run())
        await asyncio.sleep(3.0)
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task

    try:
        asyncio.run(main())
    finally:
        mock.stop()
        node.close()
        for sub in subs:
            sub.undeclare()
        client.close()
        node_session.close()

    with lock:
        got = list(poses)
    assert len(got) >= 20
    # Rate over the last two seconds, once the reader was connected and the windows full.
    t_end = got[-1][0]
    recent = [p for t, p in got if t >= t_end - 2.0]
    assert len(recent) / 2.0 >= 10.0
    errors = [math.hypot(p.x - truth[0], p.y - truth[1]) for p in recent]
    assert float(np.median(errors)) <= 0.10  # a floor tag is in reach: the LF fix
    assert all(0.0 <= p.quality <= 1.0 for p in recent)
    assert stats and stats[-1].accepted > 0 and stats[-1].connected is True


@pytest.mark.timeout(30)
def test_node_with_the_filter_sends_its_uncertainty(tmp_path) -> None:
    occ = np.zeros((50, 50), dtype=np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1
    occ[10:20, 10:30] = 1
    tag_map = generate(occ, 0.1, lf_layout="floor", seed=5)
    truth = (2.53, 1.37)
    port = free_port()
    node_session = open_session(loopback(listen_port=port))
    client = open_session(loopback(connect_port=port))
    poses: list[Pose] = []
    lock = threading.Lock()

    def on_pose(sample) -> None:
        with lock:
            poses.append(Pose.model_validate_json(sample.payload.to_bytes()))

    sub = wire.declare_subscriber(client, T.POSE, on_pose, "carol")
    mock = MockReader(ReadModel.for_tags(tag_map, seed=6), lambda t: truth,
                      link=str(tmp_path / "ttyRFID")).start()  # fmt: skip
    node = RfidNode(node_session, "carol", tag_map, mock.path, method="filter", rate_hz=20.0)

    async def main() -> None:
        task = asyncio.create_task(node.run())
        await asyncio.sleep(2.0)
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task

    try:
        asyncio.run(main())
    finally:
        mock.stop()
        node.close()
        sub.undeclare()
        client.close()
        node_session.close()
    with lock:
        got = list(poses)
    assert len(got) >= 20
    assert all(p.sigma_m is not None for p in got)
    last = got[-1]
    assert math.dist((last.x, last.y), truth) < 0.3
    assert 0 < last.sigma_m < 0.5 and last.quality > 0.3


@pytest.mark.timeout(30)
def test_node_reads_the_obstacles_its_tags_carry_into_its_book(tmp_path) -> None:
    occ = np.zeros((50, 50), dtype=np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1
    occ[10:20, 10:30] = 1
    tag_map = generate(occ, 0.1, lf_layout="none", seed=5)
    model = ReadModel.for_tags(tag_map, seed=6)
    memories = tag_memories(tag_map, occ, 0.1)
    session = open_session(loopback(listen_port=free_port()))
    book = ObstacleBook(occ.shape, 0.1)
    try:
        with MockReader(model, lambda t: (1.0, 3.0), link=str(tmp_path / "ttyRFID"),
                        memories=memories) as mock:  # fmt: skip
            node = RfidNode(session, "alice", tag_map, mock.path, method="filter", book=book)

            async def main() -> None:
                task = asyncio.create_task(node.run())
                async with asyncio.timeout(10):
                    while not book._pending:
                        await asyncio.sleep(0.05)
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task

            asyncio.run(main())
            node.close()
    finally:
        session.close()
    delta = book.delta(0, 0.0)
    assert delta is not None and len(book.polygons) >= 1 and not book.rejected
    assert np.all(occ.reshape(-1)[np.frombuffer(delta.cells, "<u4")] == 1)
