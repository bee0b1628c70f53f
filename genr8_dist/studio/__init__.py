"""The studio: watch and steer a run from a browser (``genr8 studio RUN``, ``genr8 run ... --studio``).

``data.RunView`` reads what the page shows from the run directory; ``server.Studio`` serves the page
(``static/``, with three.js vendored under ``static/vendor/three``), its data and the designer's
actions, each recorded as ``genr8 edit`` records an intervention. See docs/studio.md.
"""

from __future__ import annotations

from genr8_dist.studio.data import RunView
from genr8_dist.studio.server import Studio, is_loopback

__all__ = ["RunView", "Studio", "is_loopback"]
