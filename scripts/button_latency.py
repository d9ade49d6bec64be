"""Belt button latency on the simulated Nano: press → PAUSED tap → quiet, and the resume.

The real firmware on simavr (or the mock), the ``guidebelt belt`` driver, the daemon on a
thread, a user standing still with poses at 5 Hz and a goal, as in
``tests/drivers/belt/test_buttons_hil.py``; then ``--cycles`` pause/resume pairs, a second
apart. Per press, from the moment the harness released the button pin (a short press is
reported at its release): when the belt's tap began (debounce, serial, driver, zenoh,
daemon step, zenoh, driver, serial, firmware), when every motor was off (pause), and when
the voice cue arrived on zenoh.

    python scripts/button_latency.py --cycles 30 [--belt mock]
"""

from __future__ import annotations

import argparse
import statistics
import threading
import time

import numpy as np

from daemon.service.embedded import DaemonThread
from drivers.belt import hil
from drivers.belt.recorder import Recorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell, MapDelta, Pose, VoiceCue

SHAPE, CELL_M, AT, GOAL, USER = (40, 40), 0.10, (35, 10), (5, 30), "latency"


def poses(session, stop: threading.Event) -> None:
    x, y = (AT[1] + 0.5) * CELL_M, (SHAPE[0] - AT[0] - 0.5) * CELL_M
    while not stop.wait(0.2):
        pose = Pose(x=x, y=y, heading=1.5708, stamp=time.time())
        wire.put(session, T.POSE, USER, codec.encode(pose))


def first_after(belt: hil.SimulatedBelt, t: float, motors: set[int]) -> float | None:
    hits = [e.mono for e in list(belt.events) if e.mono > t and e.level and e.motor in motors]
    return hits[0] - t if hits else None


def quiet_after(belt: hil.SimulatedBelt, t: float) -> float | None:
    """Seconds from ``t`` to the last PWM change that left every motor off (and stayed)."""
    levels, last = [0, 0, 0, 0], None
    for e in list(belt.events):
        levels[e.motor] = e.level
        if e.mono > t:
            last = None if any(levels) else (last or e.mono)
    return last - t if last is not None else None


def cue_after(voice: Recorder[VoiceCue], kind: str, t: float) -> float | None:
    got = voice.wait_for(lambda r: r.msg.kind == kind and r.at > t, 2.0)
    return got.at - t if got else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=30)
    ap.add_argument("--belt", choices=hil.KINDS, default="simavr")
    args = ap.parse_args()
    rows: dict[str, list[float]] = {k: [] for k in
                                    ("pause tap", "pause quiet", "paused cue", "resume tap",
                                     "resumed cue")}  # fmt: skip
    stop = threading.Event()
    with DaemonThread(backend="cpu") as daemon:
        peer = daemon.peer()
        voice: Recorder[VoiceCue] = Recorder(peer, T.VOICE, USER)
        with hil.start_simulated_belt(args.belt, USER, [f"tcp/127.0.0.1:{daemon.port}"]) as belt:
            walker = threading.Thread(target=poses, args=(peer, stop), daemon=True)
            walker.start()
            empty = MapDelta.from_arrays(0, SHAPE, np.array([], np.int64),
                                         np.array([], np.uint8), time.time())  # fmt: skip
            wire.put(peer, T.MAP_DELTA, USER, codec.encode(empty))
            goal = Goal(target=GoalCell(row=GOAL[0], col=GOAL[1]), stamp=time.time())
            wire.put(peer, T.GOAL, USER, codec.encode(goal))
            assert belt.wait_for(lambda: any(belt.levels), 10.0), "no guidance on the belt"
            time.sleep(1.0)
            for _ in range(args.cycles):
                t = belt.press(0)
                time.sleep(0.6)
                for key, value in (("pause tap", first_after(belt, t, {2})),
                                   ("pause quiet", quiet_after(belt, t)),
                                   ("paused cue", cue_after(voice, "paused", t))):  # fmt: skip
                    if value is not None:
                        rows[key].append(value * 1000)
                t = belt.press(0)
                time.sleep(0.6)
                for key, value in (("resume tap", first_after(belt, t, {1, 3})),
                                   ("resumed cue", cue_after(voice, "resumed", t))):  # fmt: skip
                    if value is not None:
                        rows[key].append(value * 1000)
            stop.set()
            walker.join(1)
        voice.close()
        peer.close()
    print(f"{args.belt}: {args.cycles} pause/resume cycles; ms from the button's release")
    print("| what | n | min | median | p90 | max |")
    print("|---|---|---|---|---|---|")
    for key, values in rows.items():
        if not values:
            print(f"| {key} | 0 | - | - | - | - |")
            continue
        v = sorted(values)
        p90 = v[min(len(v) - 1, int(0.9 * len(v)))]
        print(f"| {key} | {len(v)} | {v[0]:.0f} | {statistics.median(v):.0f} | {p90:.0f} | "
              f"{v[-1]:.0f} |")  # fmt: skip


if __name__ == "__main__":
    main()
