"""The meshing versions: which exist, which new runs use, and the check of a run's choice.

A surface map is cut into triangles by one of several versions of the meshing code
(``genr8_dist.hemls.meshing``); a run records the version it was created with, so an old run's
surfaces stay the same. The versions are declared here, below every layer, so a configuration is
checked (``config.RunConfig``, ``genr8 grow --meshing``, a stored configuration) without loading the
growth code.
"""

from __future__ import annotations

import numpy as np

from genr8_dist.errors import ConfigError

__all__ = ["MESHING", "MESHINGS", "check_meshing"]

MESHINGS = (1, 2, 3, 4, 5, 6, 7, 8)   # every meshing version a surface can be cut with
MESHING = 8         # what new runs (and surfaces grown outside a run) use


def check_meshing(value: object, where: str = "meshing") -> int:
    """``value`` as a meshing version, or a ``ConfigError`` naming ``where`` and the versions."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) not in MESHINGS:
        raise ConfigError(f"{where}: unknown meshing {value!r}; use one of "
                          f"{', '.join(map(str, MESHINGS))}")
    return int(value)
