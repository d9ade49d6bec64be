"""What one user's navigation is told (``NavigatorSettings``, from the daemon's config) and what
its last step measured (``StepReport``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

from .controls import BatteryPolicy
from .route import PlanReport


@dataclass(frozen=True)
class NavigatorSettings:
    """What one user's navigation needs to know; the daemon's config supplies it."""

    planner: str = "eds"
    backend: str = "auto"
    variant: str = "fast"
    cell_m: float = 0.10
    user_radius_m: float = 0.3
    lang: str = "en"
    stale_pose_s: float = 1.0
    arrive_m: float = 0.3
    voice: Literal["companion", "sole"] = "companion"
    """``sole``: the voice guides alone (no belt); it speaks more and stops before contact."""
    wording: Literal["clock", "sides"] = "clock"
    units: Literal["metric", "imperial"] = "metric"
    reassure_s: float = 15.0
    landmarks: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    intensity: int = 100
    battery: BatteryPolicy = field(default_factory=BatteryPolicy)
    stop_m: float = 0.6
    """An obstacle nearer than this ahead in the camera's latest frame: STOP (``proximity``)."""


@dataclass(slots=True)
class StepReport:
    """How long the last step took, by part, and what the planner did in it."""

    changed: int = 0
    """Cells whose blocked state flipped."""
    inflate_ms: float = 0.0
    """Applying the step's deltas to the map and inflating them."""
    plan: PlanReport = field(default_factory=PlanReport)
    guide_ms: float = 0.0
    step_ms: float = 0.0
    """The whole step, inputs to outputs."""
    idle_ms: float = 0.0
    """After the step, its outputs out: the planner's work left for then (``between_steps``)."""
