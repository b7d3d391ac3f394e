"""``python -m glpma_tools.calibrate``: the same as ``glpma-fk calibrate``."""
import sys

from .cli import main

sys.exit(main())
