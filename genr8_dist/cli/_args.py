"""Argument types the subcommands share."""

from __future__ import annotations

import argparse

__all__ = ["int32"]


def int32(text: str) -> int:
    """A whole number that fits the run store's 32-bit columns."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not -(2**31) <= value < 2**31:
        raise argparse.ArgumentTypeError(f"{text}: out of range (at most {2**31 - 1} either way)")
    return value
