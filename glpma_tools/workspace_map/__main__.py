"""``python -m glpma_tools.workspace_map``: the same as ``glpma-fk map``."""
import sys

from .cli import main

sys.exit(main())
