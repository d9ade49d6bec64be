"""Where a ``fast`` call's device time goes inside its phases: the link profile.

``profile_cuda_phases.py`` times the phases between block 0's stamps. This script builds the
kernels with ``GB_PROFILE`` (``kernels/profile.cuh``: a product build holds none of it), walks
the same scenarios and reads, per call, what the build sums into ``ctrl`` (``abi.PF_*``):

- the relaxation's tile visits in four parts (halo load, settle passes, stores, flags), its
  take passes with and without a tile, and the queue: a flag's time to its owner's take;
- the raise visits: take, halo load, fixpoint, the rest of the visit;
- block 0's grid barriers: arrive (fence and the arrival's atomic), wait, leave (the second
  fence), and the lag from the latest arrival to block 0 seeing the release;
- block 0's exit from the relaxation after the last visit ended.

The build's own cost (clock reads, a few shared adds, one atomic a visit) makes its calls
slower than the product's: compare its parts with each other, not its totals with a product
run.

    PYTHONPATH=. python3 scripts/profile_cuda_links.py --grid 400 \\
        --scenario explore,streets --modes eds,dss [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from daemon.planning.cuda import abi, device

device.DEFINES = ("GB_PROFILE",)  # before the first compile
abi.FLAG_SEGMENTS = 8  # the flags' times: before the first planner

sys.path.insert(0, str(Path(__file__).resolve().parent))
import profile_cuda_phases as phases  # noqa: E402

WORDS = slice(abi.PF_R_VISITS, abi.PF_NS + 1)


def record_words() -> None:
    """Every recorded call also keeps its profile words (io holds the copied ctrl)."""
    add = phases.CallLog.add

    def add_words(self, p, *args, **kwargs) -> None:
        add(self, p, *args, **kwargs)
        if not hasattr(self, "words"):
            self.words = []
            self.longest = []
        self.words.append(p._io_host.array[WORDS].astype(np.uint32).copy())
        self.longest.append(int(p._io_host.array[abi.C_LONGEST]))

    phases.CallLog.add = add_words  # type: ignore[method-assign]


def parts(log: phases.CallLog, sel: np.ndarray) -> dict[str, float]:
    """Means per call (or per visit, pass, barrier) of the calls in ``sel``."""
    w = np.stack(log.words)[sel].astype(np.float64)

    def col(word: int) -> np.ndarray:
        return w[:, word - abi.PF_R_VISITS]

    ghz = col(abi.PF_CYCLES).sum() / max(col(abi.PF_NS).sum(), 1.0)  # cycles a ns
    us = 1e-3 / ghz  # µs a cycle

    def per(word: int, count: int) -> float:
        n = col(count).sum()
        return float(col(word).sum() * us / n) if n else 0.0

    ph = log.phases_us()[sel]
    host = np.asarray(log.host_us, np.float64)[sel]
    rv, av, bn = col(abi.PF_R_VISITS), col(abi.PF_A_VISITS), col(abi.PF_B_N)
    out = {
        "calls": int(sel.sum()),
        "ghz": float(ghz),
        **{f"{p}_us": float(ph[:, i].mean()) for i, p in enumerate(phases.STAMP_PHASES)},
        "device_us": float(ph.sum(axis=1).mean()),
        "wait_us": float(host[:, 1].mean()),
        "chain": float(np.mean(np.asarray(log.longest)[sel])),
        "relax_visits": float(rv.mean()),
        "r_load_us": per(abi.PF_R_LOAD, abi.PF_R_VISITS),
        "r_settle_us": per(abi.PF_R_SETTLE, abi.PF_R_VISITS),
        "r_store_us": per(abi.PF_R_STORE, abi.PF_R_VISITS),
        "r_flag_us": per(abi.PF_R_FLAG, abi.PF_R_VISITS),
        "r_take_us": per(abi.PF_R_TAKE, abi.PF_R_VISITS),
        "idle_passes": float(col(abi.PF_R_IDLE_N).mean()),
        "idle_pass_us": per(abi.PF_R_IDLE, abi.PF_R_IDLE_N),
        "queue_us": float(col(abi.PF_R_QUEUE).sum() / 1e3 / max(col(abi.PF_R_QUEUE_N).sum(), 1)),
        "queued": float(col(abi.PF_R_QUEUE_N).mean()),
        "raise_visits": float(av.mean()),
        "a_take_us_all_blocks": float(col(abi.PF_A_TAKE).mean() * us),
        "a_load_us": per(abi.PF_A_LOAD, abi.PF_A_VISITS),
        "a_fix_us": per(abi.PF_A_FIX, abi.PF_A_VISITS),
        "a_visit_us": per(abi.PF_A_VISIT, abi.PF_A_VISITS),
        "barriers": float(bn.mean()),
        "b_arrive_us": per(abi.PF_B_ARRIVE, abi.PF_B_N),
        "b_wait_us": per(abi.PF_B_WAIT, abi.PF_B_N),
        "b_leave_us": per(abi.PF_B_LEAVE, abi.PF_B_N),
        "b_lag_us": float(col(abi.PF_B_LAG).sum() / 1e3 / max(bn.sum(), 1)),
        "relax_end_lag_us": float(col(abi.PF_T_LAG).mean() / 1e3),
    }
    visit = sum(out[k] for k in ("r_load_us", "r_settle_us", "r_store_us", "r_flag_us"))
    out["r_visit_us"] = visit
    out["link_us"] = out["relax_us"] / out["chain"] if out["chain"] else 0.0
    return out


COLUMNS = (
    *("calls", "device_us", "wait_us", "raise_us", "reset_us", "relax_us", "chain", "link_us"),
    *("relax_visits", "r_take_us", "r_load_us", "r_settle_us", "r_store_us", "r_flag_us"),
    *("r_visit_us", "queue_us", "idle_pass_us", "relax_end_lag_us", "raise_visits"),
    *("a_load_us", "a_fix_us", "a_visit_us", "barriers", "b_arrive_us", "b_wait_us"),
    *("b_leave_us", "b_lag_us"),
)


def main(argv: list[str] | None = None) -> None:
    from sim.benchmark import warm_up
    from sim.scenarios import make_scenario

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default="400")
    ap.add_argument("--scenario", default="explore,streets")
    ap.add_argument("--unknown", type=float, default=0.4)
    ap.add_argument("--modes", default="eds,dss")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    record_words()
    modes = args.modes.split(",")
    warm_up("cuda", "fast", sorted({m.split("-")[0].split(":")[0] for m in modes}))
    rows = []
    print(f"{'walk':>20} " + " ".join(f"{c.removesuffix('_us')[:8]:>8}" for c in COLUMNS))
    for name in args.scenario.split(","):
        for grid in (int(v) for v in args.grid.split(",")):
            scenario = make_scenario(name, grid, args.unknown, 0)
            for mode in modes:
                log = phases.walk_logged(scenario, mode, None)
                cut = np.asarray(log.cut, bool)
                for part, sel in (("all", np.ones(cut.size, bool)), ("cut", cut), ("kept", ~cut)):
                    if part != "all" and not (cut.any() and (~cut).any()):
                        continue  # DSS never cuts over: its "kept" calls are all of them
                    row = {"scenario": name, "grid": grid, "mode": mode, "calls_of": part}
                    row.update(parts(log, sel))
                    rows.append(row)
                    label = f"{name[:6]}:{mode}:{part}"
                    print(f"{label:>20} " + " ".join(f"{row[c]:8.2f}" for c in COLUMNS))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
