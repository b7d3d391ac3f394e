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

Numba also keys a cache entry on the source of the function's own file only, while a compiled
function carries the machine code of the kernels it calls from other files (``population_fitness``
in ``models/kernels.py`` inlines the residuals of ``models/residuals.py``; every solver's loop inlines
``population_fitness``).  A change to ``residuals.py`` alone would leave the solvers' cached code
computing the old residuals.  :func:`install` therefore adds to the source stamp of every function of
this package a digest of the sources of all its compiled modules (:func:`package_digest`): any change
to a kernel recompiles them all (``glpma-fk precompile``).  It must run before the first compiled
function of the package is defined (``models/__init__.py``, the entry to the
compiled modules, calls it first).
"""
from __future__ import annotations

import contextlib
import hashlib
import itertools
from pathlib import Path

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
#: Numba's own ``get_source_stamp`` of file-backed functions (None until :func:`install` replaced it)
numba_stamp = None
#: the package whose compiled functions share the digest
PACKAGE_DIR = Path(__file__).resolve().parent.parent
#: a module is compiled when its source has this (Numba's decorator)
COMPILED_MARK = "njit"
_digest = None


def package_digest() -> str:
    """SHA-1 of the sources of the package's compiled modules (path and content, in path order)."""
    global _digest
    if _digest is None:
        h = hashlib.sha1()
        for path in sorted(PACKAGE_DIR.rglob("*.py")):
            text = path.read_bytes()
            if COMPILED_MARK.encode() in text:
                h.update(str(path.relative_to(PACKAGE_DIR)).encode() + b"\0" + text + b"\0")
        _digest = h.hexdigest()
    return _digest


def stamp_with_package(self):
    """Numba's source stamp, with :func:`package_digest` for the functions of this package."""
    own = numba_stamp(self)
    try:
        inside = Path(self._py_file).resolve().is_relative_to(PACKAGE_DIR)
    except (AttributeError, OSError, TypeError):
        inside = False
    return (own, package_digest()) if inside else own


def install() -> bool:
    """Patch Numba's cache saving and source stamps (idempotent); False where it cannot patch the saving
    (no ``flock``, or a Numba without ``IndexDataCacheFile.save``)."""
    global numba_save, numba_stamp
    try:
        from numba.core.caching import IndexDataCacheFile, _SourceFileBackedLocatorMixin  # internals: may be absent
    except ImportError:
        return False
    if _SourceFileBackedLocatorMixin.get_source_stamp is not stamp_with_package:
        numba_stamp = _SourceFileBackedLocatorMixin.get_source_stamp
        _SourceFileBackedLocatorMixin.get_source_stamp = stamp_with_package
    if fcntl is None or not hasattr(IndexDataCacheFile, "save"):
        return False
    if IndexDataCacheFile.save is not locked_save:
        numba_save = IndexDataCacheFile.save
        IndexDataCacheFile.save = locked_save
    return True
