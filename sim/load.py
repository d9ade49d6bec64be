"""Many users at once against a real daemon: the delta→belt latency each user feels, and
whether overload is reported as overload.

The load generator (``sim.load_generator``, one process, one zenoh session) plays ``users``
wearers against ``guidebelt run`` (another process): each has its own map (walls around a
``grid``² courtyard), a goal at the top and stands at the bottom, sends a fresh pose at
``pose_hz`` and a map delta at ``delta_hz`` that drops or lifts a small obstacle on the way
(so every delta changes the path). It records when each delta was sent and when the first belt
pattern decided on a map that holds it arrived (each pattern names the last delta its step had
applied, ``map_seq``), and every status.

Poses are always fresh here, so every ``stale_pose`` a user gets is a false safety signal;
users the daemon cannot serve must hear ``overloaded`` instead.
"""

from __future__ import annotations

import json
import os
import time
from collections import Counter
from pathlib import Path

import numpy as np

from protocol import session as wire
from protocol import topics as T
from protocol.messages import StatusCode

from .load_generator import LoadGenerator, LoadSpec, UserTrace

__all__ = ["LoadGenerator", "LoadSpec", "run_against_daemon", "summarise", "user_latencies"]


def user_latencies(trace: UserTrace) -> tuple[list[float], int]:
    """Delta→belt latency (ms) of each measured delta, and how many got no answer.

    Delta i is answered by the first belt pattern whose ``map_seq`` ≥ i: the pattern names the
    map it was decided on, so this is exact when the daemon coalesced several deltas into one
    step and whatever became of the step's path (latest-wins: zenoh drops paths under load,
    and pairing through them made a delta read one delta period late)."""
    if not trace.belts:
        measured = [s for s in trace.sends if s >= trace.first_measured]
        return [], len(measured)
    belts = np.array(sorted(trace.belts), dtype=np.int64)
    # The newest map seen up to each pattern (a pattern after a resync may name an older
    # map); searchsorted needs it non-decreasing.
    seen = np.maximum.accumulate(belts[:, 1])
    lat, unanswered = [], 0
    for i, sent in trace.sends.items():
        if i < trace.first_measured:
            continue
        k = int(np.searchsorted(seen, i))
        if k >= len(belts):
            unanswered += 1
            continue
        lat.append((belts[k, 0] - sent) / 1e6)
    return lat, unanswered


def summarise(gen: LoadGenerator, cpu: dict[str, float] | None = None) -> dict:
    """Latency over the users the daemon served, who was shed, and every false signal."""
    overloaded_users = [
        u for u, t in gen.traces.items() if t.codes.get(StatusCode.OVERLOADED.value, 0)
    ]
    served, all_lat, unanswered = [], [], 0
    stale = sum(t.codes.get(StatusCode.STALE_POSE.value, 0) for t in gen.traces.values())
    for u, trace in gen.traces.items():
        if u in overloaded_users:
            continue
        lat, missed = user_latencies(trace)
        served.append(u)
        all_lat.extend(lat)
        unanswered += missed
    lat = np.array(all_lat) if all_lat else np.zeros(1)
    codes: Counter = Counter()
    for t in gen.traces.values():
        codes.update(t.codes)
    spec = gen.spec
    return {
        "users": spec.users,
        "grid": spec.grid,
        "pose_hz": spec.pose_hz,
        "delta_hz": spec.delta_hz,
        "seconds": spec.seconds,
        "served": len(served),
        "overloaded": len(overloaded_users),
        "deltas_measured": len(all_lat),
        "unanswered": unanswered,
        "p50_ms": round(float(np.percentile(lat, 50)), 2),
        "p99_ms": round(float(np.percentile(lat, 99)), 2),
        "max_ms": round(float(lat.max()), 2),
        "false_stale_pose": int(stale),
        "status_codes": {k: v for k, v in sorted(codes.items())},
        **(cpu or {}),
        "machine": f"{os.cpu_count()} CPUs",
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
    }


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (from /proc)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def tree_cpu_seconds(pid: int) -> float:
    """``cpu_seconds`` of a process and its live children (a daemon's worker processes)."""
    total = cpu_seconds(pid)
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            if int(fields[1]) == pid:
                total += cpu_seconds(int(entry))
        except (OSError, ValueError, IndexError):  # gone meanwhile
            continue
    return total


