"""graspsim.checks: the one check of settings' fields (rules and their messages)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from graspsim.checks import BOOLEAN, NON_NEGATIVE, POSITIVE, Rule, check_fields, integer, or_none
from graspsim.errors import InvalidParameterError


@dataclass(frozen=True)
class _Settings:
    step: float = 0.1
    count: int = 3
    force: float | None = None


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), "0.1", None, [0.1]])
def test_positive_refuses_what_is_not_a_finite_number_above_zero(bad):
    with pytest.raises(InvalidParameterError, match=r"^_Settings\.step must be > 0, got "):
        check_fields(_Settings(step=bad), POSITIVE, "step", owner="_Settings")


def test_the_first_field_breaking_the_rule_is_named_with_the_value_given():
    s = _Settings(step=0.2, count=-2)
    with pytest.raises(InvalidParameterError) as err:
        check_fields(s, NON_NEGATIVE, "step", "count")
    assert str(err.value) == "count must be >= 0, got -2"
    check_fields(_Settings(step=0.0), NON_NEGATIVE, "step")  # zero is >= 0


def test_every_field_by_default_and_the_rule_worded_for_its_fields():
    with pytest.raises(InvalidParameterError, match=r"^force must be > 0 N, got None$"):
        check_fields(_Settings(), POSITIVE.saying("> 0 N"))
    check_fields(_Settings(), or_none(POSITIVE), "force")
    with pytest.raises(InvalidParameterError, match=r"^force must be > 0 or None, got -1$"):
        check_fields(_Settings(force=-1), or_none(POSITIVE), "force")


@pytest.mark.parametrize("bad", [True, 2.0, "3", 0])
def test_integer_wants_a_whole_python_int(bad):
    with pytest.raises(InvalidParameterError, match="count must be an integer >= 1"):
        check_fields(_Settings(count=bad), integer(1), "count")
    check_fields(_Settings(count=1), integer(1), "count")


@pytest.mark.parametrize("bad", [1, 0, "True", None])
def test_boolean_wants_true_or_false_not_a_number(bad):
    with pytest.raises(InvalidParameterError, match=r"^flag must be True or False, got "):
        check_fields(_Flags(flag=bad), BOOLEAN, "flag")
    check_fields(_Flags(flag=False), BOOLEAN, "flag")


@dataclass(frozen=True)
class _Flags:
    flag: object = True


def test_a_rule_that_cannot_compare_the_value_refuses_it():
    with pytest.raises(InvalidParameterError, match="step must be in .0, 1., got 'a'"):
        check_fields(_Settings(step="a"), Rule(lambda v: 0 <= v <= 1, "in [0, 1]"), "step")
