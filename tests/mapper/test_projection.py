"""Points land in the right cells: a box of known size and distance, a tilted camera."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from mapper.frame import FrameRejected
from mapper.occupancy_mapper import FREE, OCCUPIED, UNKNOWN, OccupancyMapper

from .scenes import NORTH, box_scene, frame, mapper


def test_box_of_known_size_lands_in_its_cells():
    m = mapper()
    m.process(frame(box_scene(), 1.0))
    occ = m.occupancy
    # The camera sees the box's near face (row 38) across its width, and its top: every
    # cell it marks is one of the box's, and the near face is whole.
    marked = np.argwhere(occ == OCCUPIED)
    assert len(marked) > 0
    assert marked[:, 0].min() >= 33 and marked[:, 0].max() <= 38
    assert marked[:, 1].min() >= 28 and marked[:, 1].max() <= 33
    assert (occ[38, 28:34] == OCCUPIED).all()
    # Between the camera and the face the floor was seen through: free, not unknown.
    assert (occ[40:47, 29:33] == FREE).all()
    # Behind the box, hidden, stays unknown.
    assert (occ[25:30, 30:32] == UNKNOWN).all()


def test_noisy_frames_keep_the_box_in_place():
    m = mapper()
    for i in range(5):
        m.process(frame(box_scene(), 1.0 + i, rng=i))
    marked = np.argwhere(m.occupancy == OCCUPIED)
    assert (m.occupancy[38, 28:34] == OCCUPIED).all()
    # Range noise may smear an edge by one cell (2 cm of noise at 1.8 m), never further.
    assert marked[:, 0].max() <= 39 and marked[:, 0].min() >= 32
    assert marked[:, 1].max() <= 34 and marked[:, 1].min() >= 27


def test_tilted_camera_still_finds_the_floor():
    """The chest camera slipped: really pitched 42°, the mounting says 30°. Without the
    floor fit the floor ahead rises above the height threshold and fills the map with
    obstacles; with RANSAC the floor is found, the box is where it is, and nothing else."""
    tilted = frame(box_scene(), 1.0, pitch=42.0, reported_pitch=30.0)
    naive = mapper(floor_ransac=False)
    naive.process(tilted)
    assert (naive.occupancy == OCCUPIED).sum() > 20  # the floor itself taken for obstacles
    m = mapper()
    result = m.process(tilted)
    assert result.floor.fitted and 8.0 < result.floor.tilt_deg < 16.0
    marked = np.argwhere(m.occupancy == OCCUPIED)
    assert marked[:, 0].min() >= 33 and marked[:, 0].max() <= 39
    assert marked[:, 1].min() >= 27 and marked[:, 1].max() <= 34
    assert (m.occupancy[38, 29:33] == OCCUPIED).all()


def test_a_kept_floor_fit_follows_the_camera_as_it_turns():
    """Refitting every 4th frame (the GPU path's budget): the slipped camera's tilt, kept in
    the camera's frame, still levels the floor while the user turns between fits; a refit
    comes only when due, and a kept fit leaves the map as a fresh fit every frame would."""
    headings = [NORTH + a for a in (0.0, 0.25, -0.25, 0.15)]
    frames = [frame(box_scene(), 1.0 + i, heading=h, pitch=42.0, reported_pitch=30.0)
              for i, h in enumerate(headings)]  # fmt: skip
    every, kept = mapper(floor_every=1), mapper(floor_every=4)
    fits = []
    for f in frames:
        every.process(f)
        fits.append(kept.process(f).floor)
    assert all(f is fits[0] for f in fits) and fits[0].fitted  # one fit, carried along
    assert (kept.occupancy == OCCUPIED).sum() < 60
    marked = np.argwhere(kept.occupancy == OCCUPIED)
    assert marked[:, 0].min() >= 32 and marked[:, 0].max() <= 39
    assert np.abs(kept.occupancy.astype(int) - every.occupancy).sum() <= 3 * 2


def test_table_a_cane_would_miss_is_an_obstacle():
    """A table top at 0.70-0.76 m with nothing below: the camera sees it, so it is mapped."""
    from sim.scene3d import TABLE, empty_scene

    scene = empty_scene((60, 60), 0.1)
    scene.put((slice(36, 39), slice(28, 34)), TABLE, 0.70, 0.76)
    m = mapper()
    m.process(frame(scene, 1.0))
    assert (m.occupancy[36:39, 28:34] == OCCUPIED).sum() >= 12


def test_proximity_reports_the_box_ahead():
    m = mapper()
    r = m.process(frame(box_scene(), 1.0))
    # The face (row 38's south edge, y = 2.1 m) is 1.05 m straight ahead of the camera.
    assert r.proximity.ahead_m is not None and 0.95 <= r.proximity.ahead_m <= 1.1
    assert abs(r.proximity.bearing) < 0.3


def _tilted_walk() -> list:
    headings = [NORTH + a for a in (0.0, 0.25, -0.25, 0.15, 0.1, -0.1)]
    return [frame(box_scene(), 1.0 + i, heading=h, pitch=42.0, reported_pitch=30.0)
            for i, h in enumerate(headings)]  # fmt: skip


def test_a_floor_fit_off_the_frame_path_is_taken_by_the_next_frame():
    """``floor_async``: the first fit is made on the frame's path; a refit due later runs on
    the worker thread once the frame is out, and the next frame takes it. With each fit
    done before the next frame (a camera's 30 fps), the map is the one that fits on the
    frame's path make, cell for cell."""
    import threading

    inline, off = mapper(floor_every=2, floor_async=False), mapper(floor_every=2)
    started, fits = [], []
    for f in _tilted_walk():
        inline.process(f)
        fits.append(off.process(f).floor)
        started.append(off.fit_pending_floor())
        off.wait_for_floor()
    # Frame 0 fits on its path (nothing to keep yet); frames 2 and 4 leave a fit due, run off
    # the path and taken by frames 3 and 5.
    assert started == [False, False, True, False, True, False]
    assert fits[0] is fits[1] is fits[2] and fits[3] is not fits[2] and fits[0].fitted
    assert np.array_equal(off.occupancy, inline.occupancy)
    assert any(t.name.startswith("floor-fit") for t in threading.enumerate())
    off.close()
    assert not any(t.name.startswith("floor-fit") for t in threading.enumerate())


def _slowed(m: OccupancyMapper, s: float) -> OccupancyMapper:
    """``m`` with every floor fit ``s`` late (the worker thread descheduled, a loaded host)."""
    fit = m._fit

    def late(sample):
        time.sleep(s)
        return fit(sample)

    m._fit = late  # type: ignore[method-assign]
    return m


def test_the_map_does_not_depend_on_when_the_fit_thread_finishes():
    """Which frame takes a fit made off the path is fixed by the frames, not by the thread:
    a worker slowed far past the next frame, one as fast as it goes, and nobody starting the
    worker at all give the same floor to every frame and the same map, a refused frame
    between a due fit and its taker included (it takes nothing: the next merged frame does)."""
    frames = _tilted_walk()
    frames.insert(3, dataclasses.replace(frames[2], stamp=frames[1].stamp))  # stale: refused
    fast, slow, never = (mapper(floor_every=2, floor_async=True) for _ in range(3))
    _slowed(slow, 0.3)  # a frame here takes ~40 ms
    used: dict[str, list] = {"fast": [], "slow": [], "never": []}
    for f in frames:
        for name, m in (("fast", fast), ("slow", slow), ("never", never)):
            try:
                fit = m.process(f).floor
                used[name].append((fit.floor_z, fit.rotation.tobytes()))
            except FrameRejected:
                used[name].append("refused")
            if m is not never and m.fit_pending_floor():  # not waited for
                assert m is fast or not m._floor_job.done()  # type: ignore[union-attr]
    assert used["fast"] == used["slow"] == used["never"]
    assert used["fast"][3] == "refused"
    # The fits taken off the path (frames 4 and 6) differ from the ones before them: a frame
    # that kept the old fit would show.
    assert len({u for u in used["fast"] if u != "refused"}) == 3
    for m in (slow, never):
        assert np.array_equal(m.occupancy, fast.occupancy)
        assert np.array_equal(m.logodds, fast.logodds)
    for m in (fast, slow, never):
        m.close()
