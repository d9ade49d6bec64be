"""The user's own controls: the belt's buttons, run-time settings and the belt's battery.

Button actions (``BUTTON_ACTIONS``, documented in ``PATTERNS.md``): pause and resume
guidance, repeat the last instruction, where am I, battery on demand, intensity steps.

Pause is a state of the user's session, not of the planner: the route keeps being planned
and the position tracked (where-am-I still answers), but nothing the guidance says reaches
the user except a safety STOP — belt patterns and cues alike. Only the resume event (the
same button again) ends it; a new goal, an arrival or a reroute do not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from daemon.guidance.cues import PHRASES, Lang
from daemon.guidance.guide import Guidance
from daemon.guidance.where import where_text
from protocol.messages import (
    BeltButton,
    CuePriority,
    PatternKind,
    Pose,
    UserSettings,
    VoiceCue,
)

from .inbox import Inbox, StepOutput

BUTTON_ACTIONS: dict[tuple[int, str], str] = {
    (0, "short"): "pause",  # pause, or resume when paused
    (1, "short"): "repeat",
    (1, "long"): "where",
    (2, "short"): "intensity",
    (2, "long"): "battery",
}
"""(button, press kind) → action. Button 0 long is left free: a held pause button does
nothing, so a user who leans on it does not toggle guidance twice."""

CONTROL_PHRASES = frozenset(
    {
        PatternKind.PAUSED, PatternKind.RESUMED, "repeat_none", "where_goal", "where_turn",
        "where_no_goal", "where_no_pose", "battery", "battery_low", "battery_unknown",
        "intensity",
    }
)  # fmt: skip
"""The keys of ``cues.PHRASES`` said only about the user's controls and the belt itself:
answers to a press and the battery warning, never an instruction to walk by. (Where-am-I
names clock hours: a listener must not take it for a turn.)"""

INTENSITY_STEPS = (0, 25, 50, 75, 100)
"""The intensity button steps up through these and wraps to the lowest."""

SAFETY_ONLY = frozenset({PatternKind.STOP})
"""What gets through while paused."""


@dataclass(frozen=True)
class BatteryPolicy:
    """When the belt's battery is low, and how full it is, for a 1-cell Li-ion pack."""

    low_v: float = 3.5
    empty_v: float = 3.3
    full_v: float = 4.2
    rearm_v: float = 0.1
    """The warning re-arms only once the battery is this far above ``low_v`` again."""
    repeat_s: float = 300.0
    """Still low: warned again this often."""

    def percent(self, volts: float) -> int:
        f = (volts - self.empty_v) / (self.full_v - self.empty_v)
        return round(100 * min(1.0, max(0.0, f)))


@dataclass(frozen=True)
class Whereabouts:
    """What where-am-I needs from the navigator, at the end of a step."""

    pose: Pose | None
    goal_xy: tuple[float, float] | None
    route_m: float | None
    turn_xy: tuple[float, float] | None


