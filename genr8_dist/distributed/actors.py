"""The island host: a Ray actor that keeps one or several islands and advances them a generation at a time.

``IslandHost`` is a plain class (testable without Ray); ``remote_host_class()`` wraps it as a Ray actor.
An actor holds each island's latest generation and the configuration versions it was sent, so they are
not sent back and forth: per generation the coordinator sends the generation number, the configuration
version in force (the configuration itself only the first time), the incoming migrants and any injected
individuals, and receives the new generation (genomes, criteria, provenance; never surfaces). A host
that lacks the generation before the one asked for (it was just created to replace a dead actor, or
it adopted an island from one) reads it from the run store: per-generation traffic stays small, and a
restarted actor rebuilds its state from the last commit. Because ``Island.step`` is a pure function of
its inputs, the rebuilt island produces exactly what the lost one would have.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Sequence
from typing import Any

from genr8_dist.evolution.individual import Individual

__all__ = ["IslandHost", "remote_host_class"]


class IslandHost:
    """Hosts islands of one run; ``run_dir`` is where it reads a generation it does not hold."""

    def __init__(self, run_dir: str) -> None:
        self.bind(run_dir)

    def bind(self, run_dir: str) -> None:
        """Serve the run in ``run_dir`` from now on, forgetting everything held of another run."""
        self.run_dir = run_dir
        self._islands: dict[tuple[int, int], Any] = {}
        self._configs: dict[int, Any] = {}
        self._latest: dict[int, tuple[int, list[Individual]]] = {}
        self._store: Any = None

    def ready(self) -> dict[str, Any]:
        """Where this host runs (answers once the actor is scheduled and started)."""
        return {"host": socket.gethostname(), "pid": os.getpid()}

    def _island(self, island: int, config: Any, config_version: int) -> Any:
        from genr8_dist.evolution.island import Island

        if config is not None:
            self._configs[config_version] = config
        key = (island, config_version)
        found = self._islands.get(key)
        if found is None:
            if config_version not in self._configs:
                raise RuntimeError(f"island host was not sent configuration version {config_version}")
            found = Island(self._configs[config_version], island, config_version=config_version)
            self._islands[key] = found
        return found

    def _previous(self, island: int, generation: int) -> list[Individual]:
        held = self._latest.get(island)
        if held is not None and held[0] == generation:
            return held[1]
        if self._store is None:
            from genr8_dist.store import RunStore

            self._store = RunStore.open(self.run_dir)
        return list(self._store.load_generation(island, generation))

    def advance(
        self,
        island: int,
        generation: int,
        config: Any,
        config_version: int,
        migrants: Sequence[Individual] = (),
        injected: Sequence[Any] = (),
    ) -> list[Individual]:
        """Compute ``island``'s ``generation`` (0: the initial population) and keep it as the latest.

        ``config`` is the configuration version ``config_version``; the coordinator sends it once per
        host and version, and ``None`` afterwards (the host keeps it)."""
        model = self._island(island, config, config_version)
        if generation == 0:
            population = list(model.initial())
        else:
            previous = self._previous(island, generation - 1)
            population = list(
                model.step(previous, generation, migrants=tuple(migrants), injected=tuple(injected))
            )
        self._latest[island] = (generation, population)
        return population

    def forget(self, island: int) -> None:
        """Drop what this host holds of ``island`` (it moved to another host)."""
        self._latest.pop(island, None)
        for key in [k for k in self._islands if k[0] == island]:
            del self._islands[key]


def remote_host_class(num_cpus: float) -> Any:
    """``IslandHost`` as a Ray actor class reserving ``num_cpus`` (fractions allowed), spread over the
    cluster's nodes (a lost node takes few islands with it), never restarted by Ray itself: the
    coordinator replaces a dead host and reloads its islands from the store."""
    import ray

    return ray.remote(IslandHost).options(num_cpus=num_cpus, max_restarts=0, max_task_retries=0,
                                         scheduling_strategy="SPREAD")
