"""The kinds of form are told apart by what a person sees: outline, height field, curvature."""

from __future__ import annotations

import types

import numpy as np

from genr8_dist.environment import load_environment
from genr8_dist.hemls import grow, load_system
from genr8_dist.history._search import _farthest, form_descriptors

SHELL = "examples/environments/shell.toml"


def _view(vertices, surface):
    """``surface``'s regions and perimeter on other vertex positions."""
    return types.SimpleNamespace(vertices=vertices, regions=surface.regions,
                                 perimeter=surface.perimeter)


def test_the_descriptors_see_height_and_outline_and_ignore_size_and_position():
    from genr8_dist.environment import Environment

    flat = grow(load_system("four_sided_tiles"), Environment(steps=3)).surface
    shell = grow(load_system("four_sided_tiles"), load_environment(SHELL)).surface
    d_flat, d_shell = form_descriptors(flat), form_descriptors(shell)
    assert d_flat is not None and d_shell is not None and d_flat.shape == d_shell.shape
    heights = slice(24, 24 + 64)
    assert np.abs(d_flat[heights]).max() < 1e-12          # a level sheet: no height anywhere
    assert np.abs(d_shell[heights]).max() > 0.05          # a vault: its crown above its rim
    tilts = slice(88, 94)
    assert d_flat[tilts][0] == 1.0 and d_shell[tilts][0] < 0.9   # level regions vs sloping ones
    # the same form, twice as large and elsewhere: the same descriptors
    moved = _view(shell.vertices * 2.0 + np.array([5.0, -3.0, 1.0]), shell)
    assert np.allclose(form_descriptors(moved), d_shell)
    # a square seen turned 45 degrees has another outline
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    turned = _view(flat.vertices @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]), flat)
    assert np.abs(form_descriptors(turned)[:24] - d_flat[:24]).max() > 0.1


def test_a_phenotype_that_is_not_a_surface_has_no_descriptors():
    assert form_descriptors(None) is None
    assert form_descriptors(types.SimpleNamespace(voxels=np.zeros((2, 2, 2)))) is None


def test_farthest_picks_start_at_the_best_and_never_pick_a_copy():
    x = np.array([[0.0, 0.0], [0.0, 0.0], [0.1, 0.0], [5.0, 0.0], [5.0, 0.0], [0.0, 3.0]])
    assert _farthest(x, 3) == [0, 3, 5]
    assert _farthest(x, 6) == [0, 3, 5, 2]       # the copies (rows 1 and 4) are never kinds
