"""What the user feels and hears for each kind of bad input or trouble.

One row per ``code`` (the ``NavStatus.code`` on the wire): the navigation state the
user's status shows and the belt pattern kind; guidance turns the kind into motor
intensities and a spoken cue. Input the daemon cannot trust about the user's position
stops the user; a goal it cannot reach says so; a map it knows is out of date makes
the user wait while it resynchronises.
"""

from __future__ import annotations

from dataclasses import dataclass

from protocol.messages import NavState, PatternKind


@dataclass(frozen=True)
class Outcome:
    state: NavState
    pattern: PatternKind


OUTCOMES: dict[str, Outcome] = {
    # Undecodable or invalid messages, whatever key they came on.
    "malformed": Outcome(NavState.ERROR, PatternKind.STOP),
    "wrong_type": Outcome(NavState.ERROR, PatternKind.STOP),
    "unknown_field": Outcome(NavState.ERROR, PatternKind.STOP),
    "invalid": Outcome(NavState.ERROR, PatternKind.STOP),
    # Goals the planner cannot take.
    "goal_off_map": Outcome(NavState.NO_PATH, PatternKind.NO_PATH),
    "goal_in_obstacle": Outcome(NavState.NO_PATH, PatternKind.NO_PATH),
    "unknown_landmark": Outcome(NavState.NO_PATH, PatternKind.NO_PATH),
    "no_path": Outcome(NavState.NO_PATH, PatternKind.NO_PATH),
    # Position the daemon cannot trust: never guide on it.
    "pose_off_map": Outcome(NavState.ERROR, PatternKind.STOP),
    "stale_pose": Outcome(NavState.STALE, PatternKind.STOP),
    # Map updates refused whole; the map is out of date until a snapshot arrives.
    "oversized": Outcome(NavState.ERROR, PatternKind.WAIT),
    "shape_mismatch": Outcome(NavState.ERROR, PatternKind.WAIT),
    "sequence_gap": Outcome(NavState.STALE, PatternKind.WAIT),
    # The daemon itself.
    "too_many_users": Outcome(NavState.ERROR, PatternKind.STOP),
    "internal": Outcome(NavState.ERROR, PatternKind.STOP),
    "shutdown": Outcome(NavState.IDLE, PatternKind.STOP),
    "idle": Outcome(NavState.IDLE, PatternKind.OFF),  # nothing heard from the user for long
}


@dataclass(frozen=True)
class Rejection:
    """One refused message (or detected trouble) waiting to be reported."""

    code: str
    reason: str
    counted: bool = True
    """False for conditions that are not a refused message (shutdown, no path)."""
