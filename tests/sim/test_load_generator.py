"""The load generator's sends: what a daemon receives from it is valid and on schedule, though
it no longer builds each pose and delta through the message models."""

from __future__ import annotations

import itertools
import threading
import time

import numpy as np
import pytest

from protocol import codec
from protocol.messages import MapDelta, Pose
from sim.load_generator import LoadGenerator, LoadSpec, _blob, _pose_template


def test_the_pose_bytes_are_a_valid_pose_with_each_stamp():
    head, tail = _pose_template(5.025, 1.025)
    for stamp in (1795745624.2573698, 1e9, 1795745624.0, time.time()):
        raw = b"".join((head, repr(stamp).encode(), tail))
        pose = codec.decode(Pose, raw)
        assert (pose.x, pose.y, pose.heading, pose.stamp) == (5.025, 1.025, 1.57, stamp)
        assert raw == codec.encode(Pose(x=5.025, y=1.025, heading=1.57, stamp=stamp))


def test_the_obstacle_is_the_same_cells_in_the_same_order_as_a_grid_of_rows_and_columns():
    for seed in range(20):
        a, b = np.random.default_rng([0, seed]), np.random.default_rng([0, seed])
        for n, size in ((200, 3), (60, 4)):
            cells = _blob(a, n, size)
            r = int(b.integers(n // 5, 4 * n // 5))
            c = int(b.integers(n // 2 - n // 10, n // 2 + n // 10))
            rr, cc = np.mgrid[r : r + size, c : c + size]
            np.testing.assert_array_equal(cells, (rr * n + cc).ravel())


@pytest.mark.timeout(30)
def test_every_user_sends_poses_and_deltas_at_their_rates_and_each_delta_decodes():
    import zenoh

    from daemon.service.embedded import free_port
    from protocol import session as wire
    from protocol import topics as T
    from protocol.settings import loopback

    port = free_port()
    listener = wire.open_session(loopback(listen_port=port))
    talker = wire.open_session(loopback(connect_port=port))
    heard: dict[tuple[str, str], list[tuple[float, bytes]]] = {}
    lock = threading.Lock()

    def keep(sample: zenoh.Sample) -> None:
        topic, user = str(sample.key_expr).split("/")[2], str(sample.key_expr).split("/")[1]
        with lock:
            heard.setdefault((topic, user), []).append(
                (time.monotonic(), sample.payload.to_bytes())
            )

    subs = [
        wire.declare_subscriber(listener, t, zenoh.handlers.Callback(keep))
        for t in (T.POSE, T.MAP_DELTA)
    ]
    gen = None
    try:
        spec = LoadSpec(users=3, grid=60, seconds=2.0, warmup_s=0.0, join_hz=30.0)
        gen = LoadGenerator(talker, spec)
        # The listener's subscriptions have reached the generator's publishers (waited for,
        # not a fixed 0.5 s): delta 0 is put once, first, and a put before would be lost.
        pubs = [*gen._pose_pubs.values(), *gen._delta_pubs.values()]
        deadline = time.monotonic() + 10.0
        while not all(p.matching_status.matching for p in pubs):
            assert time.monotonic() < deadline, "the sessions never met"
            time.sleep(0.02)
        gen.run()
    finally:
        if gen is not None:
            gen.close()
        for s in subs:
            s.undeclare()
        talker.close()
        listener.close()
    pose_leaf, delta_leaf = T.POSE.key("u").split("/")[2], T.MAP_DELTA.key("u").split("/")[2]
    for user in gen.names:
        poses = [codec.decode(Pose, raw) for _, raw in heard[(pose_leaf, user)]]
        deltas = [codec.decode(MapDelta, raw) for _, raw in heard[(delta_leaf, user)]]
        # ~2.1 s of sends (the ramp, then 2 s) at 20 and 10 Hz: 40-43 poses, 21-23 deltas with
        # the first; poses may be dropped (latest wins) on a loaded machine, deltas may not.
        assert 30 <= len(poses) <= 44 and 20 <= len(deltas) <= 23, (len(poses), len(deltas))
        assert all(b.stamp > a.stamp for a, b in itertools.pairwise(poses))
        assert [d.seq for d in deltas] == list(range(len(deltas)))
        # Delta 0 walls the map in; then each one drops a 3 × 3 obstacle or lifts it again.
        assert deltas[0].values == b"\x01" * len(deltas[0].values)
        for k, d in enumerate(deltas[1:], start=1):
            assert (d.height, d.width) == (60, 60) and len(d.values) == 9
            assert d.values == (b"\x01" if k % 2 else b"\x00") * 9
            if k % 2 == 0:
                assert d.cells == deltas[k - 1].cells  # the obstacle it lifts
        assert gen.traces[user].sends.keys() == {d.seq for d in deltas[1:]}
