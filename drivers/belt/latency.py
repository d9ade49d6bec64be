"""Belt link latency, measured: ``python -m drivers.belt.latency --belt simavr --patterns 200``.

For each of N patterns written to the belt's pty (one every 50 ms, each different):
- host: write → the PWM register change, on the host's monotonic clock;
- belt clock: the first byte entering the belt's UART → the PWM change (for simavr this
  is simulated time: the frame's 115200-baud transfer plus the firmware's work);
- the ack's round trip: write → ack frame read back by the host.
Prints medians and p95, optionally writes JSON.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import serial

from drivers.belt import frames as F
from drivers.belt.hil import SimulatedBelt


def measure(kind: str, patterns: int, link: str) -> dict[str, object]:
    belt = SimulatedBelt(kind, link).start()
    try:
        ser = serial.Serial(link, 115200, timeout=0.5)
        ser.reset_input_buffer()
        parser = F.Parser()
        host_ms, belt_ms, ack_ms = [], [], []
        for i in range(patterns):
            motors = (i % 250 + 1, (i * 7) % 250 + 1, (i * 13) % 250 + 1, (i * 31) % 250 + 1)
            seq = i & 0xFFFF
            n_rx = len(belt.rx_bursts)
            time.sleep(0.12)  # > 100 ms of quiet, so the belt reports this frame's first byte
            written = time.monotonic()
            ser.write(F.pattern_frame(seq, F.Pattern(motors, 0, 5000)))
            acked = None
            while acked is None and time.monotonic() - written < 1.0:
                for frame in parser.feed(ser.read(ser.in_waiting or 1)):
                    msg = frame.decode()
                    if isinstance(msg, F.Ack) and msg.seq == seq:
                        acked = time.monotonic()
            event = belt.wait_levels(motors, 1.0)
            if event is None or acked is None:
                raise RuntimeError(f"pattern {i} not applied or not acked")
            host_ms.append((event.mono - written) * 1000)
            ack_ms.append((acked - written) * 1000)
            if len(belt.rx_sim) > n_rx:  # the reader saw the rx line before the pwm line
                belt_ms.append((event.sim_s - belt.rx_sim[n_rx]) * 1000)
        ser.close()
    finally:
        belt.stop()

    def stats(xs: list[float]) -> dict[str, float]:
        a = np.array(xs)
        return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)),
                "max": float(a.max()), "n": len(a)}  # fmt: skip

    return {"belt": kind, "patterns": patterns, "write_to_pwm_ms": stats(host_ms),
            "first_byte_to_pwm_belt_clock_ms": stats(belt_ms), "ack_round_trip_ms": stats(ack_ms),
            "harness_stats": belt.stats}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description="Belt link latency (simavr or mock belt).")
    ap.add_argument("--belt", choices=("simavr", "mock"), default="simavr")
    ap.add_argument("--patterns", type=int, default=100)
    ap.add_argument("--link", default="/tmp/guidebelt-latency-tty")
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args()
    result = measure(args.belt, args.patterns, args.link)
    for key in ("write_to_pwm_ms", "first_byte_to_pwm_belt_clock_ms", "ack_round_trip_ms"):
        s = result[key]
        print(f"{key:34s} median {s['median']:6.2f}  p95 {s['p95']:6.2f}  max {s['max']:6.2f}"
              f"  (n={s['n']})")  # fmt: skip
    print(result["harness_stats"] or "")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
