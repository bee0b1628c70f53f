"""The checked readers of configuration values, for the environment's modules (genr8_dist.fields)."""

from genr8_dist.fields import (
    fail,
    read_bool,
    read_choice,
    read_float,
    read_int,
    read_optional_bool,
    read_vec3,
    reject_unknown,
)

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
