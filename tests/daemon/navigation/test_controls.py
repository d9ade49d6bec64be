"""The user's controls on the navigator: pause and resume, repeat, where am I, battery,
intensity (issue 26). No zenoh: the HIL test drives the same code from the simulated belt."""

from __future__ import annotations

import time

import numpy as np
import pytest

from daemon.guidance.patterns import EVENT_SHAPES
from daemon.guidance.where import where_text
from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.navigation.controls import BatteryPolicy
from protocol.messages import (
    BeltButton,
    CuePriority,
    Goal,
    GoalCell,
    MapDelta,
    PatternKind,
    Pose,
    UserSettings,
)

SHAPE = (30, 30)
_press = iter(range(1, 10_000))


def navigator(**overrides) -> Navigator:
    return Navigator("u", NavigatorSettings(backend="cpu", **overrides))


def pose(cell, heading=1.57, stamp=None) -> Pose:
    r, c = cell
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=heading,
                stamp=stamp or time.time())  # fmt: skip


def press(button: int, kind: str = "short") -> BeltButton:
    return BeltButton(press=next(_press), button=button, kind=kind, stamp=time.time())


def guiding(goal=(3, 15), at=(26, 15), **overrides) -> Navigator:
    s = navigator(**overrides)
    empty = MapDelta.from_arrays(0, SHAPE, np.array([], np.int64), np.array([], np.uint8), 0.0)
    goal_msg = Goal(target=GoalCell(row=goal[0], col=goal[1]), stamp=time.time())
    out = s.step(Inbox(deltas=[empty], goal=goal_msg, pose=pose(at)), time.time())
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    return s


def kinds(out) -> list[str]:
    return [b.kind for b in out.belt]


def test_pause_quiets_guidance_and_only_the_resume_press_ends_it():
    s = guiding()
    out = s.step(Inbox(pose=pose((25, 15)), buttons=[press(0)]), time.time())
    assert kinds(out) == [PatternKind.PAUSED]  # the step's GUIDE is gone, the tap replaces it
    assert [c.text for c in out.voice] == ["guidance paused"]
    assert out.statuses[-1].paused and s.controls.paused
    for r in (24, 23, 22):  # walking on, paused: nothing felt, nothing heard
        out = s.step(Inbox(pose=pose((r, 15))), time.time())
        assert out.belt == [] and out.voice == []
    new_goal = Goal(target=GoalCell(row=3, col=5), stamp=time.time())
    out = s.step(Inbox(goal=new_goal, pose=pose((22, 15))), time.time())
    assert out.belt == [] and s.controls.paused  # a new goal does not resume
    out = s.step(Inbox(pose=pose((22, 15)), buttons=[press(0)]), time.time())
    assert kinds(out) == [PatternKind.RESUMED] and not s.controls.paused
    assert [c.text for c in out.voice] == ["guidance resumed"]
    out = s.step(Inbox(pose=pose((22, 15))), time.time())
    assert kinds(out) == [PatternKind.GUIDE]
    assert [c.kind for c in out.voice] == ["direction"]  # said afresh after the pause


def test_a_safety_stop_gets_through_a_pause_and_is_not_covered_by_the_tap():
    s = guiding()
    s.step(Inbox(pose=pose((25, 15)), buttons=[press(0)]), time.time())
    stale = pose((25, 15), stamp=time.time() - 5.0)
    out = s.step(Inbox(pose=stale), time.time())
    assert kinds(out) == [PatternKind.STOP]
    assert [c.text for c in out.voice] == ["stop"]
    # A resume press in a step that stops: STOP is the last word, not the RESUMED tap.
    out = s.step(Inbox(pose=pose((25, 15), stamp=time.time() - 5.0), buttons=[press(0)]),
                 time.time())  # fmt: skip
    assert kinds(out) == [PatternKind.STOP] and not s.controls.paused


def test_repeat_says_the_last_instruction_again():
    s = navigator()
    out = s.step(Inbox(buttons=[press(1)]), time.time())
    assert [c.text for c in out.voice] == ["nothing to repeat yet"]
    s = guiding()
    said = s.controls.last_instruction
    assert said is not None and said.kind == "direction"
    out = s.step(Inbox(buttons=[press(1)]), time.time())
    assert [(c.text, c.kind) for c in out.voice if c.kind == "repeat"] == [(said.text, "repeat")]


