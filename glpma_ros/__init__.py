"""Real-time forward kinematics of parallel manipulators (3-RPR, 6-6 hexapod) from leg lengths."""
from .runtime.moved import install as _serve_moved_names

#: the package's version (also in package.xml; setup.py reads it from here)
__version__ = "0.3.2"

_serve_moved_names()
