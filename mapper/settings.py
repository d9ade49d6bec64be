"""What a mapper is built with (``occupancy_mapper.OccupancyMapper``): the map's size, the
heights and range a point counts in, the floor fit's schedule, the frame checks' limits and
the log-odds of the evidence."""

from __future__ import annotations

from dataclasses import dataclass, field

from .frame import FrameLimits


@dataclass(frozen=True)
class MapperSettings:
    shape: tuple[int, int] = (100, 100)
    cell_m: float = 0.10
    min_height_m: float = 0.10
    """Below this above the floor a point is floor (seed 000's height threshold)."""
    max_height_m: float = 2.0
    """Above this a point is overhead: nothing a walker runs into."""
    max_range_m: float = 3.0
    """Seed 000's sensing range (3.0 m)."""
    min_points: int = 3
    """Obstacle points a cell needs in one frame to be OCCUPIED (single noisy points are not)."""
    min_share: float = 0.25
    """Share of a cell's points (obstacle and floor) that must be obstacle points."""
    cols_per_bin: int = 4
    """Image columns per clearing ray: the frame's bearings are cut into width / this bins
    (``binning.bearing_bins``), one ray each."""
    stride: int = 1
    """Pixel step of the per-pixel pass (1 = every pixel)."""
    floor_ransac: bool = True
    floor_sample_step: int = 12
    floor_every: int = 4
    """Refit the floor every this many frames (1: every frame; 4 keeps a 640 × 480 frame on
    an H100 under 1 ms p99, where every frame's fit put it at 0.98–1.06 ms). Between fits the
    last fit is kept as a tilt of the camera (a chest camera's slip moves with the camera, not
    the world), so turning does not spoil it; a step of more than ``floor_refit_m`` since the
    last fit leaves a fit due at once (taken by the next frame, ``floor_async``), and a
    relocalisation fits on its first frame's path. On the frame's path the fit was 0.23–0.50 ms
    of a frame's p99 on the H100's host (numba), the largest single part beside the GPU pass."""
    floor_refit_m: float = 0.5
    floor_async: bool = True
    """Fit a due floor off the frame's path: the frame that leaves a fit due keeps the last
    fit, the fit of its sample runs on a worker thread once its delta is out
    (``fit_pending_floor``, which the node calls after publishing), and the NEXT frame takes
    it, waiting for it if it is not done (made there on the path if nobody started it). Which
    frame uses which fit is then fixed by the frames alone, not by the thread's timing: the
    map is the same on every run and on every backend. At a camera's 30 fps the fit (~1 ms
    on the dev VM) is done long before the next frame comes; back to back the next frame
    waits about what a fit on the path costs. Only the first fit, and the one after a
    relocalisation, are made on the frame's path of the frame that needs them."""
    max_tilt_deg: float = 25.0
    backend: str = "auto"
    limits: FrameLimits = field(default_factory=FrameLimits)
    forget_s: float = 10.0
    """An obstacle the mapper saw but has not seen again for this long, out of view, goes back
    to UNKNOWN (0: never). A person who walked off while nobody looked is not a wall for
    good; a box still there is seen again on the way. Obstacles of the start map stay."""
    tail_share: float = 0.25
    """A cell with fewer obstacle points than this share of the cell beyond it along the
    ray holds that face's range-noise tail (``evidence.range_tail``), not an obstacle."""
    l_hit: float = 0.85
    """Log-odds a hit adds (p = 0.70)."""
    l_pass: float = -0.4
    """Log-odds a ray passing through adds (p = 0.40)."""
    l_occupied: float = 0.7
    """At or above: published OCCUPIED. One hit on a cell never seen is enough (an
    obstacle that appears is mapped at once); a cell seen free needs hits to outweigh
    its passes."""
    l_free: float = -0.35
    """At or below: published FREE. One pass frees a cell never seen, as before."""
    l_min: float = -2.0
    """Clamp below: a cell seen free many times needs 4 hits in a row to be an obstacle."""
    l_max: float = 3.5
    """Clamp above: an obstacle seen many times is freed after 10 passes (a person who
    walked away leaves no ghost for more than 10 frames)."""
    corridor_m: float = 0.2
    """Half-width of the walking corridor in which an obstacle counts as ahead: half a
    walker's shoulders (the planner's 0.3 m inflation keeps obstacles just outside it)."""
