"""Numba's cache when two processes save entries of one function at once (glpma_ros.runtime.numba_cache).

Two cache-file objects on one directory (as two processes have) save two signatures' entries,
with hooks on the steps of the save forcing the order that corrupts Numba's unlocked save: both
read the index before either writes it, A's index is written before B's, B's data before A's.
The index then names, for B's signature, A's machine code (a later process loading it fails with
"can't unbox array" or runs code compiled for other types).  With the lock, B waits for A (the
hooks' waits time out: that order cannot happen) and both entries hold their own data."""
import threading

import pytest

pytest.importorskip("fcntl")

from numba.core.caching import IndexDataCacheFile

from glpma_ros.runtime import numba_cache

#: how long a hook waits for the other save's step (with the lock, the wait runs out)
HOOK_WAIT_S = 1.0
KEY_A, KEY_B = ("signature A",), ("signature B",)


def _cache_file(cache_dir):
    return IndexDataCacheFile(cache_path=str(cache_dir), filename_base="f-1.py311", source_stamp=(1.0, 10))


def _save_both_in_the_corrupting_order(cache_dir, save):
    a, b = _cache_file(cache_dir), _cache_file(cache_dir)
    b_loaded, a_indexed, b_saved = threading.Event(), threading.Event(), threading.Event()
    a_load, a_index, a_data = a._load_index, a._save_index, a._save_data
    b_load, b_index, b_data = b._load_index, b._save_index, b._save_data

    def a_load_hook():
        overloads = a_load()
        b_loaded.wait(HOOK_WAIT_S)           # B reads the index too before A writes it
        return overloads

    def a_index_hook(overloads):
        a_index(overloads)
        a_indexed.set()

    def a_data_hook(name, data):
        b_saved.wait(HOOK_WAIT_S)            # B's data is written first
        a_data(name, data)

    def b_load_hook():
        overloads = b_load()
        b_loaded.set()
        return overloads

    def b_index_hook(overloads):
        a_indexed.wait(HOOK_WAIT_S)          # B's index is written after A's
        b_index(overloads)

    def b_data_hook(name, data):
        b_data(name, data)
        b_saved.set()

    a._load_index, a._save_index, a._save_data = a_load_hook, a_index_hook, a_data_hook
    b._load_index, b._save_index, b._save_data = b_load_hook, b_index_hook, b_data_hook
    threads = [threading.Thread(target=save, args=(a, KEY_A, "code of A")),
               threading.Thread(target=save, args=(b, KEY_B, "code of B"))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not any(t.is_alive() for t in threads)
    return _cache_file(cache_dir)


def test_numbas_own_save_is_corrupted_by_this_order(tmp_path):
    """The hooks reproduce the bug (else the next test could pass for nothing)."""
    assert numba_cache.install() and numba_cache.numba_save is not None
    reader = _save_both_in_the_corrupting_order(tmp_path, numba_cache.numba_save)
    assert reader.load(KEY_B) == "code of A"


def test_the_locked_save_keeps_every_entry_right(tmp_path):
    assert numba_cache.install()
    assert IndexDataCacheFile.save is numba_cache.locked_save
    reader = _save_both_in_the_corrupting_order(tmp_path, IndexDataCacheFile.save)
    assert reader.load(KEY_A) == "code of A" and reader.load(KEY_B) == "code of B"
    # and an entry saved again keeps its data file
    names = dict(reader._load_index())
    _cache_file(tmp_path).save(KEY_A, "code of A, again")
    assert dict(reader._load_index()) == names and reader.load(KEY_A) == "code of A, again"


def test_every_process_using_the_models_saves_with_the_lock():
    """Whatever compiles needs a model: importing glpma_ros.models installs the lock."""
    import subprocess
    import sys

    from conftest import ROOT
    check = ("import glpma_ros.models; from numba.core.caching import IndexDataCacheFile as F; "
             "from glpma_ros import numba_cache; assert F.save is numba_cache.locked_save")
    p = subprocess.run([sys.executable, "-c", check], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
