"""How sure a pose is: ``Pose.quality`` (0..1) and the position uncertainty in metres.

A localiser that knows its 1-σ position error σ sends it as ``Pose.sigma_m`` and the quality
``q = S / (S + σ)`` with S = ``QUALITY_SCALE_M`` (q = 0.5 at σ = 0.25 m, 1 for an exact
pose). A sender that gives only ``quality`` is read back through the inverse, so the daemon
has one figure in metres either way; the default ``quality = 1`` (the sim's true pose, old
senders) means σ = 0 and changes nothing.
"""

from __future__ import annotations

QUALITY_SCALE_M = 0.25
"""Position spread (m) at which the quality figure is 0.5."""


def quality_from_sigma(sigma_m: float) -> float:
    return QUALITY_SCALE_M / (QUALITY_SCALE_M + max(0.0, sigma_m))


def sigma_from_quality(quality: float) -> float:
    """Inverse of ``quality_from_sigma``; quality 0 (no idea) is an unbounded error."""
    if quality <= 0.0:
        return float("inf")
    return QUALITY_SCALE_M * (1.0 - min(quality, 1.0)) / quality


def pose_sigma_m(quality: float, sigma_m: float | None) -> float:
    """The pose's uncertainty in metres: its own ``sigma_m`` when it sends one."""
    return sigma_m if sigma_m is not None else sigma_from_quality(quality)
