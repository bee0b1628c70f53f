"""Opening a run for reading, and the small facts every history query needs (criteria, targets)."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias, cast

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as pads

from genr8_dist.errors import ConfigError, HistoryError, StoreError
from genr8_dist.evolution.individual import parse_id
from genr8_dist.files import is_stream, replacing
from genr8_dist.store.schema import criterion_of

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.phenotype import Phenotype
    from genr8_dist.store import RunStore

__all__ = [
    "HistoryError",
    "RunLike",
    "atomic_write",
    "config_of",
    "criteria_of",
    "open_run",
    "parse_id",
    "phenotype_for",
    "targets_by_version",
    "write_table",
]

#: a run directory (str / PathLike / URI) or an open ``RunStore``
RunLike: TypeAlias = "str | os.PathLike[str] | RunStore"


def _label(run: RunLike) -> str:
    for attr in ("path", "root", "uri"):
        value = getattr(run, attr, None)
        if value is not None:
            return str(value)
    return str(run)


def open_run(run: RunLike) -> RunStore:
    """The ``RunStore`` for ``run`` (a directory, a URI, or an already open store, returned as is).

    A local directory that does not exist is a ``StoreError`` naming it, before the store is asked.
    """
    if not isinstance(run, (str, os.PathLike)):
        return run
    text = os.fspath(run)
    if "://" not in text and not Path(text).is_dir():
        raise StoreError(f"{text}: no such run directory")
    from genr8_dist.store import RunStore

    return RunStore.open(text)


def dataset(store: RunStore, generations: tuple[int, int] | None = None) -> pads.Dataset:
    """The committed individuals of ``store`` (only the files holding ``generations=(lo, hi)``, when
    given) as a dataset; a run with none is a ``StoreError``."""
    data = store.dataset() if generations is None else store.dataset(generations)
    if next(iter(data.get_fragments()), None) is None:
        if generations is not None and store.committed_generations():
            lo, hi = generations
            raise HistoryError(f"{_label(store)}: no committed generation in {lo}..{hi}"
                               if lo != hi else f"{_label(store)}: generation {lo} is not committed")
        raise StoreError(f"{_label(store)}: the run has no committed generation yet")
    return data


def run_label(store: RunStore) -> str:
    """A short name for ``store`` in messages (its path)."""
    return _label(store)


def criteria_of(schema: pa.Schema) -> list[str]:
    """The criterion names a run records, in column order (``crit_size`` -> ``size``)."""
    return [c for name in schema.names if (c := criterion_of(name)) is not None]


def targets_by_version(store: RunStore, criteria: list[str]) -> dict[int, dict[str, tuple[float, float]]]:
    """For every configuration version: ``{criterion: (target, unit)}``, the deviation a criterion's
    raw value is judged by (``|raw - target| / unit``, the fitness's own normalisation, unweighted)."""
    out: dict[int, dict[str, tuple[float, float]]] = {}
    for version in store.configs():
        spec = store.fitness(version)
        out[int(version.version)] = {
            name: (spec[name].target, spec[name].unit) for name in criteria if name in spec.names}
    return out


def deviation(values: np.ndarray, versions: np.ndarray, criterion: str,
              targets: dict[int, dict[str, tuple[float, float]]]) -> np.ndarray:
    """``|raw - target| / unit`` per row, the target taken from each row's configuration version; NaN
    raw values (and versions without the criterion) give ``inf`` so they never rank first."""
    known = [v for v, table in targets.items() if criterion in table and v >= 0]
    size = max([*known, int(versions.max()) if len(versions) else 0, 0]) + 1
    target = np.full(size, np.nan)
    unit = np.ones(size)
    for v in known:
        target[v], unit[v] = targets[v][criterion]
    rows = np.clip(versions, 0, size - 1)
    with np.errstate(invalid="ignore"):
        dev = np.abs(values - target[rows]) / unit[rows]
    dev[~np.isfinite(dev) | (versions < 0)] = np.inf
    return cast(np.ndarray, dev)


def as_numpy(column: pa.ChunkedArray | pa.Array, fill: float = math.nan) -> np.ndarray:
    """A numeric Arrow column as a numpy array, nulls replaced by ``fill``."""
    if column.null_count:
        column = pc.fill_null(column, fill)
    return cast(np.ndarray, column.to_numpy())


def run_directory_holding(path: str | os.PathLike[str]) -> Path | None:
    """The run directory ``path`` lies in (itself or a folder above it holding ``_manifest/``), or None."""
    if is_stream(path):
        return None
    here = Path(os.path.realpath(path))
    for folder in (here, *here.parents):
        if (folder / "_manifest").is_dir():
            return folder
    return None


def atomic_write(path: str | os.PathLike[str], write: Any) -> None:
    """Call ``write(tmp_path)`` then rename the temporary file onto ``path``: a reader never sees half
    a file, and a failure leaves ``path`` as it was. The folder must exist, and must not be inside a
    run directory: the history commands only read runs (a file written there could replace one the
    run is made of). ``-``, a device, a FIFO and a symlink are written as ``files.replacing`` says."""
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if not is_stream(path) and not folder.is_dir():
        raise FileNotFoundError(2, "no such directory", str(folder))
    inside = run_directory_holding(target)
    if inside is not None:
        raise HistoryError(f"{path}: is inside the run directory {inside}; the history commands never "
                           "write into a run: choose a path outside it")
    with replacing(target) as tmp:
        write(str(tmp))


def write_table(table: pa.Table, path: str | os.PathLike[str], format: str | None = None) -> None:
    """Write ``table`` as CSV or Parquet (``format``, else from the suffix; CSV by default)."""
    fmt = format or ("parquet" if str(path).endswith((".parquet", ".pq")) else "csv")
    if fmt == "parquet":
        import pyarrow.parquet as pq

        atomic_write(path, lambda tmp: pq.write_table(table, tmp))
    elif fmt == "csv":
        import pyarrow.csv as pcsv

        flat = table
        for n, field in enumerate(table.schema):
            if pa.types.is_list(field.type) or pa.types.is_large_list(field.type):
                values = [None if v is None else " ".join(str(x) for x in v)
                          for v in table.column(n).to_pylist()]
                flat = flat.set_column(n, field.name, pa.array(values, pa.string()))
        atomic_write(path, lambda tmp: pcsv.write_csv(flat, tmp))
    else:
        raise HistoryError(f"format {fmt!r}: write csv or parquet")


def config_of(store: RunStore, version: int) -> RunConfig:
    """The ``RunConfig`` of configuration ``version`` of ``store``."""
    if int(version) not in {int(cv.version) for cv in store.configs()}:
        raise HistoryError(f"{run_label(store)}: no configuration version {version}")
    try:
        return store.config(int(version))
    except ConfigError as exc:
        raise HistoryError(str(exc)) from None


def phenotype_for(store: RunStore, config: RunConfig) -> Phenotype:
    """The phenotype of ``config``'s universe (a configuration of ``store``).

    History runs no stored code (:mod:`genr8_dist.grammar.trust`) but the code of an installed plugin
    with the same digest, or one this machine remembers, is the user's own: a phenotype plugin's
    individuals are regrown with it. A run whose criteria are the surface criteria regrows surfaces
    without running any code; any other run whose code may not run is a ``HistoryError``."""
    from genr8_dist.evolution.evaluate import universe_for
    from genr8_dist.fitness import SURFACE, criterion_names
    from genr8_dist.grammar.discovery import consent_for_history
    from genr8_dist.phenotype import SURFACES, phenotype_of

    source = config.universe_source
    digest = source.code_digest
    if consent_for_history(source):
        return phenotype_of(universe_for(config))
    if set(store.criteria) <= set(criterion_names(SURFACE)):
        return SURFACES
    raise HistoryError(f"{run_label(store)}: universe '{source.name}' develops its texts with Python code "
                       f"this machine has not trusted (sha256 {digest[:16]}...); install the plugin, or "
                       f"continue the run once with `genr8 resume --trust-hooks`, to regrow its individuals")
