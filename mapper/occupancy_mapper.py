"""The mapper proper: one frame in, the changed cells of the global map and proximity out.

``OccupancyMapper.process`` checks the frame (``frame.check_frame``; where the pass counts
the frame's pixels itself, on cuda, the depth and motion rules are checked once it is back,
in the same order, before anything is kept), fits the floor
(``floor.fit_floor``), runs the per-pixel pass on the chosen backend (``backends``), clears
along the rays, and fuses the frame into the global map by per-cell log-odds (the
occupancy-grid update of Thrun, Burgard & Fox, *Probabilistic Robotics*, 2005, ch. 9:
l_t = l_{t-1} + log-odds of the inverse sensor model − l_0, with l_0 = 0): a cell with at
least ``min_points`` obstacle points in this frame is a hit, unless they are the range-noise
tail of the face beyond it (``evidence.range_tail``); a cell some ray passed before its hit,
or whose floor the frame sees with nothing standing in it, or such a tail over a seen floor,
is a pass. Hits add ``l_hit``, passes add ``l_pass``
(negative), clamped. A cell is published OCCUPIED at or above ``l_occupied``, FREE at or
below ``l_free``, and keeps what it had between them, so a single noisy frame cannot close
a passage the camera has seen through. Only the cells that changed come out, ready for a
``MapDelta``. Everything is computed before the map is touched, so a frame refused at any
point leaves the map exactly as it was. Proximity (STOP) reads this frame's hits alone,
tails included: it never waits for evidence to build up.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .backends import make_binner
from .binning import Window
from .camera_model import Intrinsics
from .floor import NOMINAL, FloorFit, fit_floor, points_of
from .frame import (
    UINT16,
    DepthFrame,
    FrameRejected,
    Refusal,
    check_depth,
    check_frame,
    check_header,
    check_motion,
)
from .merge import merge_frame, merge_params
from .proximity import Proximity, proximity_of
from .settings import MapperSettings

FREE, OCCUPIED, UNKNOWN = 0, 1, 2
"""As ``protocol.messages.OCCUPANCY_VALUES`` and ``daemon.planning.grid``."""

JUMPS_TO_RELOCALISE = 5
"""Consecutive pose jumps after which the new place is believed (the localiser re-fixed)."""


@dataclass(frozen=True)
class Sample:
    """What a floor fit needs of a frame: every ``floor_sample_step``-th pixel's depth
    (a copy: the frame may be reused) and the camera's pose."""

    sub: np.ndarray
    scale: float
    intr: Intrinsics
    rot: np.ndarray
    cam: np.ndarray


@dataclass
class FrameResult:
    cells: np.ndarray
    """Flat indices (``row * width + col``) of the cells this frame changed."""
    values: np.ndarray
    """Their new occupancy."""
    proximity: Proximity
    floor: FloorFit
    valid: int
    ms: dict[str, float]


