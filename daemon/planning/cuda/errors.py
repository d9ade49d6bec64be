"""The exceptions that mean "the device failed", for the caller that moves a user to the CPU.

Importable without cupy: the navigator asks for them on every machine, and only a machine
with cupy can raise cupy's.
"""

from __future__ import annotations


class DeviceFault(RuntimeError):
    """A device failure raised on purpose by tests (``CudaPlanner.inject_fault``)."""


def device_errors() -> tuple[type[BaseException], ...]:
    """cupy's CUDA runtime and driver errors and its out-of-memory, where cupy imports, and
    ``DeviceFault``. A planner that raised one of these is unusable; its map is not."""
    errors: list[type[BaseException]] = [DeviceFault]
    try:
        import cupy
    except Exception:  # no cupy: only the injected fault can occur
        return tuple(errors)
    errors += [cupy.cuda.runtime.CUDARuntimeError, cupy.cuda.driver.CUDADriverError]
    errors.append(cupy.cuda.memory.OutOfMemoryError)
    return tuple(errors)
