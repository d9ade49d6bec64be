"""The serial driver on real pseudo-terminals: reads, bad lines, unplug and replug, the mock."""

from __future__ import annotations

import asyncio
import contextlib
import math
import threading

import numpy as np
import pytest

from drivers.rfid.localiser import Localiser
from drivers.rfid.mock_reader import MockReader
from drivers.rfid.protocol import (
    MAX_LINE_BYTES,
    BadLine,
    Memory,
    ReadFilter,
    checksum,
    format_memory,
    format_read,
    parse_line,
)
from drivers.rfid.reader import RfidReader
from drivers.rfid.rssi import ReadModel
from drivers.rfid.tag_payload import ObstacleBook
from drivers.rfid.tags import generate
from sim.tag_payloads import tag_memories

EPC = "E2801160600002080A7C8F31"


async def wait_for(cond, timeout: float = 5.0) -> None:
    async with asyncio.timeout(timeout):
        while not cond():
            await asyncio.sleep(0.01)


def silent_mock(tmp_path) -> MockReader:
    """A pty with no walking user: the test writes every line itself."""
    model = ReadModel([], np.empty((0, 2)), [], np.empty((0, 2)))
    mock = MockReader(model, lambda t: None, link=str(tmp_path / "ttyRFID"))
    mock.plug()
    return mock


@contextlib.asynccontextmanager
async def running(reader: RfidReader):
    task = asyncio.create_task(reader.run())
    try:
        yield task
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


@pytest.mark.timeout(20)
def test_reads_arrive_and_bad_lines_are_counted(tmp_path) -> None:
    mock = silent_mock(tmp_path)
    got = []

    async def main() -> None:
        reader = RfidReader(mock.path, {EPC}, got.append)
        async with running(reader):
            await wait_for(reader.connected.is_set)
            await asyncio.sleep(0.05)
            mock.write(format_read(EPC, -50.0, 1))
            await wait_for(lambda: len(got) == 1)
            body = f"TAG,{EPC},-52.0,3"
            mock.write(b"\x00\x01garbage\n")
            mock.write(b"TAG," + EPC.encode() + b",-50.0,2*00\n")  # bad checksum
            mock.write(f"TAG,{EPC},9.0,2*{checksum(f'TAG,{EPC},9.0,2')}\n".encode())
            mock.write(format_read("ABCDEF0123", -50.0, 2))  # not in the tag map
            mock.write(b"TAG," + b"7" * 300)  # a runaway line with no end…
            mock.write(b"\n" + f"{body}*{checksum(body)}\n".encode()[:10])  # …then a split one
            mock.write(f"{body}*{checksum(body)}\n".encode()[10:])
            await wait_for(lambda: len(got) == 2)
            stats = reader.stats()
            assert stats["garbage"] == 2  # the binary line and the runaway one
            assert stats["checksum"] == 1
            assert stats["impossible_rssi"] == 1
            assert stats["unknown_tag"] == 1
            assert stats["accepted"] == 2

    try:
        asyncio.run(main())
    finally:
        mock.unplug()
    assert [r.rssi for r in got] == [-50.0, -52.0]


@pytest.mark.timeout(20)
def test_unplugged_and_back_reconnects(tmp_path) -> None:
    mock = silent_mock(tmp_path)
    got = []

    async def main() -> None:
        reader = RfidReader(mock.path, {EPC}, got.append, backoff_min_s=0.02, backoff_max_s=0.2)
        async with running(reader):
            await wait_for(reader.connected.is_set)
            await asyncio.sleep(0.05)
            mock.write(format_read(EPC, -50.0, 1))
            await wait_for(lambda: len(got) == 1)

            mock.unplug()  # the pty closes: the driver's read fails
            await wait_for(lambda: not reader.connected.is_set())
            assert reader.disconnects == 1
            await asyncio.sleep(0.5)  # several failed reopen attempts while it is gone
            assert not reader.connected.is_set()

            mock.plug()  # a new pty behind the same link
            await wait_for(reader.connected.is_set)
            assert reader.connects == 2
            await asyncio.sleep(0.05)
            mock.write(format_read(EPC, -55.0, 2))
            await wait_for(lambda: len(got) == 2)

    try:
        asyncio.run(main())
    finally:
        mock.unplug()
    assert [r.rssi for r in got] == [-50.0, -55.0]


