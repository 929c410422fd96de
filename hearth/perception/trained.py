"""Which fields of a configuration dataclass a trained model depends on.

Decided next to each field: a setting that only matters when a model is *used* (a threshold,
an MRF weight) is declared with ``read_time(default)``; every other field is a *trained*
field, so a field added later invalidates stored models unless someone decides otherwise.
``trained_fields(config)`` is what goes into a model's stored configuration.
"""
from __future__ import annotations

from dataclasses import asdict, field, fields
from typing import Any

_READ_TIME = "read_time"


def read_time(default: Any):
    """A dataclass field that can change without retraining (``field(default=...)``)."""
    return field(default=default, metadata={_READ_TIME: True})


def trained_fields(config) -> dict:
    """The trained fields of a configuration dataclass instance, by name (JSON-able values)."""
    values = asdict(config)
    return {f.name: values[f.name] for f in fields(config) if not f.metadata.get(_READ_TIME)}
