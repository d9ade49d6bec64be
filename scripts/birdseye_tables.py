"""Seed 004's Tables III-VI on rendered images, ours beside the paper's.

Usage: PYTHONPATH=. python scripts/birdseye_tables.py [--trials 20] [--json F]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from sim.birdseye_study import KINECT, PAPER, TURN_DEG, trial


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    trials = [trial(s) for s in range(args.trials)]
    spans = [t.span_deg for t in trials if t.span_deg is not None]
    hfov = float(np.degrees(KINECT.hfov))
    bev = np.concatenate([t.bev_ms for t in trials])
    all_s = np.array([t.all_s for t in trials])
    pair_s = np.array([t.pair_s for t in trials])
    rows = {
        "III_view_deg": {"original": round(hfov, 1),
                         "expanded_median": round(float(np.median(spans)), 1) if spans else None,
                         "designed": hfov + 4 * TURN_DEG,
                         "paper": PAPER["view"]},
        "IV_stitch_s": {"all_at_once_median": round(float(np.median(all_s)), 3),
                        "pairwise_median": round(float(np.median(pair_s)), 3),
                        "pairwise_over_all": round(float(np.median(pair_s) / np.median(all_s)), 2),
                        "paper": PAPER["stitch_s"]},
        "V_failure": {"all_at_once": sum(not t.all_ok for t in trials) / len(trials),
                      "pairwise": sum(not t.pair_ok for t in trials) / len(trials),
                      "trials": len(trials), "paper": PAPER["failure"]},
        "VI_bev_ms": {"median": round(float(np.median(bev)), 3),
                      "p99": round(float(np.percentile(bev, 99)), 3),
                      "fps": round(1e3 / float(np.median(bev)), 1),
                      "paper_s": PAPER["bev_s"]},
        "target_seen_share": sum(t.target_seen for t in trials) / len(trials),
    }  # fmt: skip
    print(json.dumps(rows, indent=1))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