def test_where_am_i_gives_the_goal_and_the_next_turn_by_the_clock():
    s = guiding(goal=(3, 15), at=(26, 15))  # the goal 2.3 m due north, the user facing north
    out = s.step(Inbox(buttons=[press(1, "long")]), time.time())
    assert [c.text for c in out.voice if c.kind == "where"] == ["goal 2 metres at 12 o'clock"]
    s = guiding(goal=(15, 27), at=(15, 3))  # due east, the user facing north: 3 o'clock
    out = s.step(Inbox(buttons=[press(1, "long")]), time.time())
    assert [c.text for c in out.voice if c.kind == "where"] == ["goal 2 metres at 3 o'clock"]


def test_where_text_names_the_turn_and_speaks_spanish():
    user = Pose(x=0.0, y=0.0, heading=0.0, stamp=1.0)  # facing east
    text = where_text("en", user, (0.0, 10.0), route_m=14.2, turn_xy=(4.0, 0.0))
    assert text == "goal 14 metres at 9 o'clock; next turn 4 metres at 12 o'clock"
    assert where_text("es", user, (0.0, -3.0)) == "destino a 3 metros, a las 3"
    assert where_text("en", None, (1.0, 1.0)) == "position unknown"
    assert where_text("en", user, None) == "no goal set"


def test_battery_on_demand_and_a_low_warning_once_until_it_recovers():
    policy = BatteryPolicy(low_v=3.5, empty_v=3.3, full_v=4.2, repeat_s=60.0)
    s = navigator(battery=policy)
    out = s.step(Inbox(buttons=[press(2, "long")]), 100.0)
    assert [c.text for c in out.voice] == ["belt battery unknown"]
    out = s.step(Inbox(battery_v=3.9, buttons=[press(2, "long")]), 101.0)
    assert [c.text for c in out.voice] == ["belt battery 3.9 volts, 67 percent"]
    warned = []
    for t, volts in [(102, 3.45), (103, 3.44), (150, 3.43), (163, 3.42), (164, 3.55),
                     (165, 3.61), (166, 3.4)]:  # fmt: skip
        out = s.step(Inbox(battery_v=volts), float(t))
        warned += [(t, c.text, c.priority) for c in out.voice if c.kind == "battery_low"]
    safety = CuePriority.SAFETY
    assert warned == [(102, "belt battery low, 17 percent", safety),
                      (163, "belt battery low, 13 percent", safety),  # still low a minute on
                      (166, "belt battery low, 11 percent", safety)]  # fmt: skip


@pytest.mark.parametrize("lang", ["en", "es"])
def test_intensity_button_steps_up_and_wraps_and_settings_set_applies(lang):
    s = navigator(intensity=50, lang=lang)
    levels = []
    for _ in range(4):
        out = s.step(Inbox(buttons=[press(2)]), time.time())
        assert out.settings is not None
        levels.append(out.settings.intensity)
    assert levels == [75, 100, 0, 25]
    said = {"en": "belt intensity 25", "es": "intensidad del cinturón 25"}[lang]
    assert [c.text for c in out.voice] == [said]
    out = s.step(Inbox(settings=UserSettings(intensity=60, stamp=time.time())), time.time())
    assert out.settings is not None and out.settings.intensity == 60
    assert s.controls.intensity == 60


def test_every_event_shape_is_its_own_and_the_pause_tap_is_short():
    felt = {(tuple(m > 0 for m in e.motors), e.period_ms) for e in EVENT_SHAPES.values()}
    assert len(felt) == len(EVENT_SHAPES)
    assert EVENT_SHAPES[PatternKind.PAUSED].ttl_ms <= 150


def test_wording_units_and_voice_change_at_run_time_and_the_rest_stays() -> None:
    s = guiding(intensity=40)
    now = time.time() + 20  # past the limiter's gaps since the first cue
    asked = UserSettings(wording="sides", units="imperial", stamp=now)
    out = s.step(Inbox(settings=asked, pose=pose((26, 15), heading=0.0, stamp=now)), now)
    st = out.settings
    assert st is not None
    assert (st.intensity, st.wording, st.units, st.voice) == (40, "sides", "imperial", "companion")
    # Facing east with the goal due north: the way is said by the side, in feet.
    later = now + 20
    texts = [c.text for c in out.voice]
    out = s.step(Inbox(pose=pose((26, 15), heading=0.0, stamp=later)), later)
    texts += [c.text for c in out.voice]
    assert "turn left, then 8 feet" in texts and "goal in 8 feet" in texts, texts
    # The voice may become the user's only guide, and back.
    out = s.step(Inbox(settings=UserSettings(voice="sole", stamp=later)), later)
    assert s.guidance.voice == "sole" and s.guidance.sole is not None
    assert out.settings is not None and out.settings.voice == "sole"
    assert out.settings.wording == "sides" and out.settings.intensity == 40
    s.step(Inbox(settings=UserSettings(voice="companion", stamp=later)), later)
    assert s.guidance.voice == "companion" and s.guidance.sole is None
