"""The pool of island hosts (Ray actors): how many, how much CPU each reserves, and replacing dead ones.

A run uses the CPUs it is given, whatever its island count: the pool starts one host per free CPU
(``max_hosts`` at most), each reserving one CPU (a fraction when the cluster offers less than one), and
deals the islands out round-robin; with ``host_cpus`` N, one host per N free CPUs, each reserving N and
evaluating N genomes at once (``actors``). When islands outnumber CPUs a host holds several; when CPUs
outnumber islands the hosts holding none evaluate genomes of the others' generations (``actors``), so a
4-island run on 16 CPUs evaluates on 16. Every host reserves its CPUs from Ray; a run that asks a cluster
for more CPUs than are free (``cpus``) asks the cluster's autoscaler for them first, so it adds nodes
(cluster/README.md). A run that cannot be scheduled
(no free CPU, or hosts not started within ``timeout`` seconds) is refused with a ``RunError``.

When a host dies (its process or its node), ``replace`` starts a new host when a CPU is free and deals
its islands to it, or else deals them to the surviving hosts; the new host reads their last committed
generation from the run store.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from genr8_dist.errors import RunError

__all__ = ["HostPool", "plan_hosts"]

# Seconds a replacement host may take to start before its islands go to the surviving hosts instead
# (the cluster's free CPUs, read just after a node died, may still count the dead node's).
REPLACE_TIMEOUT = 20.0


@dataclass(frozen=True, slots=True)
class HostPlan:
    """How many hosts to start, the CPUs each reserves and the genomes each evaluates at once."""

    hosts: int
    num_cpus: float
    slots: int = 1


def plan_hosts(n_islands: int, free_cpus: float, max_hosts: int | None = None,
               host_cpus: int = 1) -> HostPlan:
    """``min(free CPUs // host_cpus, max_hosts)`` hosts of ``host_cpus`` CPUs (and slots) each; with
    fewer free CPUs than ``host_cpus``, one host of the free CPUs (a fraction below one free CPU)."""
    if host_cpus < 1:
        raise RunError(f"a host needs at least one CPU, got host_cpus={host_cpus}")
    if n_islands < 1:
        raise RunError(f"a run needs at least one island, got {n_islands}")
    if not free_cpus > 0:
        raise RunError(
            f"the Ray cluster has no free CPU for {n_islands} island(s); "
            "free some, add a node, or give the local Ray more CPUs"
        )
    if free_cpus < host_cpus:   # one host of what is free
        slots = max(1, math.floor(free_cpus))
        return HostPlan(hosts=1, num_cpus=float(slots) if free_cpus >= 1 else float(free_cpus), slots=slots)
    hosts = max(1, math.floor(free_cpus / host_cpus))
    if max_hosts is not None:
        hosts = max(1, min(hosts, max_hosts))
    return HostPlan(hosts=hosts, num_cpus=float(host_cpus), slots=host_cpus)


class HostPool:
    """The live island hosts of one run and which island each holds."""

    def __init__(self, run_dir: str, n_islands: int, *, max_hosts: int | None = None,
                 timeout: float = 60.0, settle: float = 5.0, cpus: int | None = None,
                 host_cpus: int = 1) -> None:
        """``cpus``: the CPUs the run asks a cluster for (``genr8 run --cpus`` with ``--address``):
        when fewer are free, the cluster's autoscaler is asked for them and the pool waits up to
        ``timeout`` seconds for them, then uses what is free (at most ``cpus``). ``host_cpus``: the
        CPUs of one host, which evaluates that many genomes at once (``plan_hosts``)."""
        self.run_dir = run_dir
        self.n_islands = n_islands
        self.timeout = timeout
        free = self._free_cpus(n_islands, settle)
        if cpus is not None:
            if free < cpus:
                free = self._ask_for(cpus, timeout)
            free = min(free, float(cpus))
        self.plan = plan_hosts(n_islands, free, max_hosts, host_cpus)
        self._hosts: list[Any] = []
        self._alive: list[bool] = []
        self.placement: dict[int, int] = {}
        handles = [self._new_host() for _ in range(self.plan.hosts)]
        self._await_ready(handles, what=f"{self.plan.hosts} island host(s)")
        for handle in handles:
            self._hosts.append(handle)
            self._alive.append(True)
        for island in range(n_islands):
            self.placement[island] = island % self.plan.hosts

    @staticmethod
    def _free_cpus(wanted: int, settle: float = 5.0) -> float:
        """The cluster's free CPUs; waits up to ``settle`` seconds while fewer than ``wanted`` (and than
        the cluster has) are free, since the CPUs of hosts killed just before take a moment to return."""
        import ray

        deadline = time.monotonic() + settle
        while True:
            free = float(ray.available_resources().get("CPU", 0.0))
            total = float(ray.cluster_resources().get("CPU", 0.0))
            if free >= min(wanted, math.floor(total)) or time.monotonic() >= deadline:
                return free
            time.sleep(0.1)

    @staticmethod
    def _ask_for(cpus: int, timeout: float) -> float:
        """Ask the cluster's autoscaler for ``cpus`` CPUs (``request_resources``: it adds nodes up to
        its ``max_workers``; a cluster without one ignores it) and wait up to ``timeout`` seconds for
        them to be free; the CPUs free then."""
        import ray

        with contextlib.suppress(Exception):   # no autoscaler (a local Ray): nothing to ask
            from ray.autoscaler.sdk import request_resources

            request_resources(num_cpus=cpus)
        deadline = time.monotonic() + timeout
        while True:
            free = float(ray.available_resources().get("CPU", 0.0))
            if free >= cpus or time.monotonic() >= deadline:
                return free
            time.sleep(1.0)

    def _new_host(self) -> Any:
        from genr8_dist.distributed.actors import remote_host_class

        return remote_host_class(self.plan.num_cpus, self.plan.slots).remote(self.run_dir, self.plan.slots)

    def _await_ready(self, handles: Sequence[Any], *, what: str) -> None:
        import ray

        try:
            ray.get([h.ready.remote() for h in handles], timeout=self.timeout)
        except ray.exceptions.RayActorError as exc:
            for h in handles:
                ray.kill(h, no_restart=True)
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise RunError(
                f"could not start {what}: {first} (if the cluster's token authentication differs from "
                "this machine's, set RAY_AUTH_MODE as the cluster has it); the run was not started"
            ) from None
        except ray.exceptions.GetTimeoutError:
            for h in handles:
                ray.kill(h, no_restart=True)
            total = ray.cluster_resources().get("CPU", 0.0)
            raise RunError(
                f"could not start {what} within {self.timeout:g}s (the cluster has {total:g} CPUs, "
                f"{ray.available_resources().get('CPU', 0.0):g} free); the run was not started"
            ) from None

    def rebind(self, run_dir: str, n_islands: int) -> None:
        """Serve another run with the same hosts (a notebook or a test running several runs in turn)."""
        import ray

        live = [h for h, alive in zip(self._hosts, self._alive, strict=True) if alive]
        ray.get([h.bind.remote(run_dir) for h in live])
        self._hosts, self._alive = live, [True] * len(live)
        self.run_dir, self.n_islands = run_dir, n_islands
        self.placement = {island: island % len(live) for island in range(n_islands)}

    @property
    def size(self) -> int:
        """How many hosts are alive."""
        return sum(self._alive)

    def host_of(self, island: int) -> Any:
        """The actor handle holding ``island``."""
        return self._hosts[self.placement[island]]

    def placement_of(self, island: int) -> int:
        """The number of the host holding ``island``."""
        return self.placement[island]

    def islands_on(self, host: int) -> list[int]:
        """The islands dealt to host number ``host``."""
        return sorted(i for i, h in self.placement.items() if h == host)

    def idle(self, busy: set[int]) -> list[int]:
        """The numbers of the live hosts holding none of the ``busy`` islands (free to help others)."""
        occupied = {self.placement[i] for i in busy}
        return [n for n, alive in enumerate(self._alive) if alive and n not in occupied]

    def handle(self, host: int) -> Any:
        """The actor handle of host number ``host``."""
        return self._hosts[host]

    def helped(self) -> int:
        """Genomes the live hosts have evaluated for other hosts' islands, all runs together."""
        import ray

        return sum(ray.get([h.helped.remote() for h, alive in zip(self._hosts, self._alive, strict=True)
                            if alive]))

    def replace(self, island: int) -> list[int]:
        """The host of ``island`` died: replace it; returns every island that was on it (now moved)."""
        import ray

        dead = self.placement[island]
        moved = self.islands_on(dead)
        if self._alive[dead]:
            self._alive[dead] = False
            ray.kill(self._hosts[dead], no_restart=True)
        target: int | None = None
        if ray.available_resources().get("CPU", 0.0) >= self.plan.num_cpus:
            handle = self._new_host()
            try:
                ray.get(handle.ready.remote(), timeout=min(self.timeout, REPLACE_TIMEOUT))
            except (ray.exceptions.GetTimeoutError, ray.exceptions.RayActorError):
                ray.kill(handle, no_restart=True)
            else:
                self._hosts.append(handle)
                self._alive.append(True)
                target = len(self._hosts) - 1
        survivors = [h for h, alive in enumerate(self._alive) if alive]
        if not survivors:
            raise RunError("every island host died and no CPU is free to start a new one")
        for n, isl in enumerate(moved):
            self.placement[isl] = target if target is not None else survivors[n % len(survivors)]
        return moved

    def shutdown(self) -> None:
        """Stop every host this pool started."""
        import ray

        for handle, alive in zip(self._hosts, self._alive, strict=True):
            if alive:
                ray.kill(handle, no_restart=True)
        self._alive = [False] * len(self._alive)
