"""Voice cues: clock face, distances, both languages, the rate limit, safety first."""

from __future__ import annotations

import math

import pytest

from daemon.guidance.cues import (
    PHRASES,
    SAFETY_KINDS,
    CueLimiter,
    CueMaker,
    clock_hour,
    direction_text,
    say_distance,
)
from protocol.messages import CuePriority, PatternKind


@pytest.mark.parametrize(
    ("rel_deg", "hour"),
    [(0, 12), (-30, 1), (-60, 2), (-90, 3), (180, 6), (-180, 6), (90, 9), (60, 10), (14, 12),
     (-16, 1), (30, 11)],
)
def test_clock_hour(rel_deg: float, hour: int) -> None:
    # rel is CCW-positive (left): 3 o'clock is the right hand
    assert clock_hour(math.radians(rel_deg)) == hour


def test_direction_phrases_in_english_and_spanish() -> None:
    assert direction_text(math.radians(-60), 3.2, "en") == "turn to 2 o'clock, then 3 metres"
    assert direction_text(math.radians(-60), 3.2, "es") == "gira a las 2, luego 3 metros"
    assert direction_text(0.0, 1.1, "en") == "straight ahead, 1 metre"
    assert direction_text(0.0, 1.1, "es") == "sigue recto, 1 metro"
    assert direction_text(math.radians(90), 0.4, "en") == "turn to 9 o'clock, then half a metre"
    assert say_distance(0.5, "es") == "medio metro"
    assert say_distance(12.4, "en") == "12 metres"


@pytest.mark.parametrize(
    ("kind", "en", "es"),
    [
        (PatternKind.ARRIVED, "arrived", "has llegado"),
        (PatternKind.STOP, "stop", "alto"),
        (PatternKind.REROUTE, "path blocked, rerouting", "camino bloqueado, buscando otra ruta"),
        (PatternKind.NO_PATH, "no path to the goal", "no hay camino hasta el destino"),
        (PatternKind.WAIT, "wait", "espera"),
        (PatternKind.TURN_AROUND, "turn around", "da la vuelta"),
    ],
)
def test_event_cues_in_both_languages(kind: PatternKind, en: str, es: str) -> None:
    for lang, text in (("en", en), ("es", es)):
        cue = CueMaker(lang).event(kind, 5.0)
        assert cue is not None
        assert cue.text == text and cue.lang == lang and cue.kind == str(kind)
        assert cue.priority is CuePriority.SAFETY
        assert kind in SAFETY_KINDS


def test_both_tables_cover_the_same_phrases() -> None:
    assert set(PHRASES["en"]) == set(PHRASES["es"])


def test_guide_and_off_say_nothing() -> None:
    maker = CueMaker("en")
    assert maker.event(PatternKind.GUIDE, 1.0) is None
    assert maker.event(PatternKind.OFF, 1.0) is None


def test_unknown_language_is_refused() -> None:
    with pytest.raises(ValueError):
        CueMaker("fr")  # type: ignore[arg-type]


def test_routine_cues_are_rate_limited() -> None:
    lim = CueLimiter(min_interval_s=3.0, repeat_s=12.0)
    r = CuePriority.ROUTINE
    assert lim.allow("a", r, 0.0)
    assert not lim.allow("b", r, 1.0)  # too soon after the last one
    assert not lim.allow("b", r, 2.9)
    assert lim.allow("b", r, 3.0)
    assert not lim.allow("b", r, 7.0)  # same words again: only after repeat_s
    assert lim.allow("b", r, 15.1)
    assert lim.suppressed == 3


def test_safety_cues_pass_the_limit_and_silence_routine_ones() -> None:
    lim = CueLimiter(min_interval_s=3.0, safety_dedupe_s=3.0)
    s, r = CuePriority.SAFETY, CuePriority.ROUTINE
    assert lim.allow("turn left", r, 0.0)
    assert lim.allow("stop", s, 0.1)  # at once, though a routine cue was just said
    assert lim.allow("no path", s, 0.2)  # a different safety cue: at once too
    assert not lim.allow("stop", s, 1.0)  # the same words within 3 s: once is enough
    assert lim.allow("stop", s, 3.5)
    assert not lim.allow("turn right", r, 4.0)  # a routine cue would talk over the safety one
    assert lim.allow("turn right", r, 6.6)


def test_cue_maker_applies_the_limit() -> None:
    maker = CueMaker("en", CueLimiter(min_interval_s=3.0))
    assert maker.direction(0.0, 5.0, 0.0) is not None
    assert maker.direction(math.radians(-90), 2.0, 1.0) is None
    assert maker.event(PatternKind.STOP, 1.1) is not None
    cue = maker.direction(math.radians(-90), 2.0, 4.2)
    assert cue is not None and cue.text == "turn to 3 o'clock, then 2 metres"
    assert cue.priority is CuePriority.ROUTINE and cue.stamp == 4.2
