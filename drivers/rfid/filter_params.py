"""The pose filter's noise figures: the reader's (the RSSI model's) and a belt IMU's."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class FilterParams:
    """Noise figures: the reader's (the RSSI model's) and a belt IMU's pedometer and compass."""

    sigma_read_db: float = 3.0
    """Fast shadowing of one UHF read."""
    sigma_tag_db: float = 1.5
    """What the median cannot remove: a tag's fixed offset (mounting) and model error."""
    tag_memory_s: float = 5.0
    """A tag's fixed offset is the same in every read: the m updates one tag gave in this
    long share its variance (σ_tag² m each), so together they never count for more than one
    — else a user standing by one tag would grow sure of a biased position."""
    gate_sigma: float = 3.5
    """UHF reads whose innovation exceeds this many σ are taken as multipath and dropped."""
    lf_sigma_m: float = 0.05
    """A read LF tag is within its 10 cm read range: about 5 cm per axis."""
    step_sigma_frac: float = 0.06
    """Pedometer step-length error, a fraction of the step."""
    step_sigma_m: float = 0.02
    heading_sigma_rad: float = math.radians(6.0)
    """Compass noise plus the step's veer from the body's heading (gait)."""
    bias_walk_rad: float = math.radians(0.3)
    """How far the compass bias may drift per step (walking past steel)."""
    init_sigma_m: float = 1.0
    """Start with no prior: the first tag read puts the user within the UHF field of it."""
    init_scale_sd: float = 0.05
    """Prior on the pedometer's stride-model error: fitted to the user within a few %."""
    init_bias_sigma_rad: float = math.radians(8.0)
    """Prior on the compass bias: indoor offsets of a few degrees, rarely past 15°."""
    eq3_min_m: float = 0.6
    """Eq. 3 needs this much straight travel before it says anything about the heading."""
    eq3_window_s: float = 1.5
    eq3_max_turn_rad: float = math.radians(12.0)
    """The compass must have stayed within this during the window: walking straight."""
    eq3_gain_sigma_rad: float = math.radians(8.0)
    bump_sigma_m: float = 0.15
    """Spread added when the user bumps into an obstacle (``bump``)."""
    drift_mps: float = 0.7
    """Without a pedometer the user may be anywhere a walk takes them: the position's spread
    grows by this much per √s between corrections (a brisk walk's worth)."""
