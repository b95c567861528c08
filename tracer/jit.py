"""The tracer's ``njit``: numba's, with one change that halves what a first query compiles.

numba compiles a callee anew for every literal constant a caller passes it: ``uniform(key, 0)`` …
``uniform(key, 5)`` in the photon loop were six compiles of one function, each surface kind's ``scatter`` two
(a literal 0 at one call site, an int64 at another), ``find_in_cdf`` four. A call between two of the tracer's
kernels is typed here with its arguments made plain (``Literal[int](0)`` → ``int64``, ``Literal[bool]`` →
``bool``), so each kernel compiles once per argument *types*, as it would from Python. None of the tracer's
kernels needs a literal argument (none calls ``numba.literally``); numba's own overloads keep theirs.

Import ``njit`` (and ``prange``) from here, never from numba, in every tracer module that defines kernels:
the change is made once, when this module is first imported, before any kernel compiles.
``tests/tracer/test_jit.py`` counts the compiles of a first query.
"""

from __future__ import annotations

from numba import njit, prange
from numba.core import dispatcher, types

__all__ = ["njit", "prange"]

#: the modules whose kernels are called without literal arguments
PACKAGE = "tracer."


def _plain_call_template(original):
    """numba's `Dispatcher.get_call_template`, typing a call to a tracer kernel with its arguments made plain."""

    def get_call_template(self, args, kws):
        if (getattr(self.py_func, "__module__", None) or "").startswith(PACKAGE):
            args = tuple(types.unliteral(a) for a in args)
            kws = {k: types.unliteral(v) for k, v in kws.items()}
        return original(self, args, kws)

    get_call_template.plain_arguments = True
    return get_call_template


if not getattr(dispatcher.Dispatcher.get_call_template, "plain_arguments", False):
    dispatcher.Dispatcher.get_call_template = _plain_call_template(  # type: ignore[method-assign]
        dispatcher.Dispatcher.get_call_template)
