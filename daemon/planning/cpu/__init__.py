"""EDS, DSS and A* on the CPU.

- ``fast.py``: the default, compiled with numba: DSS is Dijkstra with Dial's bucket queue
  (``dial.py``); EDS repairs only what the user's path needs, in LPA*/D* Lite's key order
  (``repair.py``), and leaves the rest queued.
- ``paper.py``: Díaz-Toro et al.'s Figure 4 form (``g``, ``pred``, ``incon`` as read-only and
  write-only maps, whole-grid iterations until ``flag_stop``), its twin for comparison.
- ``astar.py``: Ghoniem et al.'s A* from the user's cell at every step (``astar_kernels.py``).
"""
