"""The walker that hears the voice cues: what it understands, how it walks, the walks command."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from daemon.guidance.cues import PHRASES, direction_text
from daemon.navigation.controls import CONTROL_PHRASES
from daemon.planning.grid import OCCUPIED, UNKNOWN
from protocol.messages import PatternKind
from sim.courtyard import make_courtyard
from sim.voice_walker import VoiceWalker, VoiceWalkerParams, understand
from sim.walks import belt_walk, run_table

EXACT = VoiceWalkerParams(step_sd_m=0.0, gait_sd_deg=0.0, turn_sd_deg=0.0)


def open_world(n: int = 50) -> np.ndarray:
    return np.zeros((n, n), dtype=np.uint8)


def test_it_understands_every_phrase_the_daemon_can_say() -> None:
    # A phrase added to cues.py that the listener cannot parse would silently stall walks.
    for lang, table in PHRASES.items():
        for key, text in table.items():
            if key in ("turn", "turn_wait", "ahead", "metres", "metre", "half", "new_route",
                       "off_route", "goal_in", "feet", "foot", "side_turn", "side_wait",
                       "slightly right", "right", "sharply right", "slightly left", "left",
                       "sharply left"):  # fmt: skip
                continue  # templates: checked through direction_text below
            if key in CONTROL_PHRASES:
                continue  # answers to the belt's buttons and the battery: no instruction
            assert understand(text) is not None, (lang, text)
        look = understand(table[PatternKind.LOOK])
        assert look is not None and look.action == "turn_wait" and look.turn_rad < 0  # clockwise
        for hour in range(1, 13):
            rel = -math.radians(30 * hour)  # clockwise hours are negative (left-positive)
            heard = understand(direction_text(rel, 3.2, lang))  # type: ignore[arg-type]
            assert heard is not None and heard.action == "turn" and heard.metres == 3.0
            assert math.isclose(math.remainder(heard.turn_rad - rel, 2 * math.pi), 0.0,
                                abs_tol=1e-9)  # fmt: skip
        assert understand(direction_text(0.0, 0.4, lang)).metres == 0.5  # type: ignore[arg-type,union-attr]
        # Sides and feet, for the user who set them: each side's turn, the distance in feet.
        for deg, want in ((-30, -30), (-90, -90), (-140, -135), (35, 30), (100, 90), (130, 135)):
            text = direction_text(math.radians(deg), 3.0, lang, False, "sides", "imperial")  # type: ignore[arg-type]
            heard = understand(text)
            assert heard is not None and heard.action == "turn", text
            assert math.isclose(math.degrees(heard.turn_rad), want), text
            assert heard.metres is not None and math.isclose(heard.metres, 10 * 0.3048), text
        ahead = understand(direction_text(0.1, 3.0, lang, False, "sides"))  # type: ignore[arg-type]
        assert ahead is not None and ahead.turn_rad == 0.0 and ahead.metres == 3.0
        side_wait = understand(direction_text(-1.0, 3.0, lang, True, "sides"))  # type: ignore[arg-type]
        assert side_wait is not None and side_wait.action == "turn_wait"
        # A new route or off route: the way that follows; the countdown: walk on.
        for change in ("new_route", "off_route"):
            way = direction_text(-math.radians(90), 2.0, lang)  # type: ignore[arg-type]
            heard = understand(table[change].format(way=way))
            assert heard is not None and heard.action == "turn" and heard.metres == 2.0
            assert math.isclose(heard.turn_rad, -math.pi / 2)
        countdown = understand(table["goal_in"].format(dist=table["metres"].format(n=5)))
        assert countdown is not None and countdown.action == "keep"
        # "turn to 2 o'clock and wait": the same turn, then stand for the way.
        wait = understand(direction_text(-math.radians(60), 3.0, lang, wait=True))  # type: ignore[arg-type]
        assert wait is not None and wait.action == "turn_wait"
        assert math.isclose(wait.turn_rad, -math.radians(60)) and wait.metres is None
    assert understand("sing a song") is None


def test_turns_to_the_hour_walks_on_and_stops_when_told() -> None:
    w = VoiceWalker(x=2.5, y=2.5, heading=math.pi / 2, cell_m=0.1, params=EXACT)
    assert w.move(open_world()) == "stand"  # nothing said yet: nothing done
    w.hear("turn to 3 o'clock, then 2 metres", 0.0)
    assert w.heading == pytest.approx(0.0)
    assert w.move(open_world()) == "turn"  # a quarter turn takes an action on the spot
    for _ in range(3):
        assert w.move(open_world()) == "step"  # then it walks on with no further word
    assert (w.x, w.y) == pytest.approx((2.5 + 1.5, 2.5))
    w.hear("stop", 2.4)
    assert w.move(open_world()) == "stand" and w.x == pytest.approx(4.0)
    w.hear("turn to 1 o'clock, then 1 metre", 3.0)  # 30°: turn and step at once
    assert w.move(open_world()) == "step"
    assert w.heading == pytest.approx(-math.pi / 6)
    w.hear("turn around", 4.0)
    assert w.heading == pytest.approx(5 * math.pi / 6)
    assert w.heard_at == [0.0, 2.4, 3.0, 4.0] and w.cues_heard == 4
    assert w.longest_silence_s() == pytest.approx(2.4)
    assert w.longest_silence_s(0.0, end=10.0) == pytest.approx(6.0)


def test_heeding_the_distance_stops_after_it() -> None:
    w = VoiceWalker(x=2.5, y=2.5, heading=0.0, cell_m=0.1,
                    params=replace(EXACT, heed_distance=True, distance_sd=0.0))  # fmt: skip
    w.hear("straight ahead, 1 metre", 0.0)
    assert [w.move(open_world()) for _ in range(3)] == ["step", "step", "stand"]
    assert w.walked_m == pytest.approx(1.0)


def test_a_bump_is_counted_and_never_walked_through() -> None:
    world = open_world()
    world[20:30, 30] = 1  # a wall 0.45 m east of the walker
    w = VoiceWalker(x=2.55, y=2.5, heading=0.0, cell_m=0.1, params=EXACT)
    w.hear("straight ahead, 3 metres", 0.0)
    assert w.move(world) == "bump"
    assert w.collisions == 1 and (w.x, w.y) == (2.55, 2.5)
    assert w.move(world) == "stand"  # it stopped on bumping; it waits to be told again
    w.hear("straight ahead, 3 metres", 5.0)
    assert w.move(world) == "bump" and w.collisions == 2 and w.x == 2.55


def test_a_voice_walk_repeats_exactly_for_its_seed() -> None:
    scenario = make_courtyard(50, 0.4, seed=2)
    a, b = (belt_walk(scenario, seed=2, follow="voice") for _ in range(2))
    assert np.array_equal(a.track, b.track)
    assert (a.arrived, a.collisions, a.cues, a.steps) == (b.arrived, b.collisions, b.cues, b.steps)
    c = belt_walk(scenario, seed=3, follow="voice")
    assert not np.array_equal(a.track, c.track)  # the walker's noise is the seed's


def test_with_no_turning_error_it_arrives_on_an_empty_map() -> None:
    base = make_courtyard(100, 0.0, seed=0)
    walls = np.zeros_like(base.true)
    walls[0, :] = walls[-1, :] = walls[:, 0] = walls[:, -1] = OCCUPIED  # only the outer walls
    known = np.where(walls == OCCUPIED, OCCUPIED, UNKNOWN).astype(np.uint8)
    empty = replace(base, true=walls, known=known)
    walk = belt_walk(empty, seed=0, follow="voice",
                     voice_params=replace(EXACT, step_sd_m=0.0))  # fmt: skip
    assert walk.arrived, walk.reason
    assert walk.collisions == 0 and walk.cues >= 2
    assert walk.longest_silence_s is not None and walk.longest_silence_s > 0
    assert belt_walk(empty, seed=0).longest_silence_s is None  # the belt speaks every step


@pytest.mark.timeout(60)
def test_walks_command_follows_the_voice_and_refuses_a_bogus_walker(tmp_path) -> None:
    from typer.testing import CliRunner

    from cli.app import app

    out = tmp_path / "walks.json"
    args = ["--grid", "50", "--unknown", "0.2", "--runs", "2", "--json", str(out)]
    res = CliRunner().invoke(app, ["walks", "--follow", "voice", *args])
    assert res.exit_code == 0, res.output
    (row,) = json.loads(out.read_text())
    assert row["follow"] == "voice" and row["runs"] == 2
    assert {"success_rate", "collisions", "steps_per_walk", "cues_per_walk",
            "longest_silence_s", "longest_silence_max_s", "route_changes", "reroutes_announced",
            "walks_with_changes", "walks_all_announced"} <= set(row)  # fmt: skip
    res = CliRunner().invoke(app, ["walks", "--follow", "bogus", "--runs", "1"])
    assert res.exit_code != 0
    assert "'bogus': choose one of belt, voice" in " ".join(res.output.split())
    with pytest.raises(ValueError, match="follow 'bogus'"):
        run_table([50], [0.2], 1, follow="bogus")


@pytest.mark.timeout(60)
@pytest.mark.parametrize("follow", ["belt", "voice"])
def test_a_route_change_on_the_walk_is_announced_within_a_step(follow: str) -> None:
    # Courtyard 100²/40 % seed 8: a newly seen obstacle turns the way ahead once.
    walk = belt_walk(make_courtyard(100, 0.4, seed=8), seed=8, follow=follow)
    assert walk.arrived and walk.route_changes >= 1
    assert walk.reroutes_announced == walk.route_changes
