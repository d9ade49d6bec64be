"""One user's session as a state machine: its states, the moves allowed between them, and the
rule every step keeps.

The states are ``NavState`` (the ``state`` of every ``NavStatus``). Events move the session:

    a goal received              → planning
    a path found                 → guiding (rerouting: a new path around a new obstacle)
    at the goal                  → arrived
    no path to the goal          → no_path
    refused input or trouble     → the state ``OUTCOMES`` gives its code: stale (stale pose,
                                   sequence gap), error (bad message, off the map, overloaded,
                                   internal), no_path (bad goal), idle (shutdown, silence)

``TRANSITIONS`` lists the moves allowed from each state; a move outside it is a bug in the
navigator (``IllegalMove``), never a user's input.

The rule of a step (the latch): once the step decided STOP or WAIT, nothing later in the same
step guides. Guidance resumes only in a later step, and only once the cause is cleared:

    stale_pose                       a fresh pose (received within stale_pose_s)
    sequence_gap, shape_mismatch     a snapshot brought the map up to date
    new_epoch                        the restarted map source's snapshot (its new epoch)
    restored                         a fresh pose after the daemon's restart (and the stored
                                     map confirmed by its source's snapshot)
    overloaded                       admission control guides the user again
    a refused message (old_epoch…)   a step in which nothing is refused
"""

from __future__ import annotations

from protocol.messages import NavState

S = NavState
_TROUBLE = {S.STALE, S.ERROR, S.NO_PATH, S.IDLE}
"""Where a refusal, a bad goal or trouble may take any session."""

TRANSITIONS: dict[NavState, frozenset[NavState]] = {
    S.IDLE: frozenset({S.IDLE, S.PLANNING} | _TROUBLE),
    S.PLANNING: frozenset({S.PLANNING, S.GUIDING, S.REROUTING, S.ARRIVED} | _TROUBLE),
    S.GUIDING: frozenset({S.PLANNING, S.GUIDING, S.REROUTING, S.ARRIVED} | _TROUBLE),
    S.REROUTING: frozenset({S.PLANNING, S.GUIDING, S.REROUTING, S.ARRIVED} | _TROUBLE),
    S.ARRIVED: frozenset({S.ARRIVED, S.PLANNING} | _TROUBLE),
    # The causes cleared, guidance resumes where it was.
    S.NO_PATH: frozenset({S.PLANNING, S.GUIDING, S.REROUTING, S.ARRIVED} | _TROUBLE),
    S.STALE: frozenset({S.PLANNING, S.GUIDING, S.REROUTING, S.ARRIVED} | _TROUBLE),
    S.ERROR: frozenset({S.PLANNING, S.GUIDING, S.REROUTING, S.ARRIVED} | _TROUBLE),
}
"""From each state, the states one move may reach. Not reachable: arrived → guiding (a user
at the goal is guided again only after a new goal: planning first) and idle → guiding."""

GUIDED = frozenset({S.GUIDING, S.REROUTING})


class IllegalMove(RuntimeError):
    """The navigator tried a move ``TRANSITIONS`` does not allow: a bug, said loudly."""


class SessionState:
    """The session's state and this step's latch."""

    def __init__(self) -> None:
        self.state = NavState.IDLE
        self.held = False
        """This step decided STOP or WAIT: it guides no one any more."""
        self.moves: list[tuple[NavState, NavState]] = []
        """Every move made (kept short: for tests and the state machine's own checks)."""

    def begin_step(self) -> None:
        self.held = False

    def hold(self) -> None:
        """STOP or WAIT decided: the latch stays closed until the next step."""
        self.held = True

    def may_guide(self) -> bool:
        return not self.held

    def move(self, to: NavState) -> None:
        if to in GUIDED and self.held:
            raise IllegalMove(f"{to} after a STOP or WAIT in the same step")
        if to not in TRANSITIONS[self.state]:
            raise IllegalMove(f"{self.state} → {to} is not a move of the session")
        if to != self.state:
            self.moves.append((self.state, to))
            del self.moves[:-64]
        self.state = to
