"""A run's configuration versions: each in force from a recorded generation, stored as TOML text (a
file, and a copy in the manifest that ``repair`` restores it from), parsed in one place (``config``).
"""

from __future__ import annotations

import copy
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import TYPE_CHECKING

from genr8_dist.errors import ConfigError, StoreError
from genr8_dist.meshings import MESHING, check_meshing
from genr8_dist.store.manifest import Entry, utc_now
from genr8_dist.store.schema import Event
from genr8_dist.store.transactions import Transactions

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.fitness import FitnessSpec

__all__ = ["ConfigVersion", "Configs", "check_toml", "config_meshing", "config_screen", "phenotype_columns"]


@dataclass(frozen=True, slots=True)
class ConfigVersion:
    """One configuration of a run, in force from ``effective_generation`` until the next version's."""

    version: int
    effective_generation: int
    toml: str
    created: datetime


def check_toml(text: str, what: str) -> None:
    if not isinstance(text, str):
        raise ConfigError(f"{what}: a configuration is TOML text, got {type(text).__name__}")
    try:
        tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{what}: not valid TOML: {exc}") from None


def phenotype_columns(config_toml: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The criteria and the sizes a run of ``config_toml`` stores: those of its universe's phenotype,
    or the built-in surface phenotype's when the text is not a run configuration (a bare store)."""
    from genr8_dist.config import RunConfig, run_phenotype
    from genr8_dist.errors import Genr8Error
    from genr8_dist.store.schema import builtin_sizes, criteria_names

    try:
        config = RunConfig.from_toml(config_toml)
    except Genr8Error:
        return criteria_names(), builtin_sizes()
    return tuple(config.fitness.names), tuple(run_phenotype(config.universe_source).sizes)


def config_meshing(config_toml: str) -> int:
    """The meshing a new run of ``config_toml`` records: the one it names, else the current one."""
    try:
        named = tomllib.loads(config_toml).get("meshing")
    except tomllib.TOMLDecodeError:
        return MESHING
    return MESHING if named is None else check_meshing(named, "configuration version 1: meshing")


def config_screen(config_toml: str) -> int:
    """The screen before growth (``ea.screen``) a new run of ``config_toml`` records: the one it
    names, else the current one (checked when the configuration is read)."""
    from genr8_dist.config import SCREEN

    try:
        ea = tomllib.loads(config_toml).get("ea")
    except tomllib.TOMLDecodeError:
        return SCREEN
    named = ea.get("screen") if isinstance(ea, dict) else None
    return named if isinstance(named, int) and not isinstance(named, bool) else SCREEN


class Configs(Transactions):
    """A store's configuration versions."""

    def configs(self) -> list[ConfigVersion]:
        """Every configuration version, oldest first."""
        return [self._config(e) for e in self._m["configs"]]

    def config(self, version: int | ConfigVersion) -> RunConfig:
        """Configuration ``version`` (a number, or one of ``configs()``) as a ``RunConfig``, its fitness
        over the criteria this run stores: the one place a stored configuration is parsed. A
        configuration that no longer validates is a ``ConfigError`` naming the run and the version."""
        cv = version if isinstance(version, ConfigVersion) else self._config_version(version)
        key = (cv.version, cv.toml)
        parsed = self._parsed.get(key)
        if parsed is None:
            from genr8_dist.config import RunConfig

            source = f"{self.path} configuration v{cv.version}"
            parsed = RunConfig.from_toml(cv.toml, source=source, criteria=self.criteria,
                                         meshing=self.meshing, screen=self.screen)
            self._parsed[key] = parsed
        return parsed

    def fitness(self, version: int | ConfigVersion) -> FitnessSpec:
        """The fitness specification of configuration ``version`` alone (what history queries need;
        cheaper than ``config``: no environment or universe is built)."""
        cv = version if isinstance(version, ConfigVersion) else self._config_version(version)
        from genr8_dist.fitness import FitnessSpec

        data = tomllib.loads(cv.toml)
        return FitnessSpec.from_dict(data.get("fitness"), names=self.criteria,
                                     source=f"{self.path} configuration v{cv.version}")

    def _config_version(self, version: int) -> ConfigVersion:
        for e in self._m["configs"]:
            if int(e["version"]) == int(version):
                return self._config(e)
        raise StoreError(f"{self._fs.show()}: no configuration version {version}")

    def config_for(self, generation: int) -> ConfigVersion:
        """The configuration version in force at ``generation``."""
        chosen = None
        for e in self._m["configs"]:
            if e["effective_generation"] <= generation:
                chosen = e
        if chosen is None:
            raise StoreError(f"{self._fs.show()}: no configuration is in force at generation {generation}")
        return self._config(chosen)

    def add_config(self, toml_text: str, effective_generation: int, *, events: Sequence[Event] = ()) -> int:
        """Record a new configuration version in force from ``effective_generation``, atomically with
        ``events`` (e.g. the intervention that made it). Returns the new version number (1-based)."""
        if isinstance(effective_generation, bool) or not isinstance(effective_generation, int):
            raise StoreError(f"effective_generation must be an integer, got {effective_generation!r}")
        last = self._m["configs"][-1]
        if effective_generation < last["effective_generation"]:
            raise StoreError(
                f"effective_generation {effective_generation} is before configuration version "
                f"{last['version']}'s ({last['effective_generation']}); versions take effect in order"
            )
        done = max((int(g) for g in self._m["generations"].values()), default=-1)
        if effective_generation <= done:
            raise StoreError(
                f"effective_generation {effective_generation} is already committed (up to generation "
                f"{done}); an edit takes effect from generation {done + 1} or later"
            )
        version = len(self._m["configs"]) + 1
        check_toml(toml_text, f"configuration version {version}")
        return self._publish_config(toml_text, effective_generation, events)

    def _publish_config(self, toml_text: str, effective_generation: int, events: Sequence[Event]) -> int:
        number = len(self._m["configs"]) + 1
        with self._transaction():
            version = self._next_version()
            data = toml_text.encode()
            entry = self.write_file(f"configs/v{number:04d}", ".toml", data)
            manifest = copy.deepcopy(self._m)
            manifest["configs"].append({
                "version": number,
                "effective_generation": effective_generation,
                **entry,
                "created": utc_now().isoformat(),
                "commit": version,
                "toml": toml_text,  # the copy repair() restores the file from
            })
            self._add_events(manifest, list(events), version)
            self._publish(manifest, version)
        self._config_cache[number] = toml_text
        return number

    def _config(self, entry: Entry) -> ConfigVersion:
        number = entry["version"]
        text = self._config_cache.get(number)
        if text is None:
            problem = self._check_entry(entry, deep=True)
            if problem is not None:
                raise StoreError(f"{problem}; {self._repair_hint()}")
            try:
                text = self._fs.read_bytes(entry["path"]).decode()
            except UnicodeDecodeError:
                raise StoreError(f"{self._fs.show(entry['path'])}: not UTF-8 text") from None
            self._config_cache[number] = text
        return ConfigVersion(number, entry["effective_generation"], text,
                             datetime.fromisoformat(entry["created"]))
