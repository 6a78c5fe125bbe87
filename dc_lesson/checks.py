"""Checking a configuration dataclass's fields once, at construction.

Every learner's config (``PPOConfig``, ``BCConfig``, ``GAILConfig``, ``DCConfig``) and
``SoftFlowConfig`` calls :func:`check_fields` first thing in ``__post_init__``.  The field's
annotation gives its type: an ``int`` field takes a whole number but not a bool (``True`` is
not 1 here), a ``float`` field any real number that is finite (NaN and infinities are
refused), a ``bool`` field only a bool, ``tuple[int, ...]`` a sequence of positive whole
numbers; ``X | None`` also takes None.  Numpy scalars are accepted and stored as Python
numbers, so ``to_json`` stays plain.  The ranges (``positive``, ``non_negative``, ``fraction``)
are named by each config.  Every refusal is a :class:`ConfigError` naming the class, the field
and the value.
"""

from __future__ import annotations

import dataclasses
import math
import numbers


class ConfigError(ValueError, TypeError):
    """A configuration field with a value of the wrong type or outside its range.

    Both a ``ValueError`` and a ``TypeError``, so callers catching either see it."""


def _alternatives(annotation) -> list[str]:
    text = annotation if isinstance(annotation, str) else getattr(annotation, "__name__",
                                                                  str(annotation))
    return [a.strip() for a in text.replace("typing.", "").split("|")]


def _convert(owner: str, name: str, kind: str, value):
    """``value`` as the Python type ``kind`` names; ConfigError if it is not one."""
    where = f"{owner}.{name}"
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise ConfigError(f"{where} must be a whole number, got {value!r} "
                              f"({type(value).__name__})")
        return int(value)
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ConfigError(f"{where} must be a number, got {value!r} "
                              f"({type(value).__name__})")
        if not math.isfinite(float(value)):
            raise ConfigError(f"{where} must be finite, got {value!r}")
        return float(value)
    if kind == "bool":
        if type(value).__name__ not in ("bool", "bool_"):
            raise ConfigError(f"{where} must be True or False, got {value!r} "
                              f"({type(value).__name__})")
        return bool(value)
    if kind == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{where} must be a string, got {value!r} "
                              f"({type(value).__name__})")
        return value
    if kind.replace(" ", "") == "tuple[int,...]":
        if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
            raise ConfigError(f"{where} must be a tuple of layer widths, got {value!r}")
        out = []
        for v in value:
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 1:
                raise ConfigError(f"{where} must hold positive whole numbers, got {value!r}")
            out.append(int(v))
        return tuple(out)
    return value   # another type (a nested config): its own class checks it


def check_fields(config, *, positive=(), non_negative=(), fraction=(), choices=None) -> None:
    """Checks (and normalises in place) every field of the dataclass ``config``.

    ``positive`` fields must be > 0, ``non_negative`` >= 0, ``fraction`` in [0, 1];
    ``choices`` maps a field to its allowed values.  A None (where the type allows it) skips
    the range check.
    """
    owner = type(config).__name__
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        kinds = _alternatives(field.type)
        if value is None:
            if "None" not in kinds:
                raise ConfigError(f"{owner}.{field.name} must not be None")
            continue
        kind = next((k for k in kinds if k != "None"), "")
        value = _convert(owner, field.name, kind, value)
        object.__setattr__(config, field.name, value)
    for name in positive:
        value = getattr(config, name)
        if value is not None and not value > 0:
            raise ConfigError(f"{owner}.{name} must be positive, got {value!r}")
    for name in non_negative:
        value = getattr(config, name)
        if value is not None and not value >= 0:
            raise ConfigError(f"{owner}.{name} must be zero or more, got {value!r}")
    for name in fraction:
        value = getattr(config, name)
        if value is not None and not 0 <= value <= 1:
            raise ConfigError(f"{owner}.{name} must be between 0 and 1, got {value!r}")
    for name, allowed in (choices or {}).items():
        if getattr(config, name) not in allowed:
            raise ConfigError(f"{owner}.{name} must be one of {', '.join(map(repr, allowed))}; "
                              f"got {getattr(config, name)!r}")


__all__ = ["ConfigError", "check_fields"]
