"""The module names of 0.3 still import, for one release, as the modules at their new names (README,
"Architecture"; glpma_ros/runtime/moved.py)."""
import importlib
import sys
import warnings

import pytest

from glpma_ros.runtime.moved import MOVED


@pytest.mark.parametrize("old", sorted(MOVED))
def test_a_name_of_0_3_imports_the_moved_module_with_a_warning(old):
    sys.modules.pop(old, None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    assert module is importlib.import_module(MOVED[old])
    assert any(issubclass(w.category, DeprecationWarning) and MOVED[old] in str(w.message) for w in caught)
