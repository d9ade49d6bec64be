"""The state database: what it keeps, how often it writes, and what a broken file costs."""

from __future__ import annotations

import logging
import sqlite3
import time

import numpy as np
import pytest

from daemon.service.state_db import FILE_NAME, StateDB, StoredSession

SESSION = StoredSession(goal='{"target": {"kind": "cell", "row": 1, "col": 2}, "stamp": 1.0}',
                        state="guiding", paused=False)  # fmt: skip


def open_db(folder, **kw) -> tuple[StateDB, object]:
    opened = StateDB.open(folder, **kw)
    assert opened is not None
    return opened


@pytest.mark.timeout(30)
def test_sessions_maps_and_settings_come_back_after_a_restart(tmp_path):
    db, stored = open_db(tmp_path)
    assert not stored.sessions and not stored.maps
    occ = np.random.default_rng(1).integers(0, 3, (40, 60)).astype(np.uint8)
    db.put_session("ann", SESSION)
    db.put_map("ann", occ, 17, 2**64 - 1, 5.0)  # an epoch past SQLite's signed INTEGER
    db.put_settings("ann", '{"intensity": 30, "stamp": 1.0}')
    db.put_session("bob", StoredSession(None, "idle", True))
    db.put_map("bob", occ, 3, None, 5.0)
    db.forget("bob")  # bob went idle: session and map go, before they were ever written
    db.close()
    with sqlite3.connect(tmp_path / FILE_NAME) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    db, stored = open_db(tmp_path)
    assert stored.sessions == {"ann": SESSION}
    assert sorted(stored.maps) == ["ann"]
    m = stored.maps["ann"]
    assert (m.seq, m.epoch) == (17, 2**64 - 1)
    assert np.array_equal(m.snapshot.array(), occ)
    assert stored.settings == {"ann": '{"intensity": 30, "stamp": 1.0}'}
    db.close()


@pytest.mark.timeout(30)
def test_a_users_map_is_written_at_most_once_a_period_and_the_latest_wins(tmp_path):
    db, _ = open_db(tmp_path, map_period_s=0.5, commit_s=0.01)
    t0 = time.monotonic()
    occ = np.zeros((20, 20), np.uint8)
    puts = 0
    while time.monotonic() - t0 < 1.2:  # a delta every 10 ms for 1.2 s
        occ[puts % 20, puts // 20 % 20] = 1
        db.put_map("ann", occ.copy(), puts, 1, time.time())
        puts += 1
        time.sleep(0.01)
    writes_before_close = db.rows
    db.close()  # writes the latest, due or not
    assert puts > 50
    assert 1 <= writes_before_close <= 3, writes_before_close  # at 0, 0.5 and 1.0 s
    _, stored = open_db(tmp_path)
    assert stored.maps["ann"].seq == puts - 1
    assert np.array_equal(stored.maps["ann"].snapshot.array(), occ)


@pytest.mark.timeout(30)
@pytest.mark.parametrize(
    "make",
    [
        lambda p: p.write_bytes(b"not a database at all, just bytes " * 200),
        lambda p: sqlite3.connect(p).executescript("CREATE TABLE other (x); PRAGMA user_version=3"),
    ],
    ids=["garbage", "foreign"],
)
def test_a_corrupt_or_foreign_file_is_moved_aside_with_one_line(tmp_path, caplog, make):
    make(tmp_path / FILE_NAME)
    with caplog.at_level(logging.INFO, logger="guidebelt.state"):
        db, stored = open_db(tmp_path)
    lines = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert [r.getMessage() for r in lines] == [
        "state database unusable, moved aside; starting with no saved state"
    ]
    assert not stored.sessions
    aside = [p.name for p in tmp_path.iterdir() if ".bad-" in p.name]
    assert len(aside) == 1
    db.put_session("ann", SESSION)  # the fresh database works
    db.close()
    assert open_db(tmp_path)[1].sessions == {"ann": SESSION}


@pytest.mark.timeout(30)
def test_a_state_dir_that_cannot_be_made_turns_the_store_off(tmp_path, caplog):
    (tmp_path / "file").write_text("x")
    with caplog.at_level(logging.ERROR, logger="guidebelt.state"):
        assert StateDB.open(tmp_path / "file" / "state") is None
    assert "state not kept" in caplog.text


@pytest.mark.timeout(30)
def test_puts_are_coalesced_per_user_and_kind_and_never_wait(tmp_path):
    db, _ = open_db(tmp_path, commit_s=0.05)
    occ = np.zeros((400, 400), np.uint8)
    t0 = time.perf_counter()
    for i in range(2000):  # 200 users' sessions and maps, ten times over
        db.put_session(f"u{i % 200}", SESSION)
        db.put_map(f"u{i % 200}", occ, i, None, 1.0)
    per_put_us = (time.perf_counter() - t0) / 4000 * 1e6
    db.close()
    assert db.errors == 0 and db.dropped == 0
    # Coalesced: at most 400 rows (one per user and kind) reached the disk, not 4000.
    assert db.rows <= 400 + 400
    print(f"{per_put_us:.1f} µs a put")
