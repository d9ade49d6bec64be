"""What the user feels and hears for each kind of bad input or trouble.

One row per ``code`` (the ``NavStatus.code`` on the wire): the navigation state the
user's status shows and the belt pattern kind; guidance turns the kind into motor
intensities and a spoken cue. Input the daemon cannot trust about the user's position
stops the user; a goal it cannot reach says so; a map it knows is out of date makes
the user wait while it resynchronises.
"""

from __future__ import annotations

from dataclasses import dataclass

from protocol.messages import NavState, PatternKind, StatusCode


@dataclass(frozen=True)
class Outcome:
    state: NavState
    pattern: PatternKind


OUTCOMES: dict[StatusCode, Outcome] = {
    # Undecodable or invalid messages, whatever key they came on.
    StatusCode.MALFORMED: Outcome(NavState.ERROR, PatternKind.STOP),
    StatusCode.WRONG_TYPE: Outcome(NavState.ERROR, PatternKind.STOP),
    StatusCode.UNKNOWN_FIELD: Outcome(NavState.ERROR, PatternKind.STOP),
    StatusCode.INVALID: Outcome(NavState.ERROR, PatternKind.STOP),
    # Goals the planner cannot take.
    StatusCode.GOAL_OFF_MAP: Outcome(NavState.NO_PATH, PatternKind.NO_PATH),
    StatusCode.GOAL_IN_OBSTACLE: Outcome(NavState.NO_PATH, PatternKind.NO_PATH),
    StatusCode.UNKNOWN_LANDMARK: Outcome(NavState.NO_PATH, PatternKind.NO_PATH),
    StatusCode.NO_PATH: Outcome(NavState.NO_PATH, PatternKind.NO_PATH),
    # Position the daemon cannot trust: never guide on it.
    StatusCode.POSE_OFF_MAP: Outcome(NavState.ERROR, PatternKind.STOP),
    StatusCode.STALE_POSE: Outcome(NavState.STALE, PatternKind.STOP),
    # A pose too unsure to guide on: stand and wait for a fix (``pose_margin``).
    StatusCode.POSE_UNCERTAIN: Outcome(NavState.STALE, PatternKind.WAIT),
    # Map updates refused whole; the map is out of date until a snapshot arrives.
    StatusCode.OVERSIZED: Outcome(NavState.ERROR, PatternKind.WAIT),
    StatusCode.SHAPE_MISMATCH: Outcome(NavState.ERROR, PatternKind.WAIT),
    StatusCode.SEQUENCE_GAP: Outcome(NavState.STALE, PatternKind.WAIT),
    StatusCode.NEW_EPOCH: Outcome(NavState.STALE, PatternKind.WAIT),
    StatusCode.OLD_EPOCH: Outcome(NavState.STALE, PatternKind.WAIT),
    # The daemon itself.
    StatusCode.TOO_MANY_USERS: Outcome(NavState.ERROR, PatternKind.STOP),
    # The daemon cannot keep up with everyone: this user is not guided for now. Said as it
    # is (not a stale pose, not an obstacle); the belt asks the user to wait.
    StatusCode.OVERLOADED: Outcome(NavState.ERROR, PatternKind.WAIT),
    StatusCode.INTERNAL: Outcome(NavState.ERROR, PatternKind.STOP),
    StatusCode.SHUTDOWN: Outcome(NavState.IDLE, PatternKind.STOP),
    # Back after a crash: the goal and map are restored, the pose is not (never guide on it).
    StatusCode.RESTORED: Outcome(NavState.STALE, PatternKind.WAIT),
    # Nothing heard from the user for long.
    StatusCode.IDLE: Outcome(NavState.IDLE, PatternKind.OFF),
}


@dataclass(frozen=True)
class Rejection:
    """One refused message (or detected trouble) waiting to be reported."""

    code: StatusCode
    reason: str
    counted: bool = True
    """False for conditions that are not a refused message (shutdown, no path)."""
