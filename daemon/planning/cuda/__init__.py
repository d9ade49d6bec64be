"""EDS and DSS on a CUDA device (CuPy raw kernels in ``kernels/``).

- ``planner.py``: ``CudaPlanner``, the public class; ``variant="fast"`` (tiles relaxed in
  shared memory, served by a resident loop: ``call.py``, ``resident.py``, ``path.py``) or
  ``variant="paper"`` (``paper.py``, Díaz-Toro et al.'s Figure 4 form).
- ``batch.py``: ``step_many``, many planners' walking steps served side by side in one post
  of the device's loop (issue 28: a venue's users on one GPU).
- ``abi.py``: every number host and device exchange, written once; ``kernels/abi.cuh`` is
  generated from it.
- ``device.py``: compilation, pinned host buffers, waiting on a kernel's done word.
- ``errors.py``: the exceptions that mean "the device failed" (importable without cupy).

Nothing here is imported until a cuda planner is asked for: cupy is optional.
"""
