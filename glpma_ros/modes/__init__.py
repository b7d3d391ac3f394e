"""Every real assembly mode of a set of leg lengths: :mod:`.multistart` (local solves from random
starts with a stopping rule, or the papers' G3-PCX runs; ``solve_all``) and :mod:`.exact` (certified by
msolve)."""
