"""The trust rule in isolation: consent per code digest, remembered outside any run, the installed
plugin's identical code trusted, anything else refused in one line; stored code never runs unasked."""

from __future__ import annotations

import pickle

import pytest

from genr8_dist.errors import UniverseError
from genr8_dist.grammar import build_universe, discovery, find_source, trust
from genr8_dist.grammar.source import UniverseSource, load_modules


@pytest.fixture
def machine(tmp_path, monkeypatch):
    """A machine that trusts nothing yet."""
    monkeypatch.setenv("GENR8_TRUST_FILE", str(tmp_path / "trusted-hooks"))
    monkeypatch.setattr(trust, "_CONSENTED", set())
    return tmp_path / "trusted-hooks"


def altered(source: UniverseSource, marker: str) -> UniverseSource:
    files = dict(source.files)
    files["hooks.py"] += f"\n# {marker}\n"
    return UniverseSource(source.name, tuple(files.items()), origin="stored in a copied run")


def test_the_installed_plugins_own_code_is_trusted_an_altered_copy_is_not(machine):
    timed, origin = find_source("timed")
    assert origin.startswith("plugin:") and timed.modules == ("hooks",)
    assert discovery.consent_for_history(timed)
    assert build_universe(timed).hooks is not None
    other = altered(timed, "changed")
    assert other.code_digest != timed.code_digest
    assert not discovery.consent_for_history(other)
    with pytest.raises(UniverseError, match=r"refusing to run its Python code \(hooks.py, sha256 "):
        load_modules(other)
    with pytest.raises(UniverseError) as info:
        discovery.consent_for_stored([other], trust_flag=False, command="resume runs/r")
    assert str(info.value) == (
        f"stored in a copied run: universe 'timed' carries Python code (hooks.py, sha256 "
        f"{other.code_digest[:16]}...) that this machine has not trusted; read it (the [stored_universe] "
        "table of the run's configs/*.toml), then run `genr8 resume runs/r --trust-hooks`")
    assert not machine.exists()


def test_trust_hooks_is_remembered_outside_the_run_and_lasts(machine, monkeypatch):
    timed, _ = find_source("timed")
    other = altered(timed, "mine")
    discovery.consent_for_stored([other], trust_flag=True, command="resume r")
    assert machine.read_text().split()[0] == other.code_digest
    monkeypatch.setattr(trust, "_CONSENTED", set())          # a later command on the same machine
    discovery.consent_for_stored([other], trust_flag=False, command="resume r")
    assert trust.may_run(other.code_digest)


def test_consent_travels_with_the_driver_s_pickle_and_never_from_a_file(machine):
    timed, _ = find_source("timed")
    other = altered(timed, "sent")
    assert not trust.may_run(other.code_digest)
    unconsented = pickle.dumps(other)
    trust.consent(other.code_digest)
    consented = pickle.dumps(other)
    trust._CONSENTED.clear()
    pickle.loads(unconsented)
    assert not trust.may_run(other.code_digest)
    pickle.loads(consented)                                  # what a Ray host receives from the driver
    assert trust.may_run(other.code_digest)
    stored = UniverseSource.from_dict(other.to_dict(), "configs/v0001.toml")
    assert stored == other and not stored.origin.startswith("plugin")
