"""Numba's on-disk cache, stamped with every source file a compiled function is built from.

Numba stamps a cached function with the contents of its own file only (numba 0.68,
``caching._SourceFileBackedLocatorMixin.get_source_stamp``), but a jitted function that calls
the jitted functions of another module compiles their code into its own. Edit only
``cpu/repair_queue.py`` and ``cpu/repair.step`` kept running the old queue from the cache
until ``__pycache__`` was cleared: after an upgrade, a daemon could have run compiled code that
no longer matched its source. The locators here stamp a function with the files of every
jitted function (and module of this project) it reaches, transitively, so a stale entry is
never loaded; numba then compiles afresh and overwrites it.

``install()`` puts them first in numba's ``CACHE_LOCATOR_CLASSES`` (unless the environment
chose locators itself); ``daemon/__init__.py`` calls it, so it is in place before any module
of the daemon, the simulator or the mapper compiles (they all import the daemon first or
define only self-contained jitted functions).
"""

from __future__ import annotations

import hashlib
import inspect
import types
from pathlib import Path

from numba.core import caching, config
from numba.core.dispatcher import Dispatcher

PROJECT_ROOT = Path(__file__).resolve().parents[1]
"""Modules under this folder are followed; numpy and numba themselves are not."""


def _names(code: types.CodeType) -> set[str]:
    """Every global name ``code`` and the code objects nested in it may read."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _names(const)
    return names


def _ours(module: types.ModuleType) -> str | None:
    file = getattr(module, "__file__", None)
    if file is None or not Path(file).resolve().is_relative_to(PROJECT_ROOT):
        return None
    return file


def source_files(py_func: types.FunctionType) -> list[str]:
    """The files whose code ``py_func`` compiles into itself: its own, those of the jitted
    functions it calls (through their names, modules or closures), and theirs in turn."""
    files: set[str] = set()
    seen: set[int] = set()
    stack: list[object] = [py_func]
    while stack:
        func = stack.pop()
        if id(func) in seen or not isinstance(func, types.FunctionType):
            continue
        seen.add(id(func))
        files.add(inspect.getfile(func))
        found = [func.__globals__.get(name) for name in _names(func.__code__)]
        found += [cell.cell_contents for cell in func.__closure__ or ()]
        for obj in found:
            if isinstance(obj, Dispatcher):
                stack.append(obj.py_func)
            elif isinstance(obj, types.ModuleType) and (file := _ours(obj)) is not None:
                files.add(file)
                stack += [d.py_func for d in vars(obj).values() if isinstance(d, Dispatcher)]
    return sorted(files)


class _StampedByDependencies:
    """Mixin over numba's source-file locators: the stamp hashes every file in
    ``source_files``, its own first, where numba hashes only its own."""

    _py_file: str

    def __init__(self, py_func: types.FunctionType, py_file: str) -> None:
        super().__init__(py_func, py_file)  # type: ignore[call-arg]
        self._py_func = py_func

    def get_source_stamp(self) -> bytes:
        digest = hashlib.sha256()
        for path in [self._py_file, *source_files(self._py_func)]:
            digest.update(path.encode())
            digest.update(Path(path).read_bytes())
        return digest.digest()


class UserDirLocator(_StampedByDependencies, caching.UserProvidedCacheLocator):
    """``NUMBA_CACHE_DIR`` set (the systemd unit's ``/var/cache/guidebelt``)."""


class InTreeLocator(_StampedByDependencies, caching.InTreeCacheLocator):
    """The default: ``__pycache__`` beside the source."""


def install() -> None:
    """Use the locators above first, numba's own for what they do not cover."""
    if config.CACHE_LOCATOR_CLASSES:
        return  # chosen by the environment (NUMBA_CACHE_LOCATOR_CLASSES): leave it
    ours = [f"{__name__}.{cls.__name__}" for cls in (UserDirLocator, InTreeLocator)]
    theirs = ["UserWideCacheLocator", "IPythonCacheLocator", "ZipCacheLocator"]
    config.CACHE_LOCATOR_CLASSES = ",".join(ours + theirs)
