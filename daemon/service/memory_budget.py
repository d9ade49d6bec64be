"""The maps' memory budget: what a map cell costs a user, and whether a new map may be taken."""

from __future__ import annotations

BYTES_PER_CELL = 64
"""What one map cell costs a user, all told, for the memory budget: the map keeper's occupancy,
cover and inflation (~8 B), the CPU planner's state (17 B at 2000²), the CUDA planner's host
and device copies, with room for the copies a step makes."""


def map_too_big(
    cells: int | None, others: int, max_map_cells: int, memory_budget_mb: float
) -> str | None:
    """Why a map of ``cells`` cells may not be taken (None: it may): past the per-user cap, or
    past the memory budget with the other users' maps' ``others`` cells (``MapCells.others``)."""
    if cells is None:
        return None  # no header: the decoder says what is wrong with it
    if cells > max_map_cells:
        return f"a map of {cells} cells exceeds max_map_cells {max_map_cells}"
    need_mb = (others + cells) * BYTES_PER_CELL / 2**20
    if need_mb > memory_budget_mb:
        return (
            f"a map of {cells} cells would bring all users' maps to {need_mb:.0f} MB, "
            f"past memory_budget_mb {memory_budget_mb:g}"
        )
    return None
