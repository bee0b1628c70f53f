"""The kinds of form: chosen one by one, each the least like those chosen."""

from __future__ import annotations

import numpy as np

from genr8_dist.history._search import _farthest


def test_farthest_picks_start_at_the_best_and_never_pick_a_copy():
    x = np.array([[0.0, 0.0], [0.0, 0.0], [0.1, 0.0], [5.0, 0.0], [5.0, 0.0], [0.0, 3.0]])
    assert _farthest(x, 3) == [0, 3, 5]
    assert _farthest(x, 6) == [0, 3, 5, 2]       # the copies (rows 1 and 4) are never kinds
