"""The compiled code's runtime: :mod:`.numba_cache` (Numba's on-disk cache, locked and stamped),
:mod:`.precompile` (compile or load ahead of time), :mod:`.compat` (the numba floor),
:mod:`.collector` (Python's garbage collector held off while a solve runs under a deadline)."""
