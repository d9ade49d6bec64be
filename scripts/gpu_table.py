"""Print the short table of ``scripts/gpu_check.sh``: cuda against cpu, and the targets.

Reads ``bench_cuda.json``, ``bench_cpu.json`` and the ``bench_big_*.json`` of 1000 and 2000
(``guidebelt bench`` rows), ``replay.json``
(``scripts/time_cuda_planner.py`` rows) and ``device.txt`` from the folder given; missing
files are skipped. Times are medians per replanning step (update + path to the host).

    python3 scripts/gpu_table.py out/gpu_check
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

# (grid, mode) -> the target on an H100, ms per step.
TARGETS = {(400, "eds"): 0.1, (400, "dss"): 0.25, (2000, "eds"): 1.0, (2000, "dss"): 2.0,
           (4000, "dss-only"): 8.0}  # fmt: skip


def load(path: Path) -> list[dict]:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return []


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/gpu_check")
    device = (out / "device.txt").read_text().split("\n") if (out / "device.txt").exists() else []
    print("\n" + " | ".join(line for line in device if line))
    cells: dict[tuple, dict[str, float]] = {}
    capped: set[tuple[int, int]] = set()
    for name in ("bench_cuda", "bench_cpu", "bench_big_cuda", "bench_big_cpu"):
        for r in load(out / f"{name}.json"):
            key = (r["grid"], r["unknown"], r["mode"])
            cells.setdefault(key, {})[r["backend"]] = r["ms_median"]
            if r.get("capped"):
                capped.add((r["grid"], r["steps"]))
    for r in load(out / "replay.json"):
        key = (r["grid"], r["unknown"], r["mode"])
        name = {"fast": "cuda", "cpu": "cpu"}.get(r["variant"], r["variant"])
        if (r["grid"], r["mode"]) in ((400, "eds"), (400, "dss")) and name in ("cuda", "cpu"):
            name += " (replay)"
        # replayed steps as the walk now takes them: update_and_path, one synchronisation
        cells.setdefault(key, {}).setdefault(name, r.get("fused_ms_median", r["step_ms_median"]))
        if not r.get("exact", True):
            print(f"NOT EXACT: {r}")
    print(f"{'grid':>5} {'unk':>4} {'mode':9} {'cuda ms':>9} {'cpu ms':>9} {'cpu/cuda':>8} "
          f"{'paper ms':>9} {'target':>7}")  # fmt: skip
    for (grid, unknown, mode), v in sorted(cells.items(), key=lambda kv: (kv[0][2] == "dss-only",
                                                                          kv[0])):  # fmt: skip
        cuda, cpu, paper = v.get("cuda"), v.get("cpu"), v.get("paper")
        ratio = f"{cpu / cuda:8.1f}" if cuda and cpu else f"{'':8}"
        target = TARGETS.get((grid, mode))
        mark = "" if target is None or cuda is None else ("ok" if cuda <= target else "MISS")
        fmt = lambda x: f"{x:9.3f}" if x is not None else f"{'-':>9}"  # noqa: E731
        print(f"{grid:5} {unknown:4} {mode:9} {fmt(cuda)} {fmt(cpu)} {ratio} {fmt(paper)} "
              f"{(f'{target:g} ' + mark) if target else '':>7}")  # fmt: skip
    for grid, steps in sorted(capped):
        print(f"({grid} x {grid}: walks capped at {steps} steps)")
    rows = load(out / "replay.json")
    variants = [r for r in rows if r["grid"] == 400 and r["mode"] != "dss-only"]
    if variants:
        print("\nvariants, 400 x 400 at 40 % (replayed walk): ms per step (update + path)")
        print("(step = update then path, two syncs; fused = update_and_path, one sync)")
        print(f"{'variant':14} {'mode':4} {'step':>7} {'repair':>7} {'path':>7} {'fused':>7} "
              f"{'rounds':>6}")  # fmt: skip
        for r in variants:
            print(
                f"{r['variant']:14} {r['mode']:4} {r['step_ms_median']:7.3f} "
                f"{r['repair_ms_median']:7.3f} {r['path_ms_median']:7.3f} "
                f"{r.get('fused_ms_median', float('nan')):7.3f} {r['iter_median']:6.0f}"
            )
    dss = [r for r in rows if r["mode"] == "dss-only"]
    if dss:
        print("\nDSS only (from scratch + path; fused: in one update_and_path)")
        print(f"{'variant':9} {'grid':>5} {'step':>7} {'fused':>7} {'rounds':>6} exact")
        for r in dss:
            print(f"{r['variant']:9} {r['grid']:5} {r['step_ms_median']:7.3f} "
                  f"{r.get('fused_ms_median', float('nan')):7.3f} {r['iter_median']:6.0f} "
                  f"{r['exact']}")  # fmt: skip


if __name__ == "__main__":
    main()
