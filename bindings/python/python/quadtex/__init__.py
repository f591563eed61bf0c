# The package is the extension module `quadtex.quadtex` (Rust, see
# `bindings/python/src`), re-exported, plus pure-Python helpers in
# submodules that are imported only when asked for (`quadtex.dask`, which
# needs the optional `dask` extra). The reference is `__init__.pyi`.
from .quadtex import *  # noqa: F401,F403
from .quadtex import __all__, __doc__, __version__  # noqa: F401
