"""Stand-ins for cupy and the mapped buffers: the cuda backend's host side without a GPU.

``CudaPlanner``'s host code (the mailbox, the post and the wait, the result words, the path's
read-back) can then run as it is on a machine without a GPU, against a device played by
Python: ``test_host_protocol.py`` checks the host's half of the protocol against a model of
the kernels. The ``cuda`` fixture imports the cuda modules afresh over the stand-in cupy, with
``device.Pinned`` replaced by ``HostPinned``, and removes them again after the test.
"""

from __future__ import annotations

import importlib
import sys
from types import SimpleNamespace
from unittest import mock

import numpy as np
import pytest

STANDIN_FREE = ("daemon.planning.cuda.abi", "daemon.planning.cuda.errors")
"""cuda modules that do not import cupy: imported once, never over the stand-in."""

NOT_READY = 600  # cudaErrorNotReady: what streamQuery says of a loop that is still running


class DeviceArray(np.ndarray):
    """A numpy array with cupy's two transfer methods: the planner's "device" arrays."""

    def set(self, host: np.ndarray) -> None:
        self[...] = host

    def get(self) -> np.ndarray:
        return np.array(self)


def standin_cupy() -> mock.MagicMock:
    """cupy for the host code: arrays are ``DeviceArray``s, launches and streams do nothing
    (a ``MagicMock`` answers them), and a started stream never finishes on its own."""
    cp = mock.MagicMock(name="cupy")
    cp.ndarray = np.ndarray
    cp.zeros = lambda n, dtype=np.float64: np.zeros(n, dtype=dtype).view(DeviceArray)
    cp.full = lambda n, value, dtype=None: np.full(n, value, dtype=dtype).view(DeviceArray)
    cp.cuda.runtime.streamQuery = lambda ptr: NOT_READY
    return cp


class HostPinned:
    """``device.Pinned`` in ordinary host memory: it grows as Pinned does (doubling,
    zeroed, a new array when it moves) and its copies to and from the device do nothing (the
    stand-in device reads and writes the host buffers themselves)."""

    def __init__(self, count: int, dtype: type = np.int32, *, mapped: bool = False) -> None:
        self.dtype, self.mapped = np.dtype(dtype), mapped
        self.count, self.device_ptr, self.memory = 0, 0, None
        self.array = np.empty(0, dtype=self.dtype)
        self.view = memoryview(self.array)
        self.reserve(count)

    def reserve(self, count: int) -> bool:
        if count <= self.count:
            return False
        self.count = max(count, 2 * self.count)
        self.array = np.zeros(self.count, dtype=self.dtype)
        self.view = memoryview(self.array)
        return True

    def to_device(self, dst: object, count: int, offset: int = 0) -> None:
        pass

    def from_device(self, src: object, count: int, offset: int = 0) -> None:
        pass


@pytest.fixture
def cuda(monkeypatch):
    """The cuda modules imported afresh over the stand-in cupy, and removed again after."""
    prefix = "daemon.planning.cuda."

    def over_cupy() -> list[str]:
        return [n for n in sys.modules if n.startswith(prefix) and n not in STANDIN_FREE]

    for name in over_cupy():
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "cupy", standin_cupy())
    device = importlib.import_module("daemon.planning.cuda.device")
    monkeypatch.setattr(device, "Pinned", HostPinned)
    mods = SimpleNamespace(
        device=device,
        resident=importlib.import_module("daemon.planning.cuda.resident"),
        planner=importlib.import_module("daemon.planning.cuda.planner"),
    )
    yield mods
    mods.resident._ACTIVE = None
    package = sys.modules["daemon.planning.cuda"]
    for name in over_cupy():
        del sys.modules[name]
        if hasattr(package, name.rsplit(".", 1)[1]):
            delattr(package, name.rsplit(".", 1)[1])
