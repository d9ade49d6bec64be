"""The MCAP file's bounds: rotation past a size, drops counted when the writer falls behind."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from protocol import topics as T
from protocol.messages import Pose


def test_rotation_keeps_every_file_readable_and_every_message(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    from recording.log import McapLog

    log = McapLog(tmp_path / "walk.mcap", max_bytes=64 * 1024)
    n = 6000
    for i in range(n):
        log.write(
            T.POSE.key("ann"), Pose(x=i * 0.01, y=1.0, heading=0.5, stamp=1e9 + i), 1e9 + i
        )
    log.close()
    files = log.counts.files
    assert len(files) >= 3 and files[1].name == "walk.001.mcap"
    sequences = []
    for path in files:
        assert path.stat().st_size < 64 * 1024 + 16 * 1024  # past the bound by a chunk at most
        with path.open("rb") as f:
            sequences += [m.sequence for _s, _c, m in make_reader(f).iter_messages()]
    assert sequences == list(range(n))  # none lost, none twice, numbered across the files


@pytest.mark.timeout(30)
def test_a_writer_that_falls_behind_drops_and_counts(tmp_path: Path) -> None:
    from daemon.service.embedded import free_port
    from protocol import session as wire
    from protocol import topics as T
    from protocol.session import loopback, open_session
    from recording.recorder import Recorder

    port = free_port()
    rec_session = open_session(loopback(listen_port=port))
    pub_session = open_session(loopback(connect_port=port))
    gate = threading.Event()
    try:
        rec = Recorder(rec_session, tmp_path / "w.mcap", "ann", queue_max=5)
        write = rec.log.write
        rec.log.write = lambda *a: (gate.wait(10), write(*a))  # a disk that stalls
        with rec:
            pub = wire.declare_publisher(pub_session, T.STATUS, "ann")
            # The recorder's subscription has reached the publisher (waited for, not a fixed
            # 0.3 s): a put before it would be lost, and all 40 must be heard.
            end = time.monotonic() + 10
            while not pub.matching_status.matching:
                assert time.monotonic() < end, "the recorder's subscription never arrived"
                time.sleep(0.02)
            status = b'{"state": "guiding", "stamp": 1.0}'
            for _ in range(40):
                pub.put(status)
            end = time.monotonic() + 5
            while rec.counts.heard < 40 and time.monotonic() < end:
                time.sleep(0.02)
            gate.set()
            pub.undeclare()
        counts = rec.counts
    finally:
        pub_session.close()
        rec_session.close()
    assert counts.heard == 40
    assert counts.dropped > 0 and counts.written + counts.dropped == counts.heard
    assert counts.invalid == 0


@pytest.mark.timeout(60)
def test_the_daemon_records_what_it_hears_and_sends(daemon, tmp_path: Path) -> None:
    """``guidebelt run --record``: a recorder on the daemon's own session hears the world's
    inputs (no router needed) and the daemon's outputs, up to its users' last STOP."""
    from daemon.service.embedded import DaemonThread
    from recording.recorder import Recorder
    from recording.replay import read
    from sim.live import LiveWalks

    out = tmp_path / "run.mcap"
    recorders: list[Recorder] = []

    def observe(session):
        recorders.append(Recorder(session, out).start())
        return recorders[-1]

    config = daemon.config.model_dump(exclude={"zenoh"})
    with DaemonThread(observers=[observe], **config) as d:
        walks = LiveWalks(d.port, ["ann"], pace_s=0.0).start()
        assert walks.join(60)
    counts = recorders[0].counts
    assert counts.dropped == 0 and counts.invalid == 0 and counts.written == counts.heard
    topics = [T.topic_of(r.key) for r in read(out)]
    assert {T.MAP_DELTA, T.POSE, T.GOAL, T.PATH, T.BELT, T.STATUS} <= set(topics)
    assert topics[-1] in (T.BELT, T.STATUS)  # the daemon's last words, after its stop
