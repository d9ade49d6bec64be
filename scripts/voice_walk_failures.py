"""Why voice-only walks fail: each bump and each walk's end, classified (lab notes, not a test).

Runs the same seeded walks as ``guidebelt walks --follow voice`` with an instrumented
``VoiceWalker`` and counts, for every collision, whether it came before or after the walker
had covered the distance the last cue said (a heading error against an overshoot), and for
every walk that did not arrive, what the walker was doing when time ran out and how long it
had heard nothing.

    .venv/bin/python scripts/voice_walk_failures.py --grid 100 --unknown 0.4 --runs 50
"""

from __future__ import annotations

import argparse
from collections import Counter
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

import sim.walks as walks
from sim.scenarios import make_scenario
from sim.voice_walker import VoiceWalker, VoiceWalkerParams, understand


@dataclass
class Traced(VoiceWalker):
    """A ``VoiceWalker`` that remembers what it was told and where each bump happened."""

    said_m: float | None = None
    since_cue_m: float = 0.0
    last_text: str = ""
    bumps: list[str] = field(default_factory=list)
    made: ClassVar[list[Traced]] = []
    """Every walker built, newest last: ``belt_walk`` keeps its walker to itself."""
    stopped_by: str = ""

    def __post_init__(self) -> None:
        Traced.made.append(self)

    def hear(self, text: str, now: float) -> None:
        super().hear(text, now)
        meaning = understand(text)
        if meaning is not None and meaning.action == "halt":
            self.stopped_by = f"the cue {text!r}"
        elif meaning is not None:
            self.said_m, self.since_cue_m = meaning.metres, 0.0
        self.last_text = text

    def move(self, occupancy: np.ndarray) -> str:
        before = self.walked_m
        action = super().move(occupancy)
        self.since_cue_m += self.walked_m - before
        if action == "bump":
            over = self.said_m is not None and self.since_cue_m > self.said_m + 0.25
            self.bumps.append("past the said distance" if over else "within the said distance")
            self.stopped_by = "a bump"
        return action


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=int, default=100)
    ap.add_argument("--unknown", type=float, default=0.4)
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--turn-sd", type=float, default=20.0)
    ap.add_argument("--gait-sd", type=float, default=4.0)
    args = ap.parse_args()
    params = replace(VoiceWalkerParams(), turn_sd_deg=args.turn_sd, gait_sd_deg=args.gait_sd)
    walks.VoiceWalker = Traced  # type: ignore[misc]  # the class belt_walk builds
    bumps: Counter[str] = Counter()
    ends: Counter[str] = Counter()
    arrived = 0
    for seed in range(args.runs):
        w = walks.belt_walk(make_scenario("courtyard", args.grid, args.unknown, seed), seed=seed,
                            follow="voice", voice_params=params)  # fmt: skip
        walker = Traced.made[-1]
        bumps.update(walker.bumps)
        if w.arrived:
            arrived += 1
            continue
        if walker.walking:
            ends[f"still walking on {_kind(walker.last_text)!r}"] += 1
        else:
            ends[f"standing, stopped by {walker.stopped_by or 'nothing (no cue)'}"] += 1
    print(f"{args.grid}² at {args.unknown:.0%}, {args.runs} walks, turn σ {args.turn_sd}°, "
          f"gait σ {args.gait_sd}°: "
          f"{arrived} arrived")  # fmt: skip
    print("collisions:", dict(bumps))
    print("walks that did not arrive, as time ran out:")
    for what, n in ends.most_common():
        print(f"  {n:3d}  {what}")


def _kind(text: str) -> str:
    """A cue's words with the numbers taken out, to group them."""
    return "".join("N" if ch.isdigit() else ch for ch in text) if text else "(none)"


if __name__ == "__main__":
    main()