def _deployment(spec: LoadSpec, port: int, root: Path) -> tuple[dict, wire.ZenohSettings]:
    """As shipped: certificates for every load user and the simulator, the daemon on a
    ``tls/`` port with the access rules (its config file); the generator is the simulator."""
    from protocol.deployment import certify
    from protocol.settings import load_node_settings

    names = [f"load{i:03d}" for i in range(spec.users)]
    certify(root, names, [T.Role.SIM])
    env = {
        "GUIDEBELT_CONFIG": str(root / "daemon.toml"),
        "GUIDEBELT_ZENOH__LISTEN": json.dumps([f"tls/127.0.0.1:{port}"]),
    }
    sim = load_node_settings(root / "sim.toml")
    return env, sim.model_copy(update={"connect": [f"tls/127.0.0.1:{port}"]})


def run_against_daemon(
    spec: LoadSpec, backend: str = "cpu", env: dict | None = None, tls: bool = False
) -> dict:
    """Start ``guidebelt run`` as its own process on a free loopback port, load it, stop it.

    ``env`` adds ``GUIDEBELT_…`` settings (e.g. a smaller step budget) to the daemon's;
    ``tls``: mutual TLS and access rules, as the shipped config."""
    import json
    import shutil
    import signal
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from daemon.service.embedded import free_port
    from protocol.settings import loopback

    root = Path(__file__).resolve().parents[1]
    port = free_port()
    daemon_env = {
        **os.environ,
        "PYTHONPATH": str(root),
        "GUIDEBELT_CONFIG": "",
        "GUIDEBELT_ZENOH__LISTEN": json.dumps([f"tcp/127.0.0.1:{port}"]),
        "GUIDEBELT_BACKEND": backend,
        "GUIDEBELT_CELL_M": str(10.0 / spec.grid),
        "GUIDEBELT_MAX_USERS": str(max(spec.users, 16)),
        "GUIDEBELT_LOG_LEVEL": "WARNING",
        # The daemon keeps its state as in production, in a database of its own for this run:
        # never the system's /var/lib/guidebelt, nothing restored from an earlier run.
        "GUIDEBELT_STATE_DIR": (state := tempfile.mkdtemp(prefix="guidebelt-load-")),
        **(env or {}),
    }
    settings = loopback(connect_port=port)
    if tls:
        tls_env, settings = _deployment(spec, port, Path(state) / "tls")
        daemon_env.update(tls_env)
    daemon = subprocess.Popen([sys.executable, "-m", "cli.app", "run"], cwd=root, env=daemon_env)
    session = gen = None
    try:
        session = wire.open_session(settings)
        deadline = time.monotonic() + 60
        while not wire.alive(session, T.ALIVE, timeout=0.5):
            if daemon.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("the daemon did not come up")
            time.sleep(0.2)
        gen = LoadGenerator(session, spec)
        time.sleep(0.3)  # subscriptions meet the daemon's publishers
        cpu0, t0 = tree_cpu_seconds(daemon.pid), time.monotonic()
        own0 = time.process_time()
        gen.run()
        took = time.monotonic() - t0
        cores = (tree_cpu_seconds(daemon.pid) - cpu0) / took
        extra = {
            "daemon_cores": round(cores, 2),
            "generator_cores": round((time.process_time() - own0) / took, 2),
        }
        result = summarise(gen, extra)
        # CPU, not wall clock: on a shared machine this is what one served user costs.
        served_s = max(result["served"], 1) * took
        result["daemon_cpu_ms_per_served_user_s"] = round(cores * took * 1e3 / served_s, 2)
        return result
    finally:
        if gen is not None:
            gen.close()
        if session is not None:
            session.close()
        daemon.send_signal(signal.SIGTERM)
        try:
            daemon.wait(10)
        except subprocess.TimeoutExpired:
            daemon.kill()
            daemon.wait(5)
        shutil.rmtree(state, ignore_errors=True)
