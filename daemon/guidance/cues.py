"""Voice cues the way blind travellers are guided: clock-face directions and distances.

"Turn to 2 o'clock, then 3 metres": 12 o'clock is straight ahead, 3 o'clock is the right hand.
Phrase tables in English and Spanish. Safety cues (stop, path blocked, no path, wait, turn
around, arrived) are spoken at once; routine direction cues are rate limited and only repeated
when what they say has changed, so the voice does not chatter over the belt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from protocol.messages import CuePriority, PatternKind, VoiceCue

Lang = Literal["en", "es"]
Wording = Literal["clock", "sides"]
"""Directions as clock hours ("turn to 2 o'clock") or as sides ("turn slightly right")."""
Units = Literal["metric", "imperial"]

FOOT_M = 0.3048

PHRASES: dict[str, dict[str, str]] = {
    "en": {
        "turn": "turn to {hour} o'clock, then {dist}",
        "turn_wait": "turn to {hour} o'clock and wait",
        "new_route": "new route, {way}",
        "off_route": "off route, {way}",
        "goal_in": "goal in {dist}",
        "ahead": "straight ahead, {dist}",
        "metres": "{n} metres",
        "metre": "1 metre",
        "half": "half a metre",
        "feet": "{n} feet",
        "foot": "1 foot",
        "side_turn": "turn {side}, then {dist}",
        "side_wait": "turn {side} and wait",
        "slightly right": "slightly right",
        "right": "right",
        "sharply right": "sharply right",
        "slightly left": "slightly left",
        "left": "left",
        "sharply left": "sharply left",
        PatternKind.ARRIVED: "arrived",
        PatternKind.STOP: "stop",
        PatternKind.REROUTE: "path blocked, rerouting",
        PatternKind.NO_PATH: "no path to the goal",
        PatternKind.WAIT: "wait",
        PatternKind.TURN_AROUND: "turn around",
        PatternKind.PAUSED: "guidance paused",
        PatternKind.RESUMED: "guidance resumed",
        PatternKind.LOOK: "turn slowly and look for the target",
        "repeat_none": "nothing to repeat yet",
        "where_goal": "goal {dist} at {hour} o'clock",
        "where_turn": "next turn {dist} at {hour} o'clock",
        "where_no_goal": "no goal set",
        "where_no_pose": "position unknown",
        "battery": "belt battery {volts} volts, {pct} percent",
        "battery_low": "belt battery low, {pct} percent",
        "battery_unknown": "belt battery unknown",
        "intensity": "belt intensity {n}",
    },
    "es": {
        "turn": "gira a las {hour}, luego {dist}",
        "turn_wait": "gira a las {hour} y espera",
        "new_route": "nueva ruta, {way}",
        "off_route": "fuera de ruta, {way}",
        "goal_in": "destino a {dist}",
        "ahead": "sigue recto, {dist}",
        "metres": "{n} metros",
        "metre": "1 metro",
        "half": "medio metro",
        "feet": "{n} pies",
        "foot": "1 pie",
        "side_turn": "gira {side}, luego {dist}",
        "side_wait": "gira {side} y espera",
        "slightly right": "un poco a la derecha",
        "right": "a la derecha",
        "sharply right": "muy a la derecha",
        "slightly left": "un poco a la izquierda",
        "left": "a la izquierda",
        "sharply left": "muy a la izquierda",
        PatternKind.ARRIVED: "has llegado",
        PatternKind.STOP: "alto",
        PatternKind.REROUTE: "camino bloqueado, buscando otra ruta",
        PatternKind.NO_PATH: "no hay camino hasta el destino",
        PatternKind.WAIT: "espera",
        PatternKind.TURN_AROUND: "da la vuelta",
        PatternKind.PAUSED: "guía en pausa",
        PatternKind.RESUMED: "guía reanudada",
        PatternKind.LOOK: "gira despacio y busca el objetivo",
        "repeat_none": "aún no hay nada que repetir",
        "where_goal": "destino a {dist}, a las {hour}",
        "where_turn": "próximo giro a {dist}, a las {hour}",
        "where_no_goal": "no hay destino",
        "where_no_pose": "posición desconocida",
        "battery": "batería del cinturón {volts} voltios, {pct} por ciento",
        "battery_low": "batería del cinturón baja, {pct} por ciento",
        "battery_unknown": "batería del cinturón desconocida",
        "intensity": "intensidad del cinturón {n}",
    },
}

SAFETY_KINDS = frozenset(
    {
        PatternKind.STOP,
        PatternKind.REROUTE,
        PatternKind.NO_PATH,
        PatternKind.WAIT,
        PatternKind.TURN_AROUND,
        PatternKind.ARRIVED,
    }
)
"""Spoken at once, ahead of routine cues (arrived too: the user must stop walking)."""


def clock_hour(rel: float) -> int:
    """Relative angle (radians, positive = left) → clock hour 1..12, 12 straight ahead."""
    h = round(-math.degrees(rel) / 30.0) % 12
    return 12 if h == 0 else int(h)


def side_of(rel: float) -> str | None:
    """Relative angle (radians, positive = left) → a side phrase key; None for straight ahead
    (within the ±15° that 12 o'clock covers)."""
    deg = math.degrees(rel)
    if abs(deg) <= 15.0:
        return None
    hand = "left" if deg > 0 else "right"
    if abs(deg) <= 45.0:
        return f"slightly {hand}"
    return hand if abs(deg) <= 112.5 else f"sharply {hand}"


def say_distance(metres: float, lang: Lang, units: Units = "metric") -> str:
    p = PHRASES[lang]
    if units == "imperial":
        n = max(1, math.floor(metres / FOOT_M + 0.5))
        return p["foot"] if n == 1 else p["feet"].format(n=n)
    if metres < 0.75:
        return p["half"]
    n = max(1, math.floor(metres + 0.5))  # half up: round() would say 4 for 4.5
    return p["metre"] if n == 1 else p["metres"].format(n=n)


def direction_text(
    rel: float,
    metres: float,
    lang: Lang,
    wait: bool = False,
    wording: Wording = "clock",
    units: Units = "metric",
) -> str:
    """The way in words; ``wait``: turn on the spot and stand (a turn near an obstacle, kept
    apart from the walking that follows it)."""
    hour = clock_hour(rel)
    dist = say_distance(metres, lang, units)
    if wording == "sides":
        side = side_of(rel) if hour != 12 else None
        if side is None:
            return PHRASES[lang]["ahead"].format(dist=dist)
        said = PHRASES[lang][side]
        if wait:
            return PHRASES[lang]["side_wait"].format(side=said)
        return PHRASES[lang]["side_turn"].format(side=said, dist=dist)
    if wait and hour != 12:
        return PHRASES[lang]["turn_wait"].format(hour=hour)
    if hour == 12:
        return PHRASES[lang]["ahead"].format(dist=dist)
    return PHRASES[lang]["turn"].format(hour=hour, dist=dist)


def event_text(kind: PatternKind, lang: Lang) -> str:
    return PHRASES[lang][kind]


@dataclass
class CueLimiter:
    """Routine cues: at most one per ``min_interval_s`` and only when the words changed, or as
    a reminder after ``repeat_s``. Safety cues always pass, except the same words again within
    ``safety_dedupe_s`` — a belt can repeat itself every 100 ms, a voice cannot.
    """

    min_interval_s: float = 4.0
    repeat_s: float = 12.0
    safety_dedupe_s: float = 3.0
    last_routine_at: float = -math.inf
    last_routine_text: str = ""
    last_safety_at: float = -math.inf
    safety_said: dict[str, float] = field(default_factory=dict)
    """When each safety phrase was last let through."""
    suppressed: int = 0

    def allow(self, text: str, priority: CuePriority, now: float) -> bool:
        if priority is CuePriority.SAFETY:
            if now - self.safety_said.get(text, -math.inf) < self.safety_dedupe_s:
                self.suppressed += 1
                return False
            self.safety_said[text] = now
            self.last_safety_at = now
            # A routine cue right after a safety one would talk over it.
            self.last_routine_at = max(self.last_routine_at, now)
            return True
        quiet = now - max(self.last_routine_at, self.last_safety_at)
        if quiet < self.min_interval_s:
            self.suppressed += 1
            return False
        if text == self.last_routine_text and now - self.last_routine_at < self.repeat_s:
            self.suppressed += 1
            return False
        self.last_routine_at, self.last_routine_text = now, text
        return True

    def reset(self) -> None:
        self.last_routine_at = self.last_safety_at = -math.inf
        self.last_routine_text = ""
        self.safety_said.clear()


class CueMaker:
    """Phrases cues in one language and passes them through the limiter."""

    def __init__(
        self,
        lang: Lang = "en",
        limiter: CueLimiter | None = None,
        wording: Wording = "clock",
        units: Units = "metric",
    ) -> None:
        if lang not in PHRASES:
            raise ValueError(f"unsupported language {lang!r}; choose one of {sorted(PHRASES)}")
        if wording not in ("clock", "sides") or units not in ("metric", "imperial"):
            raise ValueError(
                f"wording {wording!r} / units {units!r}: clock or sides, metric or imperial"
            )
        self.lang: Lang = lang
        self.limiter = limiter or CueLimiter()
        self.wording: Wording = wording
        self.units: Units = units

    def _say(self, text: str, priority: CuePriority, kind: str, now: float) -> VoiceCue | None:
        """The cue, or None when the limiter holds it back."""
        if not self.limiter.allow(text, priority, now):
            return None
        return VoiceCue(text=text, lang=self.lang, priority=priority, kind=kind, stamp=now)

    def direction(
        self, rel: float, metres: float, now: float, wait: bool = False
    ) -> VoiceCue | None:
        text = direction_text(rel, metres, self.lang, wait, self.wording, self.units)
        return self._say(text, CuePriority.ROUTINE, "direction", now)

    def route_change(self, change: str, rel: float, metres: float, now: float) -> VoiceCue | None:
        """ "new route, turn to 2 o'clock, then 3 metres" (or "off route, …"): said at once,
        as a safety cue is, since the way the user was walking is no longer the way."""
        way = direction_text(rel, metres, self.lang, False, self.wording, self.units)
        text = PHRASES[self.lang][change].format(way=way)
        return self._say(text, CuePriority.SAFETY, change, now)

    def goal_in(self, metres: float, now: float) -> VoiceCue | None:
        """The distance left on the last leg ("goal in 5 metres"), a routine cue."""
        dist = say_distance(metres, self.lang, self.units)
        text = PHRASES[self.lang]["goal_in"].format(dist=dist)
        return self._say(text, CuePriority.ROUTINE, "countdown", now)

    def event(self, kind: PatternKind, now: float) -> VoiceCue | None:
        if kind not in PHRASES[self.lang]:
            return None  # GUIDE and OFF have nothing to say
        # The daemon's reason (goal_off_map, stale_pose…) goes to the status, not the ear.
        priority = CuePriority.SAFETY if kind in SAFETY_KINDS else CuePriority.ROUTINE
        return self._say(event_text(kind, self.lang), priority, str(kind), now)
