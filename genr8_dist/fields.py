"""Checked readers for configuration values (the one family of field validators: environments, run
configurations, fitness specifications): every failure names the source (when there is one), the
field and the value.

``setting(default, help, ...)`` declares a field of a configuration section once: its type (the
default's), default, range or choices and help. ``check_settings`` validates a section from those
declarations and ``settings_table`` writes its documentation table (docs/run-config.md is checked
against it by a test), so a new field is one line of its dataclass.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from genr8_dist.errors import ConfigError

__all__ = [
    "Setting",
    "check_settings",
    "fail",
    "read_bool",
    "read_choice",
    "read_float",
    "read_int",
    "read_optional_bool",
    "read_rate",
    "read_vec3",
    "reject_unknown",
    "setting",
    "settings_table",
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


def read_rate(value: Any, source: str, field: str) -> float:
    """``value`` as a probability: a number in [0, 1]."""
    try:
        return read_float(value, source, field, minimum=0.0, maximum=1.0)
    except ConfigError:
        raise fail(source, field, f"must be a number in [0, 1], got {value!r}") from None


#: A bound of a setting: a number, or a function of the section read so far (fields are read in
#: declaration order, so a bound may name an earlier field: ``maximum=lambda ea: ea.population``).
Bound = int | float | Callable[[Any], int | float] | None


@dataclasses.dataclass(frozen=True)
class Setting:
    """How one declared field is read and documented: its help (the docs' meaning column), its bounds
    or choices, whether it is a probability, or a reader of its own ``read(value, path, section)``."""

    help: str
    minimum: Bound = None
    maximum: Bound = None
    choices: tuple[str, ...] | None = None
    rate: bool = False
    read: Callable[[Any, str, Any], Any] | None = None
    shown: str | None = None


def setting(default: Any, help: str, *, minimum: Bound = None, maximum: Bound = None,
            choices: Sequence[str] | None = None, rate: bool = False,
            read: Callable[[Any, str, Any], Any] | None = None, shown: str | None = None) -> Any:
    """A dataclass field declared once: default, bounds or choices, help (see the module docstring);
    ``shown``: the docs' default column where the default is no TOML value (``None``: a default
    computed when the field is read)."""
    info = Setting(help, minimum, maximum, None if choices is None else tuple(choices), rate, read, shown)
    return dataclasses.field(default=default, metadata={"setting": info})


def _bound(bound: Bound, section: Any) -> Any:
    return bound(section) if callable(bound) else bound


def _read_setting(info: Setting, default: Any, value: Any, path: str, section: Any) -> Any:
    if info.read is not None:
        return info.read(value, path, section)
    if info.choices is not None:
        return read_choice(value, "", path, info.choices)
    if isinstance(default, bool):
        return read_bool(value, "", path)
    if isinstance(default, int):
        return read_int(value, "", path, minimum=_bound(info.minimum, section),
                        maximum=_bound(info.maximum, section))
    if info.rate:
        return read_rate(value, "", path)
    return read_float(value, "", path, minimum=_bound(info.minimum, section),
                      maximum=_bound(info.maximum, section))


def check_settings(section: Any, name: str) -> None:
    """Validate the declared fields of the frozen dataclass ``section`` (the table ``[name]``) in
    declaration order, storing each normalised value; errors name ``name.field`` (``field`` where
    ``name`` is empty: the configuration's top level)."""
    for f in dataclasses.fields(section):
        info = f.metadata.get("setting")
        if info is not None:
            path = f"{name}.{f.name}" if name else f.name
            value = _read_setting(info, f.default, getattr(section, f.name), path, section)
            object.__setattr__(section, f.name, value)


def _toml(value: Any) -> str:
    """``value`` as TOML writes it (the docs' default column)."""
    if isinstance(value, tuple):
        value = json.loads(json.dumps(value))
    return json.dumps(value)


def settings_table(cls: type) -> str:
    """The Markdown table (key, default, meaning) of the declared fields of ``cls``."""
    rows = ["| key | default | meaning |", "| --- | --- | --- |"]
    for f in dataclasses.fields(cls):
        info = f.metadata.get("setting")
        if info is not None:
            shown = info.shown if info.shown is not None else f"`{_toml(f.default)}`"
            rows.append(f"| `{f.name}` | {shown} | {info.help} |")
    return "\n".join(rows)
