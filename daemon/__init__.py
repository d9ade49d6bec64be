"""The navigation daemon: the service, one user's navigation, planning and guidance."""

from . import numba_cache

numba_cache.install()
