"""Print the short table of ``scripts/gpu_check.sh``: cuda against cpu, and the targets.

Reads ``bench_cuda.json``, ``bench_big_cuda.json``, ``bench_2000_cuda.json`` and
``bench_scen_cuda.json`` (``guidebelt bench`` rows: the walk through the daemon's navigator),
``dss.json`` (``scripts/time_dss.py`` rows) and ``device.txt`` from the folder given; missing
files are skipped. The target is on the median
replanning step (repair + path to the host); a second table gives issue 20's checks on the
worst step: EDS p99 against ``P99_TARGETS`` and DSS's p99, EDS walk time against DSS's.

    python3 scripts/gpu_table.py out/gpu_check
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

# (grid, mode) -> the target on an H100, ms per step: the courtyard's walk only.
TARGETS = {(400, "eds"): 0.1, (400, "dss"): 0.25, (2000, "eds"): 1.0, (2000, "dss"): 2.0}
# grid -> issue 20's target for the EDS step's p99 on an H100, ms, in every scenario; and
# everywhere EDS p99 <= DSS p99 and EDS walk <= WALK_SHARE x DSS walk.
P99_TARGETS = {400: 0.2, 1000: 0.4, 2000: 1.0}
WALK_SHARE = 0.5


def worst_step_lines(rows: list[dict]) -> list[str]:
    """Issue 20's checks, one line per walk that has both an EDS and a DSS row."""
    by_walk: dict[tuple, dict[str, dict]] = {}
    for r in rows:
        key = (r.get("scenario", "courtyard"), r["grid"], r["unknown"])
        by_walk.setdefault(key, {})[r["mode"]] = r
    lines = []
    for (scenario, grid, unknown), modes in by_walk.items():
        if "eds" not in modes or "dss" not in modes:
            continue
        eds, dss = modes["eds"], modes["dss"]
        target = P99_TARGETS.get(grid)
        share = eds["walk_ms"] / dss["walk_ms"] if dss["walk_ms"] else float("nan")
        checks = [
            "" if target is None else ("ok" if eds["ms_p99"] <= target else "MISS"),
            "ok" if eds["ms_p99"] <= dss["ms_p99"] else "MISS",
            "ok" if share <= WALK_SHARE else "MISS",
        ]
        lines.append(
            f"{scenario:9} {grid:5} {unknown:4} {eds['ms_p99']:7.3f} "
            f"{'' if target is None else f'{target:g}':>6} {checks[0]:>4} {dss['ms_p99']:7.3f} "
            f"{checks[1]:>4} {share:6.2f} {checks[2]:>4}"
        )
    return lines


