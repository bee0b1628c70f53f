"""What a person sees of a surface, as numbers: outline, height field, curvature."""

from __future__ import annotations

import types
from pathlib import Path

import numpy as np

from genr8_dist.environment import Environment, load_environment
from genr8_dist.forms import form_descriptors
from genr8_dist.hemls import grow, load_system

SHELL = Path(__file__).resolve().parents[1] / "examples" / "environments" / "shell.toml"


def _view(vertices, surface):
    """``surface``'s regions and perimeter on other vertex positions."""
    return types.SimpleNamespace(vertices=vertices, regions=surface.regions,
                                 perimeter=surface.perimeter)


def test_the_descriptors_see_height_and_outline_and_ignore_size_and_position():
    flat = grow(load_system("four_sided_tiles"), Environment(steps=3)).surface
    shell = grow(load_system("four_sided_tiles"), load_environment(SHELL)).surface
    (o_flat, h_flat, c_flat), (_, h_shell, c_shell) = form_descriptors(flat), form_descriptors(shell)
    assert (len(o_flat), len(h_flat), len(c_flat)) == (24, 64, 7)
    assert np.abs(h_flat).max() < 1e-12            # a level sheet: no height anywhere
    assert np.abs(h_shell).max() > 0.05            # a shell: its crown above its rim
    assert c_flat[0] == 1.0 and c_shell[0] < 0.9   # level regions vs sloping ones
    # the same form, twice as large and elsewhere: the same descriptors
    moved = form_descriptors(_view(shell.vertices * 2.0 + np.array([5.0, -3.0, 1.0]), shell))
    assert all(np.allclose(a, b) for a, b in zip(moved, form_descriptors(shell), strict=True))
    # a square seen turned 45 degrees has another outline
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    turned = _view(flat.vertices @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]), flat)
    assert np.abs(form_descriptors(turned)[0] - o_flat).max() > 0.1
    # a hair's move is a hair's change (no bin edge jumps)
    nudged = form_descriptors(_view(shell.vertices + 1e-9, shell))
    assert all(np.abs(a - b).max() < 1e-6 for a, b in zip(nudged, form_descriptors(shell), strict=True))


def test_what_is_not_a_surface_has_no_descriptors_and_the_surface_phenotype_gives_them():
    from genr8_dist.phenotype import SURFACES, Developed, Phenotype

    assert form_descriptors(None) is None
    assert form_descriptors(types.SimpleNamespace(voxels=np.zeros((2, 2, 2)))) is None
    shell = grow(load_system("four_sided_tiles"), load_environment(SHELL)).surface
    looks = SURFACES.looks(Developed(value=shell, digest="x"))
    assert looks is not None and len(looks) == 3
    assert Phenotype.looks(SURFACES, Developed(value=shell, digest="x")) is None   # the default
