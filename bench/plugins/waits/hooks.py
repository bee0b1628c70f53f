"""Hooks of the ``waits`` universe: a phenotype whose development waits instead of computing.

bench/scale.py runs hundreds of islands on tens of simulated hosts on a small machine: each
individual's development sleeps for a time drawn from ``QUANTILES``, the per-individual evaluation
time distribution of the default universe's default configuration measured once with the real engine
(heavy tail included), so a run measures only the engine's own costs (breeding, traffic, commits,
scheduling). The draw is a function of the text alone (its blake2b digest: the same text waits the
same time everywhere), so rows are the same whatever the scheduling; ``GENR8_WAITS_SCALE`` multiplies
every wait (default 1; 0 waits nothing); ``GENR8_WAITS_LOG`` names a folder where each wait is
logged (``_log``). The fitness is another number drawn from the digest,
independent of the wait, so selection does not drift towards cheap individuals.
"""

from __future__ import annotations

import bisect
import hashlib
import os
import time
from collections.abc import Mapping
from typing import Any

from genr8_dist.fitness import CriterionInfo, criterion_names, register_criterion
from genr8_dist.phenotype import Developed, Phenotype

# (cumulative probability, seconds) of one evaluation (map + develop + measure) of the default
# universe's default configuration: one island of 60, generations 0..4, seeds 1..5, 1,480
# evaluations (mean 0.027 s, median 0.010 s, p99 0.13 s, max 8.9 s; wall seconds on the 2-core
# machine, lightly loaded); evaluations a cache served (0 s) left out: the engine's caches serve them.
QUANTILES: tuple[tuple[float, float], ...] = (
    (0, 6.5e-05), (0.01, 0.001249), (0.02, 0.001395), (0.03, 0.001509), (0.04, 0.001626),
    (0.05, 0.001694), (0.06, 0.001775), (0.07, 0.001865), (0.08, 0.001915), (0.09, 0.001997),
    (0.1, 0.002116), (0.11, 0.002187), (0.12, 0.002246), (0.13, 0.00235), (0.14, 0.002424),
    (0.15, 0.002551), (0.16, 0.002686), (0.17, 0.002782), (0.18, 0.002964), (0.19, 0.003048),
    (0.2, 0.00321), (0.21, 0.003377), (0.22, 0.003534), (0.23, 0.003718), (0.24, 0.004099),
    (0.25, 0.004443), (0.26, 0.004796), (0.27, 0.005106), (0.28, 0.005348), (0.29, 0.005749),
    (0.3, 0.005981), (0.31, 0.006145), (0.32, 0.006329), (0.33, 0.00651), (0.34, 0.006739),
    (0.35, 0.006916), (0.36, 0.00707), (0.37, 0.007197), (0.38, 0.007393), (0.39, 0.007631),
    (0.4, 0.007808), (0.41, 0.008062), (0.42, 0.008479), (0.43, 0.008694), (0.44, 0.008957),
    (0.45, 0.009291), (0.46, 0.009389), (0.47, 0.009728), (0.48, 0.009935), (0.49, 0.010179),
    (0.5, 0.010445), (0.51, 0.010668), (0.52, 0.010847), (0.53, 0.011082), (0.54, 0.011419),
    (0.55, 0.011708), (0.56, 0.011883), (0.57, 0.012101), (0.58, 0.012356), (0.59, 0.012809),
    (0.6, 0.013212), (0.61, 0.013635), (0.62, 0.013897), (0.63, 0.014234), (0.64, 0.014764),
    (0.65, 0.015141), (0.66, 0.015642), (0.67, 0.015921), (0.68, 0.01647), (0.69, 0.016977),
    (0.7, 0.017493), (0.71, 0.018202), (0.72, 0.018696), (0.73, 0.019145), (0.74, 0.019668),
    (0.75, 0.020157), (0.76, 0.020703), (0.77, 0.021232), (0.78, 0.021868), (0.79, 0.022845),
    (0.8, 0.023503), (0.81, 0.024388), (0.82, 0.025504), (0.83, 0.026948), (0.84, 0.028421),
    (0.85, 0.030039), (0.86, 0.031469), (0.87, 0.033118), (0.88, 0.035737), (0.89, 0.037452),
    (0.9, 0.039589), (0.91, 0.042473), (0.92, 0.044938), (0.93, 0.04871), (0.94, 0.052663),
    (0.95, 0.056999), (0.96, 0.064067), (0.97, 0.07421), (0.98, 0.085793), (0.99, 0.1309),
    (0.995, 0.184709), (0.999, 2.32754), (1, 8.88057),
)


def _unit(digest: bytes, k: int) -> float:
    return int.from_bytes(digest[8 * k:8 * k + 8], "little") / 2.0**64


def _draw_wait(text: str, quantiles: tuple[tuple[float, float], ...] = QUANTILES) -> float:
    """The seconds ``text`` waits: the inverse of the measured distribution at a uniform drawn from the
    text's digest (linear between quantiles)."""
    u = _unit(hashlib.blake2b(text.encode(), digest_size=16).digest(), 0)
    probs = [p for p, _ in quantiles]
    k = min(max(bisect.bisect_right(probs, u), 1), len(quantiles) - 1)
    (p0, s0), (p1, s1) = quantiles[k - 1], quantiles[k]
    return s0 + (s1 - s0) * (u - p0) / (p1 - p0) if p1 > p0 else s1


def _log(start: float, end: float, asked: float) -> None:
    """With ``GENR8_WAITS_LOG`` (a folder: bench/scale.py's ``--timeline``), one line per wait in
    this process's file: when it began and ended (epoch seconds) and what it asked for."""
    folder = os.environ.get("GENR8_WAITS_LOG")
    if folder:
        with open(os.path.join(folder, f"{os.getpid()}.txt"), "a", encoding="ascii") as f:
            f.write(f"{start!r} {end!r} {asked!r}\n")


def _scale() -> float:
    """``GENR8_WAITS_SCALE``: the factor applied to every wait."""
    return float(os.environ.get("GENR8_WAITS_SCALE", "1"))


if "score" not in criterion_names("waits"):
    register_criterion(CriterionInfo("score", lambda value, env: value["score"], 0.0, 1.0,
                                     heading="score", phenotype="waits",
                                     description="a number in [0, 1) drawn from the text's digest"))
if "wait" not in criterion_names("waits"):
    register_criterion(CriterionInfo("wait", lambda value, env: value["wait"], 0.0, 0.0,
                                     heading="wait", phenotype="waits",
                                     description="the seconds the development waited (scale 1)"))


class WaitsPhenotype(Phenotype):
    """Development sleeps ``_draw_wait(text) * scale()`` seconds; fitness is the drawn ``score``."""

    name = "waits"
    noun = "wait"
    direction = "minimise"
    capped_is_invalid = False
    stage = "develop"

    def develop(self, text: str, config: Any) -> Developed:
        digest = hashlib.blake2b(text.encode(), digest_size=16).digest()
        wait = _draw_wait(text)
        seconds = wait * _scale()
        if seconds > 0:
            start = time.time()
            time.sleep(seconds)
            _log(start, time.time(), seconds)
        return Developed({"wait": wait, "score": _unit(digest, 1)}, digest.hex())

    def measure(self, developed: Developed, config: Any) -> dict[str, float]:
        names = config.fitness.names if config is not None else self.criteria
        return {name: float(developed.value[name]) for name in names}

    def fitness(self, raw: Mapping[str, float], config: Any) -> float:
        return float(raw["score"])


PHENOTYPE = WaitsPhenotype()
