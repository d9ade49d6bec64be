"""The simulated user who walks by ear: hears the voice cues, never feels the belt.

Nobody had checked that the cues alone can guide someone; this walker measures it. It acts on
the *words* of each cue (``VoiceCue.text``), as a listener does, when the daemon says one, and
keeps doing what it was last told in between:

- "turn to H o'clock, then D" (or "straight ahead, D"): turn by the clock hour (H·30°
  clockwise, 12 = no turn) with a seeded turning error (σ ``turn_sd_deg``, not applied to
  "straight ahead": the listener keeps its heading), then walk straight at walking pace
  (``step_m`` per action, each step veering σ ``gait_sd_deg``) until the next cue. A turn of
  more than ``turn_in_place_deg`` costs one action on the spot, as for the belt walker.
  With ``heed_distance`` the listener stops once it has walked the distance it was told
  (with a relative error σ ``distance_sd``) and waits for the next cue instead.
- "turn around": turn about 180° (the voice names no side; the error as for a turn), walk on.
- "stop", "wait", "path blocked, rerouting", "no path to the goal", "arrived": stand still
  until the next direction.
- A step whose straight line would enter an OCCUPIED cell of the true map is a collision,
  counted exactly as the belt walker counts it (``step_hits``); the walker stays where it
  was and, unlike the belt walker whose belt keeps pointing, stands until the next cue: a
  person who walked into something does not keep walking into it.

It hears English and Spanish (``PHRASES`` in ``daemon/guidance/cues.py``); words it does not
understand are counted in ``not_understood`` and ignored. Numpy only, like ``belt_walker``.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .belt_walker import step_hits

_TURN = re.compile(r"(?:turn to|gira a las) (\d{1,2})\b")
_AHEAD = re.compile(r"^(?:straight ahead|sigue recto)\b")
_METRES = re.compile(r"(\d+) (?:metres|metre|metros|metro)\b")
_FEET = re.compile(r"(\d+) (?:feet|foot|pies|pie)\b")
_SIDE = re.compile(
    r"^(?:turn|gira) (slightly|sharply|un poco a la|muy a la|a la)? ?(right|left|derecha|izquierda)"
)
_SIDE_DEG = {None: 90.0, "slightly": 30.0, "un poco a la": 30.0, "sharply": 135.0,
             "muy a la": 135.0, "a la": 90.0}  # fmt: skip
_HALF = re.compile(r"\b(?:half a metre|medio metro)\b")
_CHANGE = re.compile(r"^(?:new route|off route|nueva ruta|fuera de ruta), ")
_GOAL_IN = re.compile(r"^(?:goal in|destino a) ")
_WAIT_AFTER = re.compile(r"\b(?:and wait|y espera)$")
_AROUND = ("turn around", "da la vuelta")
_LOOK = ("turn slowly and look for the target", "gira despacio y busca el objetivo")
LOOK_TURN_RAD = -math.radians(45.0)
"""On LOOK the listener turns on the spot, clockwise, as the belt walker does, and stands: the
camera sees the next half of its view (``belt_walker``'s ``look_turn_deg``)."""
_HALT = (
    "stop", "alto", "wait", "espera", "path blocked, rerouting",
    "camino bloqueado, buscando otra ruta", "no path to the goal",
    "no hay camino hasta el destino", "arrived", "has llegado",
)  # fmt: skip


@dataclass(frozen=True)
class VoiceWalkerParams:
    """A cautious adult guided by voice alone; pace and veer as the belt walker's."""

    step_m: float = 0.5
    step_sd_m: float = 0.05
    gait_sd_deg: float = 4.0
    """Veer of each step away from the intended direction."""
    turn_sd_deg: float = 20.0
    """Error of a turn made on a spoken clock hour: the hour already rounds the direction to
    30°, and a person turning to "2 o'clock" without sight misses by a few tens of degrees."""
    turn_in_place_deg: float = 40.0
    heed_distance: bool = False
    """Stop after the distance the cue said (else: walk on until the next cue)."""
    distance_sd: float = 0.15
    """Relative error of a distance walked by counting steps (``heed_distance`` only)."""


@dataclass(frozen=True)
class Heard:
    """What one cue means to the listener."""

    action: str
    """``turn`` (with ``turn_rad``), ``turn_wait`` (turn, then stand), ``around``, ``halt`` or
    ``keep`` (go on as before: the distance left to the goal)."""
    turn_rad: float = 0.0
    """Counter-clockwise turn (the walker's frame): 3 o'clock is −π/2."""
    metres: float | None = None


def understand(text: str) -> Heard | None:
    """The meaning of a cue's words, or None for words the listener does not know."""
    t = _CHANGE.sub("", text.strip().lower())  # a new route: the way that follows is the news
    if _GOAL_IN.search(t):
        return Heard("keep")  # the distance left: walk on as before
    if t in _AROUND:
        return Heard("around", math.pi)
    if t in _LOOK:
        return Heard("turn_wait", LOOK_TURN_RAD)
    if t in _HALT:
        return Heard("halt")
    half = _HALF.search(t)
    metres_m = _METRES.search(t)
    metres = 0.5 if half else float(metres_m.group(1)) if metres_m else None
    feet = _FEET.search(t)
    if feet:
        metres = float(feet.group(1)) * 0.3048
    action = "turn_wait" if _WAIT_AFTER.search(t) else "turn"
    side = _SIDE.search(t)
    if side:
        degrees = _SIDE_DEG[side.group(1)]
        left = side.group(2) in ("left", "izquierda")
        return Heard(action, math.radians(degrees if left else -degrees), metres)
    turn = _TURN.search(t)
    if turn:
        hour = int(turn.group(1))
        if not 1 <= hour <= 12:
            return None
        # Hours 1..6 are to the right (clockwise, negative here), 7..11 to the left.
        degrees = -30.0 * hour if hour <= 6 else 30.0 * (12 - hour)
        return Heard(action, math.radians(degrees), metres)
    if _AHEAD.search(t):
        return Heard("turn", 0.0, metres)
    return None


@dataclass
class VoiceWalker:
    x: float
    y: float
    heading: float
    cell_m: float
    params: VoiceWalkerParams = field(default_factory=VoiceWalkerParams)
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    walked_m: float = 0.0
    steps: int = 0
    turns: int = 0
    collisions: int = 0
    cues_heard: int = 0
    not_understood: int = 0
    heard_at: list[float] = field(default_factory=list)
    """When each cue was heard (the world's clock): the silences between them."""
    walking: bool = False
    """Told a direction and not stopped since (a halt cue, a bump, the distance walked)."""
    left_m: float = math.inf
    """Metres still to walk on the current cue (``heed_distance``)."""
    _turn_pending: bool = False

    def act(self, view: Any) -> str:
        """The world's walker seam (``world.py``): only ``view.voice`` and the true map are
        used — never the path, never the belt."""
        for cue in getattr(view, "voice", ()):
            self.hear(str(cue.text), float(view.now))
        return self.move(view.true)

    def hear(self, text: str, now: float) -> None:
        """Take in one spoken cue: turn (the error drawn now), start or stop walking."""
        self.cues_heard += 1
        self.heard_at.append(now)
        meaning = understand(text)
        if meaning is None:
            self.not_understood += 1
            return
        p = self.params
        if meaning.action == "halt":
            self.walking, self._turn_pending = False, False
            return
        if meaning.action == "keep":
            return
        turn = meaning.turn_rad
        if meaning.action == "around" or turn != 0.0:
            turn += self._noise(p.turn_sd_deg)
        self.heading = _wrap(self.heading + turn)
        self._turn_pending = abs(turn) > math.radians(p.turn_in_place_deg)
        self.walking = meaning.action != "turn_wait"
        self.left_m = math.inf
        if p.heed_distance and meaning.metres is not None:
            self.left_m = max(0.1, meaning.metres * (1.0 + self.rng.normal(0.0, p.distance_sd)))

    def move(self, occupancy: np.ndarray) -> str:
        """Act once on what was last heard: ``"step"``, ``"turn"``, ``"stand"`` or ``"bump"``."""
        if self._turn_pending:  # the turn just heard took this action
            self._turn_pending = False
            self.turns += 1
            return "turn"
        if not self.walking:
            return "stand"
        p = self.params
        length = min(max(0.05, self.rng.normal(p.step_m, p.step_sd_m)), self.left_m)
        direction = self.heading + self._noise(p.gait_sd_deg)
        x1 = self.x + length * math.cos(direction)
        y1 = self.y + length * math.sin(direction)
        if step_hits(occupancy, self.cell_m, self.x, self.y, x1, y1):
            self.collisions += 1
            self.walking = False
            return "bump"
        self.x, self.y = x1, y1
        self.walked_m += length
        self.steps += 1
        self.left_m -= length
        if self.left_m <= 1e-9:
            self.walking = False
        return "step"

    def longest_silence_s(self, start: float = 0.0, end: float | None = None) -> float:
        """The longest time between two cues heard, ``start`` counting as one; with ``end``,
        the wait from the last cue to it too (an arrival, which ends the walk before the
        walker hears "arrived"). A walk that never arrives leaves ``end`` out: it would
        otherwise report its stall until the time limit, not a gap between cues."""
        times = [start, *self.heard_at, *([] if end is None else [end])]
        return max((b - a for a, b in itertools.pairwise(times)), default=0.0)

    def _noise(self, sd_deg: float) -> float:
        return math.radians(self.rng.normal(0.0, sd_deg)) if sd_deg > 0 else 0.0


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
