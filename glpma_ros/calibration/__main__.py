"""``python -m glpma_ros.calibration``: the same as ``glpma-fk calibrate``."""
import sys

from .cli import main

sys.exit(main())
