"""Checked readers for configuration values (the one family of field validators: environments, run
configurations, fitness specifications): every failure names the source (when there is one), the
field and the value."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from genr8_dist.errors import ConfigError

__all__ = [
    "fail",
    "read_bool",
    "read_choice",
    "read_float",
    "read_int",
    "read_optional_bool",
    "read_vec3",
    "reject_unknown",
]


def fail(source: str, field: str, message: str) -> ConfigError:
    """A ConfigError reading ``source: field 'x': message`` (``field 'x': message`` without a source:
    the caller names the file)."""
    return ConfigError(f"{source}: field '{field}': {message}" if source else f"field '{field}': {message}")


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def read_float(value: Any, source: str, field: str, *, minimum: float | None = None,
               maximum: float | None = None, strict_minimum: bool = False) -> float:
    """``value`` as a finite float within the given bounds."""
    try:
        import numpy as np

        if isinstance(value, np.generic) and not isinstance(value, np.bool_):
            value = value.item()
    except ImportError:  # pragma: no cover - numpy is a hard dependency
        pass
    if not _is_number(value):
        raise fail(source, field, f"must be a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise fail(source, field, f"must be finite, got {value!r}")
    if minimum is not None and (number <= minimum if strict_minimum else number < minimum):
        relation = ">" if strict_minimum else ">="
        raise fail(source, field, f"must be {relation} {minimum:g}, got {value!r}")
    if maximum is not None and number > maximum:
        raise fail(source, field, f"must be <= {maximum:g}, got {value!r}")
    return number


def read_int(value: Any, source: str, field: str, *, minimum: int | None = None,
             maximum: int | None = None) -> int:
    """``value`` as an int within the given bounds (floats with no fraction are not accepted)."""
    try:
        import numpy as np

        if isinstance(value, np.integer):
            value = int(value)
    except ImportError:  # pragma: no cover
        pass
    if isinstance(value, bool) or not isinstance(value, int):
        raise fail(source, field, f"must be an integer, got {value!r}")
    if minimum is not None and value < minimum:
        raise fail(source, field, f"must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise fail(source, field, f"must be <= {maximum}, got {value}")
    return value


def read_bool(value: Any, source: str, field: str) -> bool:
    """``value`` as a bool (only true/false are accepted, not 0/1)."""
    if not isinstance(value, bool):
        raise fail(source, field, f"must be true or false, got {value!r}")
    return value


def read_optional_bool(value: Any, source: str, field: str) -> bool | None:
    """``value`` as a bool, or None."""
    return None if value is None else read_bool(value, source, field)


def read_choice(value: Any, source: str, field: str, choices: Sequence[str]) -> str:
    """``value`` as one of ``choices``."""
    if not isinstance(value, str) or value not in choices:
        allowed = ", ".join(repr(c) for c in choices)
        raise fail(source, field, f"must be one of {allowed}, got {value!r}")
    return value


def read_vec3(value: Any, source: str, field: str, *, allow_scalar: bool = False,
              minimum: float | None = None, strict_minimum: bool = False) -> tuple[float, float, float]:
    """``value`` as three finite floats; with ``allow_scalar`` one number stands for all three."""
    if allow_scalar and _is_number(value):
        number = read_float(value, source, field, minimum=minimum, strict_minimum=strict_minimum)
        return (number, number, number)
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sequence):
        try:
            import numpy as np

            if isinstance(value, np.ndarray):
                value = value.tolist()
            else:
                raise TypeError
        except TypeError:
            what = "a number or " if allow_scalar else ""
            raise fail(source, field, f"must be {what}a list of 3 numbers [x, y, z], got {value!r}") from None
    if len(value) != 3:
        raise fail(source, field, f"must have 3 numbers [x, y, z], got {len(value)}: {value!r}")
    x, y, z = (read_float(v, source, f"{field}[{i}]", minimum=minimum, strict_minimum=strict_minimum)
               for i, v in enumerate(value))
    return (x, y, z)


def reject_unknown(data: Mapping[str, Any], known: Sequence[str], source: str, where: str = "") -> None:
    """Raise a ConfigError naming the first key of ``data`` that is not in ``known``."""
    for key in data:
        if key not in known:
            allowed = ", ".join(sorted(known))
            field = f"{where}.{key}" if where else str(key)
            raise fail(source, field, f"unknown field (known fields: {allowed})")
