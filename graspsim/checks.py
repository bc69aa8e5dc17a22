"""The one check of settings: the rule a value follows, and the function that holds a
settings dataclass's fields to it.

Every frozen settings dataclass (``MapConfig``, ``RobustConfig``, ``SceneConfig``,
``EnvConfig``, ``DepthNoise`` ...) validates itself in ``__post_init__``. What they all
repeat -- "each of these fields must be a finite number > 0" -- is
:func:`check_fields` with a :class:`Rule`: the first field that breaks it raises
:class:`~graspsim.errors.InvalidParameterError`, one line naming the field, what is
valid and what was given (``MapConfig.surface_step must be > 0, got -1.0``). Checks
that tie fields together stay in the dataclass that has them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import Any

from graspsim.errors import InvalidParameterError

__all__ = ["Rule", "POSITIVE", "NON_NEGATIVE", "BOOLEAN", "integer", "or_none", "check_fields"]


@dataclass(frozen=True)
class Rule:
    """``ok(value)`` says whether a value is valid (a value it cannot even compare, a
    string where a number belongs, is not); ``says`` what a valid value is, as the error
    message puts it after "must be"."""

    ok: Callable[[Any], bool]
    says: str

    def holds(self, value) -> bool:
        try:
            return bool(self.ok(value))
        except (TypeError, ValueError):
            return False

    def saying(self, says: str) -> Rule:
        """The same rule, worded for its fields (a unit, a range's meaning)."""
        return replace(self, says=says)


def _finite(v) -> bool:
    """A finite Python number (an int or a float, numpy's float64 too; not a string, None
    or a one-element array)."""
    return isinstance(v, (int, float)) and math.isfinite(v)


#: A finite number > 0.
POSITIVE = Rule(lambda v: _finite(v) and v > 0, "> 0")
#: A finite number >= 0.
NON_NEGATIVE = Rule(lambda v: _finite(v) and v >= 0, ">= 0")
#: True or False (a bool, not 0 / 1).
BOOLEAN = Rule(lambda v: isinstance(v, bool), "True or False")


def integer(low: int) -> Rule:
    """A whole number (a Python ``int``, not a bool) >= ``low``."""
    return Rule(lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= low, f"an integer >= {low}")


def or_none(rule: Rule) -> Rule:
    """``rule``, or None (the field's "not set")."""
    return Rule(lambda v: v is None or rule.ok(v), f"{rule.says} or None")


def check_fields(obj, rule: Rule, *names: str, owner: str | None = None) -> None:
    """Raise :class:`~graspsim.errors.InvalidParameterError` for the first of ``names``
    (default: every field of the dataclass ``obj``) whose value breaks ``rule``:
    ``"<owner>.<name> must be <rule.says>, got <value>"`` (no ``owner.`` when None)."""
    for name in names or tuple(f.name for f in fields(obj)):
        value = getattr(obj, name)
        if not rule.holds(value):
            raise InvalidParameterError(f"{owner + '.' if owner else ''}{name} must be {rule.says}, got {value!r}")