class UserControls:
    def __init__(
        self, lang: Lang = "en", intensity: int = 100, battery: BatteryPolicy | None = None
    ) -> None:
        self.lang: Lang = lang
        self.intensity = intensity
        self.battery = battery or BatteryPolicy()
        self.paused = False
        self.battery_v: float | None = None
        self.last_instruction: VoiceCue | None = None
        self.ignored = 0
        """Presses with no action (button 0 long, or a button this daemon does not know)."""
        self._low = False
        self._warned_at = -math.inf
        self._answered = False

    def finish(
        self,
        inbox: Inbox,
        out: StepOutput,
        now: float,
        guidance: Guidance,
        where: Whereabouts,
    ) -> bool:
        """The end of a step: silence it if paused, then the buttons, settings and battery.

        Returns whether pause was switched (the caller publishes the status)."""
        if self.paused:
            _silence(out)
        elif out.voice:
            self.last_instruction = out.voice[-1]
        if inbox.settings is not None:
            # Voice, wording and units were applied as the step began (``Navigator.step``).
            asked = inbox.settings
            intensity = self.intensity if asked.intensity is None else asked.intensity
            self._set_intensity(intensity, now, out, guidance)
        if inbox.battery_v is not None:
            self.battery_v = inbox.battery_v
        switched = False
        self._answered = False
        for press in inbox.buttons:
            switched |= self._press(press, out, now, guidance, where)
        self._check_battery(out, now)
        if self._answered:
            # A routine direction right after an answer would talk over it. Not after
            # "guidance resumed": the direction is what the user wants to hear next.
            limiter = guidance.cues.limiter
            limiter.last_routine_at = max(limiter.last_routine_at, now)
        return switched

    # -- actions --------------------------------------------------------------------------

    def _press(
        self, press: BeltButton, out: StepOutput, now: float, guidance: Guidance, where: Whereabouts
    ) -> bool:
        action = BUTTON_ACTIONS.get((press.button, press.kind))
        p = PHRASES[self.lang]
        if action == "pause":
            self.paused = not self.paused
            kind = PatternKind.PAUSED if self.paused else PatternKind.RESUMED
            # This step's own guidance goes too: on resume, so the RESUMED tap is felt
            # before the next step's GUIDE; a STOP of this step stays, and wins.
            _silence(out)
            if not any(b.kind == PatternKind.STOP for b in out.belt):
                out.belt.append(guidance.patterns.event(kind, now))
            if not self.paused:
                guidance.reset()  # directions are said afresh, as after a new goal
            self._say(out, p[kind], str(kind), now, CuePriority.SAFETY)
            return True
        if action == "repeat":
            last = self.last_instruction
            self._say(out, last.text if last else p["repeat_none"], "repeat", now)
        elif action == "where":
            text = where_text(self.lang, where.pose, where.goal_xy, where.route_m, where.turn_xy)
            self._say(out, text, "where", now)
        elif action == "battery":
            self._say(out, self._battery_text(), "battery", now)
        elif action == "intensity":
            higher = [n for n in INTENSITY_STEPS if n > self.intensity]
            self._set_intensity(higher[0] if higher else INTENSITY_STEPS[0], now, out, guidance)
            self._say(out, p["intensity"].format(n=self.intensity), "intensity", now)
        else:
            self.ignored += 1
        return False

    def _set_intensity(
        self, intensity: int, now: float, out: StepOutput, guidance: Guidance
    ) -> None:
        self.intensity = intensity
        out.settings = self.state(guidance, now)

    def state(self, guidance: Guidance, now: float) -> UserSettings:
        """Every setting as it is now: what the daemon publishes and stores."""
        return UserSettings(intensity=self.intensity, voice=guidance.voice,
                            wording=guidance.cues.wording, units=guidance.cues.units,
                            stamp=now)  # fmt: skip

    def _battery_text(self) -> str:
        p = PHRASES[self.lang]
        if self.battery_v is None:
            return p["battery_unknown"]
        volts = f"{self.battery_v:.1f}"
        if self.lang == "es":
            volts = volts.replace(".", ",")
        return p["battery"].format(volts=volts, pct=self.battery.percent(self.battery_v))

    def _check_battery(self, out: StepOutput, now: float) -> None:
        v, policy = self.battery_v, self.battery
        if v is None:
            return
        if v >= policy.low_v + policy.rearm_v:
            self._low = False
            return
        if v >= policy.low_v or (self._low and now - self._warned_at < policy.repeat_s):
            return
        self._low, self._warned_at = True, now
        text = PHRASES[self.lang]["battery_low"].format(pct=policy.percent(v))
        self._say(out, text, "battery_low", now, CuePriority.SAFETY)

    def _say(
        self,
        out: StepOutput,
        text: str,
        kind: str,
        now: float,
        priority: CuePriority = CuePriority.ROUTINE,
    ) -> None:
        # Answers to the user's own request bypass the limiter: asked for, so said now.
        self._answered |= priority is CuePriority.ROUTINE
        out.voice.append(VoiceCue(text=text, lang=self.lang, priority=priority, kind=kind,
                                  stamp=now))  # fmt: skip


def _silence(out: StepOutput) -> None:
    """Keep only what gets through a pause: safety STOP patterns and their cue."""
    out.belt[:] = [b for b in out.belt if b.kind in SAFETY_ONLY]
    out.voice[:] = [c for c in out.voice if c.kind == str(PatternKind.STOP)]


__all__ = ["BUTTON_ACTIONS", "CONTROL_PHRASES", "BatteryPolicy", "UserControls", "Whereabouts"]