class OccupancyMapper:
    """One user's global map, built frame by frame."""

    def __init__(self, settings: MapperSettings | None = None,
                 initial: np.ndarray | None = None) -> None:  # fmt: skip
        self.settings = s = settings or MapperSettings()
        if initial is not None:
            if initial.shape != s.shape:
                raise ValueError(f"initial map {initial.shape} is not {s.shape}")
            self.occupancy = np.ascontiguousarray(initial, dtype=np.uint8).copy()
        else:
            self.occupancy = np.full(s.shape, UNKNOWN, np.uint8)
        self._fixed = self.occupancy == OCCUPIED
        self._logodds = np.zeros(s.shape, np.float32)
        self._logodds[self.occupancy == OCCUPIED] = s.l_occupied
        self._logodds[self.occupancy == FREE] = s.l_free
        self._seen_at = np.zeros(s.shape, np.float64)
        self._on_device = False
        """The binner merged the last frame on the device: log-odds and seen-at are there."""
        self._forgot_at = 0.0
        self.binner = make_binner(s.backend)
        self.refused: Counter[str] = Counter()
        self.frames = 0
        self.last_stamp: float | None = None
        self.last_xy: tuple[float, float] | None = None
        self._jumps = 0
        self._floor: tuple[FloorFit, np.ndarray, tuple] | None = None
        """The last fit, its correction in the camera's frame, and where the camera was."""
        self._floor_age = 0
        self._floor_due: tuple | None = None
        """The sample of a fit due, waiting for ``fit_pending_floor`` (``floor_async``)."""
        self._floor_job: Future | None = None
        self._fitter: ThreadPoolExecutor | None = None
        reach = math.ceil(s.max_range_m / s.cell_m) + 2
        self._side = 2 * reach + 1
        self._reach = reach

    @property
    def backend(self) -> str:
        return self.binner.name

    @property
    def logodds(self) -> np.ndarray:
        """Each cell's fused evidence; the start map's cells start at their threshold."""
        self._pull()
        return self._logodds

    @property
    def seen_at(self) -> np.ndarray:
        """When each cell was last seen occupied or free."""
        self._pull()
        return self._seen_at

    def _pull(self) -> None:
        """Where the device merges (cuda), its log-odds and seen-at into the host's arrays:
        only when read, never on a frame's path. The occupancy is kept current every frame."""
        if self._on_device:
            self.binner.pull(self._logodds, self._seen_at)
            self._on_device = False

    def depth_buffer(self, height: int, width: int, dtype: type = np.uint16) -> np.ndarray:
        """An array for a frame's producer to write the next depth into: on cuda the
        page-locked buffer the frame's graph uploads from, so a frame whose depth is this
        very array is not copied on its path (614 kB at 640 × 480, the largest piece of a
        paced frame's host work). A producer that makes the depth (a decoder, a renderer:
        ``sim.camera.RgbdCamera.render``'s ``out``) writes it here; frames in someone else's
        memory (a camera SDK's) are copied once, here or by the pass. It holds one frame:
        write it only between ``process`` calls. Elsewhere (cpu, strided, float64) a plain
        array."""
        s, dt = self.settings, np.dtype(dtype)
        lent = None
        if self.binner.merges and s.stride == 1 and dt != np.float64:
            bins = (width + s.cols_per_bin - 1) // s.cols_per_bin
            lent = self.binner.depth_buffer(s.shape, self._side, bins, height, width, dt)
        return np.zeros((height, width), dt) if lent is None else lent

    def window(self, x: float, y: float) -> Window:
        h = self.settings.shape[0]
        row = h - 1 - math.floor(y / self.settings.cell_m)
        col = math.floor(x / self.settings.cell_m)
        return Window(row - self._reach, col - self._reach, self._side, h, self.settings.cell_m)

    def process(self, frame: DepthFrame) -> FrameResult:
        """Merge one frame; ``FrameRejected`` (counted, map untouched) if it is unusable."""
        try:
            return self._process(frame)
        except FrameRejected as exc:
            self.refused[exc.refusal] += 1
            if exc.refusal is Refusal.POSE_JUMP:
                self._jumps += 1
                if self._jumps >= JUMPS_TO_RELOCALISE:  # a fit due from the old place, too
                    self.last_xy, self._jumps, self._floor = None, 0, None
                    self._floor_due, self._floor_job = None, None
            raise

    def _process(self, frame: DepthFrame) -> FrameResult:
        s = self.settings
        t0 = time.perf_counter()
        late = self.binner.counts_valid  # the pass counts the pixels: check those after it
        if late:
            intr, pose = check_header(frame, self.last_stamp)
        else:
            intr, pose = check_frame(frame, s.limits, self.last_stamp, self.last_xy)
        depth = frame.depth
        scale = intr.depth_scale if depth.dtype == UINT16 else 1.0
        rot = pose.world_from_optical()
        cam = np.asarray(pose.position, np.float64)
        x, y = cam[:2].tolist()  # plain floats for the scalar work: numpy's scalars are slower
        t1 = time.perf_counter()
        fit, floor_rot, floor_z, refit, arrived = self._floor_for(depth, scale, intr, rot, cam,
                                                                  (x, y))  # fmt: skip
        t2 = time.perf_counter()
        win = self.window(x, y)
        args = (depth, scale, intr, floor_rot, cam, floor_z, win, s.min_height_m,
                s.max_height_m, s.max_range_m, s.cols_per_bin, s.stride)  # fmt: skip
        forget_before = -math.inf
        if s.forget_s > 0 and frame.stamp - self._forgot_at >= 1.0:  # the whole map, once a second
            forget_before = frame.stamp - s.forget_s
        if self.binner.merges:  # the pass merges too, into the device's map, and checks late
            cells, values, valid, near = self._merge_on_device(frame, pose, args, forget_before,
                                                               (x, y))  # fmt: skip
            t3 = t3b = time.perf_counter()
        else:
            binned = self.binner(*args)
            t3 = time.perf_counter()
            if late:  # check_frame's last two rules, in its order; nothing was kept yet
                assert binned.present is not None
                check_depth(binned.present, depth.size, s.limits)
                check_motion(pose, frame.stamp, s.limits, self.last_stamp, self.last_xy)
            t3b = time.perf_counter()
            cells, values, *near = merge_frame(
                binned.counts[0], binned.counts[1], binned.hit, binned.far, x, y,
                math.cos(pose.heading), math.sin(pose.heading), win.r0, win.c0, win.map_rows,
                win.cell_m, self.occupancy, self._logodds, self._seen_at, self._fixed,
                frame.stamp, forget_before, s.min_points, s.min_share, s.tail_share, s.l_hit,
                s.l_pass, s.l_occupied, s.l_free, s.l_min, s.l_max, s.corridor_m,
            )  # fmt: skip
            valid = binned.valid
        if forget_before > -math.inf:
            self._forgot_at = frame.stamp
        prox = proximity_of(*near, frame.stamp)
        t4 = time.perf_counter()
        self.last_stamp, self.last_xy, self._jumps = frame.stamp, (x, y), 0
        if arrived is not None:  # the fit the last frame left due, taken by this frame
            self._floor, self._floor_job, self._floor_due = arrived, None, None
        if isinstance(refit, Sample):
            self._floor_due, self._floor_age = refit, 0
        elif refit is not None:
            self._floor, self._floor_age = refit, 0
        self._floor_age += 1
        self.frames += 1
        ms = {
            "check": (t1 - t0 + t3b - t3) * 1e3, "floor": (t2 - t1) * 1e3,
            "bin": (t3 - t2) * 1e3, "merge": (t4 - t3b) * 1e3, "total": (t4 - t0) * 1e3,
        }  # fmt: skip
        return FrameResult(cells, values, prox, fit, valid, ms)

    def _merge_on_device(self, frame: DepthFrame, pose, args: tuple, forget_before: float,
                         xy: tuple[float, float]) -> tuple:  # fmt: skip
        """The frame binned and merged on the device (``cuda_merge``): its changed cells,
        values, valid pixels and (ahead, nearest, side, fwd). ``check_motion`` is worked out
        here before the launch, ``check_depth`` on the device from its own pixel count: the
        device writes the map only if both pass, and a refusal is raised here in
        ``check_frame``'s order."""
        s = self.settings
        jump: FrameRejected | None = None
        try:
            check_motion(pose, frame.stamp, s.limits, self.last_stamp, self.last_xy)
        except FrameRejected as exc:
            jump = exc
        win, (x, y) = args[6], xy
        inv = 1.0 / win.cell_m  # merge_frame's camera cell, in its operations' order
        cam_row = win.map_rows - 1 - y * inv + 0.5 - win.r0
        cam_col = x * inv - 0.5 - win.c0
        need = s.limits.min_valid_share * frame.depth.size
        heading = pose.heading
        params = merge_params(s, math.cos(heading), math.sin(heading), cam_row, cam_col,
                              frame.stamp, forget_before, need, jump is None)  # fmt: skip
        maps = (self.occupancy, self._logodds, self._seen_at, self._fixed)
        cells, values, valid, present, written, near = self.binner.merge(maps, params, *args)
        self._on_device = True
        if not written:
            check_depth(present, frame.depth.size, s.limits)
            assert jump is not None, "the device kept the map for a frame the host passed"
            raise jump
        self.occupancy.reshape(-1)[cells] = values
        return cells, values, valid, near

    def _floor_for(
        self,
        depth: np.ndarray,
        scale: float,
        intr: Intrinsics,
        rot: np.ndarray,
        cam: np.ndarray,
        xy: tuple[float, float],
    ) -> tuple[FloorFit, np.ndarray, float, tuple | Sample | None, tuple | None]:
        """The floor-corrected camera rotation and floor height for this frame: a new fit
        when one is due (``floor_every``, a step, a relocalisation), else the last one carried
        in the camera's frame. Returns the new fit to keep (or, ``floor_async``, the sample
        to fit once the frame is out), or None, and the fit the last merged frame left due
        (``_pending_fit``), or None: both applied by the caller only once the frame is merged
        (a refused frame changes nothing, also one refused after this, on cuda)."""
        s = self.settings
        if not s.floor_ransac:
            return NOMINAL, rot, 0.0, None, None
        arrived = self._pending_fit()
        last = arrived or self._floor
        due = (last is None or self._floor_age >= s.floor_every
               or math.dist(xy, last[2]) > s.floor_refit_m)  # fmt: skip
        sample = Sample(depth[:: s.floor_sample_step, :: s.floor_sample_step].copy(),
                        scale, intr, rot, cam.copy()) if due else None  # fmt: skip
        if sample is not None and (last is None or not s.floor_async):
            keep = self._fit(sample)
            return keep[0], keep[0].rotation @ rot, keep[0].floor_z, keep, arrived
        # The floor itself does not move: its height is kept as it was fitted.
        assert last is not None
        fit, in_cam, _ = last
        return fit, rot @ in_cam, fit.floor_z, sample, arrived

    def _fit(self, sample: Sample) -> tuple[FloorFit, np.ndarray, tuple]:
        """The fit of one frame's sample, to keep: the fit, the camera's own tilt and where
        the camera stood (x, y as plain floats, for each frame's distance check). World =
        fit.rotation @ rot = rot @ (rot^T fit.rotation rot): that last factor is the camera's
        own tilt, valid whichever way the camera turns next."""
        s, rot = self.settings, sample.rot
        pts = points_of(sample.sub, s.floor_sample_step, sample.scale, sample.intr, rot,
                        sample.cam)  # fmt: skip
        fit = fit_floor(pts, sample.cam, max_tilt_deg=s.max_tilt_deg)
        return fit, rot.T @ fit.rotation @ rot, tuple(sample.cam[:2].tolist())

    def _pending_fit(self) -> tuple[FloorFit, np.ndarray, tuple] | None:
        """The fit the last merged frame left due (``floor_async``), for this frame: waited
        for if the worker has not finished it, made here if nobody started it (a caller that
        never calls ``fit_pending_floor``), so the frame that takes it never depends on the
        thread's timing. None when none is due."""
        if self._floor_job is not None:
            return self._floor_job.result()
        if self._floor_due is not None:
            return self._fit(self._floor_due)
        return None

    def fit_pending_floor(self) -> bool:
        """Start the floor fit a frame left due (``floor_async``) on the worker thread; the
        node calls this once the frame's delta is out, and the next merged frame takes it.
        False when none is due, or the one started is not taken yet (a refused frame
        between them)."""
        if self._floor_due is None or self._floor_job is not None:
            return False
        if self._fitter is None:
            self._fitter = ThreadPoolExecutor(max_workers=1, thread_name_prefix="floor-fit")
        sample, self._floor_due = self._floor_due, None
        self._floor_job = self._fitter.submit(self._fit, sample)
        return True

    def wait_for_floor(self, timeout_s: float = 10.0) -> None:
        """Until the fit running on the worker thread is done (tests, and a clean close)."""
        if self._floor_job is not None:
            self._floor_job.result(timeout=timeout_s)

    def close(self) -> None:
        """Stop the floor fit's worker thread, if one was started."""
        if self._fitter is not None:
            self._fitter.shutdown(wait=True, cancel_futures=True)
            self._fitter, self._floor_job = None, None
