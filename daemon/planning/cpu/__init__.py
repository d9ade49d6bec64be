"""EDS and DSS on the CPU.

- ``fast.py``: the default, Dial's bucket queue compiled with numba (``dial.py``); EDS touches
  only the cells whose cost can change.
- ``paper.py``: Díaz-Toro et al.'s Figure 4 form (``g``, ``pred``, ``incon`` as read-only and
  write-only maps, whole-grid iterations until ``flag_stop``), its twin for comparison.
"""
