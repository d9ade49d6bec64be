"""A belt IMU as the pose filter hears it: a pedometer's steps and a compass, with their errors.

The filter (``drivers.rfid.pose_filter``) is fed what a waist-worn IMU reports, never the
truth: each step's length with a per-walk scale error (a pedometer's stride model is fitted
to the user only roughly) and a per-step error, and the body's heading off by a per-walk
compass bias (steel and wiring indoors) plus per-reading noise. The figures are those of
consumer step counters and MEMS compasses indoors; they are parameters, not measurements.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ImuParams:
    scale_sd: float = 0.03
    """Per-walk stride-model error, a fraction of every step."""
    step_sd_m: float = 0.03
    compass_bias_sd_deg: float = 5.0
    """Per-walk compass offset (indoor magnetic disturbance)."""
    compass_sd_deg: float = 3.0


@dataclass
class Imu:
    """Turns the walker's true movement into the step and compass reports the filter gets."""

    params: ImuParams = field(default_factory=ImuParams)
    seed: int = 0
    rng: np.random.Generator = field(init=False, repr=False)
    scale: float = field(init=False)
    bias: float = field(init=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.scale = 1.0 + self.rng.normal(0.0, self.params.scale_sd)
        self.bias = math.radians(self.rng.normal(0.0, self.params.compass_bias_sd_deg))

    def compass(self, true_heading: float) -> float:
        noise = math.radians(self.rng.normal(0.0, self.params.compass_sd_deg))
        return _wrap(true_heading + self.bias + noise)

    def step(self, true_length_m: float) -> float:
        measured = true_length_m * self.scale + self.rng.normal(0.0, self.params.step_sd_m)
        return max(0.0, measured)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
