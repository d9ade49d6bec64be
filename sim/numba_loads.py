"""Which of the product's numba functions compiled or loaded code: what tells a slow step's
own work from a first use (the harmonic bench's per-step ``loaded``, the warm-up's tests)."""

from __future__ import annotations

import sys

from numba.core.registry import CPUDispatcher


def numba_signatures() -> dict[str, int]:
    """The signatures each numba function of the product (``daemon.*``) holds so far: a call
    that compiles one, or loads it from numba's cache, adds one."""
    out = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith("daemon.") or module is None:
            continue
        for attr, value in vars(module).items():
            if isinstance(value, CPUDispatcher):
                out[f"{name}.{attr}"] = len(value.signatures)
    return out