@pytest.mark.timeout(30)
def test_mock_reader_end_to_end(tmp_path) -> None:
    """The mock reports a walking user's tags over a pty; the localiser follows the user."""
    occ = np.zeros((60, 60), dtype=np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1
    occ[20:30, 10:25] = 1
    tag_map = generate(occ, 0.1, lf_layout="none", seed=1)
    t0 = [None]
    lock = threading.Lock()

    def position(t: float) -> tuple[float, float]:
        with lock:
            if t0[0] is None:
                t0[0] = t
            s = t - t0[0]
        return (1.0 + 0.5 * s, 1.5)  # east along y = 1.5 m at 0.5 m/s

    model = ReadModel.for_tags(tag_map, seed=2)
    loc = Localiser(tag_map)
    errors = []

    async def main(mock: MockReader) -> None:
        reader = RfidReader(mock.path, tag_map.ids, loc.add)
        async with running(reader):
            await wait_for(reader.connected.is_set)
            await asyncio.sleep(0.8)  # the median windows fill
            loop = asyncio.get_running_loop()
            headings = []
            for _ in range(20):
                await asyncio.sleep(0.1)
                now = reader.clock()
                est = loc.estimate(now)
                assert est is not None
                x, y = position(now)
                errors.append(math.hypot(est.x - x, est.y - y))
                headings.append(est.heading)
            assert loop.is_running()
            stats = reader.stats()
            assert stats["accepted"] > 100
            assert stats["garbage"] == stats["checksum"] == stats["unknown_tag"] == 0
            # Walking east: the heading from successive positions says so, roughly.
            assert abs(float(np.median(headings[-10:]))) < 0.8

    with MockReader(model, position, link=str(tmp_path / "ttyRFID")) as mock:
        asyncio.run(main(mock))
    assert mock.lines > 100
    assert float(np.median(errors)) < 0.6


@pytest.mark.timeout(30)
def test_the_reader_reads_the_obstacles_the_tags_carry(tmp_path) -> None:
    """The mock reader gets the tags' memory from the world and sends each tag's once per
    connection, after its first read; the driver hands it to the book, not the localiser."""
    occ = np.zeros((60, 60), dtype=np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1
    occ[20:30, 10:25] = 1
    tag_map = generate(occ, 0.1, lf_layout="none", seed=1)
    memories = tag_memories(tag_map, occ, 0.1)
    assert memories
    model = ReadModel.for_tags(tag_map, seed=2)
    book = ObstacleBook(occ.shape, 0.1)
    seen: list[str] = []
    loc = Localiser(tag_map)

    def on_memory(m) -> None:
        seen.append(m.tag_id)
        book.read(m.data)

    async def main(mock: MockReader) -> None:
        reader = RfidReader(mock.path, tag_map.ids, loc.add, on_memory=on_memory)
        async with running(reader):
            await wait_for(lambda: len(book._pending) >= 1)
            await asyncio.sleep(0.5)
            assert reader.filter.memories == len(seen)
            assert reader.stats()["garbage"] == reader.stats()["checksum"] == 0

    # Standing by the block's north-west corner (x 1.0, y 3.0 m): its tags answer.
    with MockReader(model, lambda t: (1.0, 3.05), link=str(tmp_path / "ttyRFID"),
                    memories=memories) as mock:  # fmt: skip
        asyncio.run(main(mock))
    assert len(seen) == len(set(seen))  # each tag's memory once
    delta = book.delta(0, 0.0)
    assert delta is not None
    cells = np.frombuffer(delta.cells, "<u4")
    assert np.all(occ.reshape(-1)[cells] == 1)


def test_memory_lines_parse_and_bad_ones_are_rejected() -> None:
    data = bytes(range(32))
    line = format_memory(EPC, data)
    got = parse_line(line, 2.0)
    assert isinstance(got, Memory) and got.data == data and got.tag_id == EPC
    assert len(line) <= MAX_LINE_BYTES + 1
    with pytest.raises(BadLine) as err:
        parse_line(line.replace(b"*", b"0*", 1), 0.0)  # odd number of hex digits
    assert err.value.reason == "garbage"
    with pytest.raises(BadLine) as err:
        parse_line(format_memory(EPC, bytes(33)), 0.0)  # more than a tag's 32 bytes
    assert err.value.reason == "garbage"
    with pytest.raises(BadLine) as err:
        parse_line(line[:-3] + (b"01" if line[-3:-1] == b"00" else b"00") + b"\n", 0.0)
    assert err.value.reason == "checksum"
    filt = ReadFilter({EPC})
    assert filt.feed(format_memory("ABCD", data), 0.0) is None  # not in the tag map
    assert isinstance(filt.feed(line, 0.0), Memory)
    assert filt.memories == 1 and filt.accepted == 0 and filt.rejected["unknown_tag"] == 1