def load(path: Path) -> list[dict]:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return []


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/gpu_check")
    device = (out / "device.txt").read_text().split("\n") if (out / "device.txt").exists() else []
    print("\n" + " | ".join(line for line in device if line))
    print("closed-loop walk, ms per replanning step (repair + path); nav = the navigator's step")
    print("(own: the planner's own time for the same calls, without the navigator around them)")
    print(f"{'scenario':9} {'grid':>5} {'unk':>4} {'mode':4} {'planner':16} {'steps':>6} "
          f"{'median':>7} {'p99':>7} {'max':>7} {'walk':>8} {'own med':>7} {'nav med':>7} "
          f"{'nav p99':>7} {'target':>8}")  # fmt: skip
    for name in ("bench_cuda", "bench_big_cuda", "bench_2000_cuda", "bench_scen_cuda"):
        for r in load(out / f"{name}.json"):
            # rows from before the scenario field are the courtyard's
            scenario = r.get("scenario", "courtyard")
            target = TARGETS.get((r["grid"], r["mode"])) if scenario == "courtyard" else None
            mark = "" if target is None else ("ok" if r["ms_median"] <= target else "MISS")
            steps = f"{r['steps']}" + ("c" if r.get("capped") else "")
            print(f"{scenario:9} {r['grid']:5} {r['unknown']:4} {r['mode']:4} {r['planner']:16} "
                  f"{steps:>6} {r['ms_median']:7.3f} {r['ms_p99']:7.3f} {r['ms_max']:7.3f} "
                  f"{r['walk_ms']:8.1f} {r['plan_ms_median']:7.3f} {r['nav_ms_median']:7.3f} "
                  f"{r['nav_ms_p99']:7.3f} "
                  f"{(f'{target:g} ' + mark) if target else '':>8}")  # fmt: skip
    # per file: the courtyard at 400 is walked by bench_cuda and by bench_scen_cuda
    names = ("bench_cuda", "bench_big_cuda", "bench_2000_cuda", "bench_scen_cuda")
    lines = [line for name in names for line in worst_step_lines(load(out / f"{name}.json"))]
    if lines:
        print("\nissue 20, the worst step: EDS p99 against its target and DSS's, EDS walk / DSS")
        print(f"{'scenario':9} {'grid':>5} {'unk':>4} {'EDS p99':>7} {'target':>6} {'':>4} "
              f"{'DSS p99':>7} {'':>4} {'walk':>6} {'<=0.5':>4}")  # fmt: skip
        print("\n".join(lines))
    defer = sorted(out.glob("defer_*.json"))
    if defer:
        print("\nissue 20 with DeferredBlocks (file: on/off), the same checks; idle: the walk's")
        print("deferred blocks given between steps, ms, in no step")
        for path in defer:
            rows = load(path)
            idle = {(r.get("scenario"), r["grid"]): r.get("idle_walk_ms", 0.0) for r in rows
                    if r["mode"] == "eds"}  # fmt: skip
            for line, key in zip(worst_step_lines(rows), idle, strict=False):
                print(f"{path.stem:15} {line} idle {idle[key]:7.1f}")
    dss = load(out / "dss.json")
    if dss:
        print("\nDSS from scratch + path on the whole map (fused: one update_and_path call)")
        print(f"{'variant':9} {'grid':>5} {'step':>7} {'fused':>7} {'max':>7} {'rounds':>6} "
              f"{'MB':>6} exact")  # fmt: skip
        for r in dss:
            mb = f"{r['device_MB']:6.1f}" if r.get("device_MB") is not None else f"{'-':>6}"
            print(f"{r['variant']:9} {r['grid']:5} {r['step_ms_median']:7.3f} "
                  f"{r['fused_ms_median']:7.3f} {r['fused_ms_max']:7.3f} {r['iterations']:6} "
                  f"{mb} {r['exact']}")  # fmt: skip
    harmonic = load(out / "harmonic" / "replan.json")
    if harmonic:
        print("\nissue 21, harmonic beside EDS on the courtyard walk (scripts/harmonic_check.sh)")
        print(f"{'planner':9} {'grid':>5} {'steps':>6} {'median':>8} {'p99':>8} {'max':>8} "
              f"{'sweeps med':>10} {'target':>8}")  # fmt: skip
        for r in harmonic:
            s = r["step_ms"]
            target = {400: 1.0, 2000: 10.0}.get(r["grid"]) if r["planner"] == "harmonic" else None
            mark = "" if target is None else ("ok" if s["median"] <= target else "MISS")
            print(f"{r['planner']:9} {r['grid']:5} {r['steps']:6} {s['median']:8.3f} "
                  f"{s['p99']:8.3f} {s['max']:8.3f} {r['sweeps']['median']:10} "
                  f"{(f'{target:g} ' + mark) if target else '':>8}")  # fmt: skip
    users = load(out / "users" / "users_cuda.json") + load(out / "users" / "users_rate.json")
    if users:
        print("\nissue 28, users on one device (400², 40 %): per-user step ms (rate: from due)")
        print(f"{'backend':7} {'mode':11} {'users':>5} {'median':>7} {'p99':>7} {'max':>7} "
              f"{'steps/s':>8} {'MB/user':>7} kept up")  # fmt: skip
        for r in users:
            print(f"{r['backend']:7} {r['mode']:11} {r['users']:5} {r['median']:7.3f} "
                  f"{r['p99']:7.3f} {r['max']:7.3f} {r['steps_per_s']:8.0f} "
                  f"{r['device_bytes'] / 1e6:7.2f} {r.get('kept_up', '')}")  # fmt: skip
    mapper = load(out / "mapper" / "bench.json")
    if mapper:
        print("\nissue 23, the mapper: a 640 x 480 depth frame to a published delta, ms")
        print(f"{'backend':7} {'floor refit':>11} {'frames':>6} {'median':>7} {'p99':>7} "
              f"{'max':>7}")  # fmt: skip
        for r in mapper:
            print(f"{r['backend']:7} {'every ' + str(r['floor_every']):>11} {r['frames']:6} "
                  f"{r['median_ms']:7.3f} {r['p99_ms']:7.3f} {r['max_ms']:7.3f}")  # fmt: skip


if __name__ == "__main__":
    main()
