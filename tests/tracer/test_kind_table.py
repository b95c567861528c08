"""`tracer.jit.kind_table`: kinds called at their addresses, compiled only where bound, never a jump to nowhere."""

from __future__ import annotations

import numpy as np
import pytest
from numba import types

from tracer.jit import kind_table, njit

RETURNS = types.Tuple((types.int64, types.float64))


@njit(cache=True)
def double(scale, x):
    return 1, scale[0] * 2.0 * x


@njit(cache=True)
def square(scale, x):
    return 2, scale[0] * x * x


@njit(cache=True)
def wrong(scale, x):   # returns a float where the family returns an int first
    return 3.0, scale[0] * x


def _signature(head):
    return head[0], types.float64


family = kind_table("family", {1: double, 2: square}, _signature, RETURNS)
mixed = kind_table("mixed", {1: double, 3: wrong}, _signature, RETURNS)


@njit(cache=True)
def call_each(table, kinds, scale, x):
    out = np.zeros(len(kinds))
    for i in range(len(kinds)):
        tag, value = family(table, kinds[i], (scale, x))
        out[i] = tag * 100 + value
    return out


def test_a_bound_kind_answers_as_its_own_function_and_an_unbound_one_is_never_compiled():
    scale = np.array([1.5])
    head = (types.float64[::1],)
    table = np.zeros(family.size, np.int64)
    family.bind(table, head, [1, 1, 7])   # 7: no such kind, left alone
    assert table[1] != 0 and table[2] == 0
    assert square.signatures == []      # a kind no one bound is not compiled
    assert np.allclose(call_each(table, np.array([1, 1]), scale, 3.0), [100 + 9.0, 100 + 9.0])
    family.bind(table, head, [2])
    assert len(square.signatures) == 1
    assert np.allclose(call_each(table, np.array([2, 1]), scale, 3.0), [200 + 13.5, 100 + 9.0])


def test_an_unbound_entry_is_an_error_naming_the_family_not_a_jump_to_zero():
    table = np.zeros(family.size, np.int64)
    with pytest.raises(RuntimeError, match="family: the kind table holds no address"):
        call_each(table, np.array([1]), np.array([1.0]), 2.0)


def test_a_kind_that_returns_another_layout_is_refused_when_bound():
    table = np.zeros(mixed.size, np.int64)
    with pytest.raises(TypeError, match="wrong returns"):
        mixed.bind(table, (types.float64[::1],), [3])
    assert table[3] == 0
