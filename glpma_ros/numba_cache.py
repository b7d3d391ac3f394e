"""Numba's on-disk cache (``cache=True``), safe when several processes compile at once.

Numba saves a new cache entry of a function by reading the function's index file, taking the
first free data-file number, writing the index, then the data file -- with no lock.  Two
processes that compile two signatures of one function at the same time (a cold cache: the node
and its assembly-modes worker starting together, two ``glpma-fk`` commands, a test process and
the node it starts) can take the same number; the index then names, for one signature, the
machine code of the other, and every later process that loads it fails (``TypeError: can't
unbox array from PyObject into native value``) or runs code compiled for other types.

:func:`install` makes the save hold an exclusive lock (``flock`` on ``<index>.lock`` beside the
index), re-read the index under it, and write the data file before the index entry that names
it: a reader then never finds an entry whose data is another signature's, or not there yet.
Loading is unchanged (it takes no lock: files are replaced atomically).
"""
from __future__ import annotations

import contextlib
import itertools

try:
    import fcntl
except ImportError:            # not POSIX: numba's own behaviour
    fcntl = None

#: suffix of the lock file beside a function's cache index
LOCK_SUFFIX = ".lock"


@contextlib.contextmanager
def _exclusive(path: str):
    with open(path, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def locked_save(self, key, data) -> None:
    """``IndexDataCacheFile.save`` under the lock: the entry's data, then the index naming it."""
    with _exclusive(self._index_path + LOCK_SUFFIX):
        overloads = self._load_index()
        data_name = overloads.get(key)
        if data_name is None:
            taken = set(overloads.values())
            data_name = next(name for name in map(self._data_name, itertools.count(1)) if name not in taken)
        self._save_data(data_name, data)
        if overloads.get(key) != data_name:
            overloads[key] = data_name
            self._save_index(overloads)


#: Numba's own ``IndexDataCacheFile.save`` (None until :func:`install` replaced it)
numba_save = None


def install() -> bool:
    """Patch Numba's cache saving (idempotent); False where it cannot (no ``flock``, or a Numba
    without ``IndexDataCacheFile.save``)."""
    global numba_save
    try:
        from numba.core.caching import IndexDataCacheFile
    except ImportError:
        return False
    if fcntl is None or not hasattr(IndexDataCacheFile, "save"):
        return False
    if IndexDataCacheFile.save is not locked_save:
        numba_save = IndexDataCacheFile.save
        IndexDataCacheFile.save = locked_save
    return True
