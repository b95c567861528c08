"""The tracer's ``njit``: numba's, with two changes that cut what a first query compiles.

numba compiles a callee anew for every literal constant a caller passes it: ``uniform(key, 0)`` …
``uniform(key, 5)`` in the photon loop were six compiles of one function, each surface kind's ``scatter`` two
(a literal 0 at one call site, an int64 at another), ``find_in_cdf`` four. A call between two of the tracer's
kernels is typed here with its arguments made plain (``Literal[int](0)`` → ``int64``, ``Literal[bool]`` →
``bool``), so each kernel compiles once per argument *types*, as it would from Python. None of the tracer's
kernels needs a literal argument (none calls ``numba.literally``); numba's own overloads keep theirs.

Inlining is LLVM's, not numba's. ``inline="always"`` asks numba to paste the callee's IR into every caller and
type it again there: 72 small helpers of the walks and the optics were, and typing the two-level walk
(`tracer.accel.traverse.closest_with_stacks`) alone took 23 s of a 153 s first forward query (bench/compile_probe.py).
Here it means ``forceinline``: the helper compiles once per argument types, like any callee, and LLVM's
always-inliner pastes its optimised code into each caller, so the machine code keeps its shape (answers
bit-identical, rays and photons per second unchanged within `bench/ab.py`'s noise; docs/ARCHITECTURE.md, "Compile
time"). Such a helper that takes one of the kernels' tuples (`TUPLES`) does so without reference counts (``_nrt=False``,
docs/CONTRACTS.md), unless it says otherwise because it allocates. Every other kernel is
compiled with ``forceinline=False`` said explicitly, since numba lets a callee inherit the flag from the caller it
is compiled for. No kernel is called through a C function pointer, so none gets numba's cfunc wrapper
(``no_cfunc_wrapper``): 6 % of a cold compile (`kind_table` calls a kind at its address with numba's own
calling convention, which needs none).

Import ``njit`` (and ``prange``) from here, never from numba, in every tracer module that defines kernels:
the change is made once, when this module is first imported, before any kernel compiles.
``tests/tracer/test_jit.py`` counts the compiles of a first query.
"""

from __future__ import annotations

from typing import Any

import numba
from numba import prange
from numba.core import dispatcher, types

__all__ = ["kind_switch", "kind_table", "njit", "prange"]

#: the modules whose kernels are called without literal arguments
PACKAGE = "tracer."


#: first parameters that name one of the kernels' tuples (scene, lights, materials, sensors, queries)
TUPLES = ("sa", "L", "M", "S", "Q")


def njit(*args: Any, **options: Any):
    """numba's ``njit`` (same arguments), with ``inline="always"`` made LLVM's ``forceinline`` and no cfunc wrapper
    (module docstring)."""
    if args and callable(args[0]):
        return njit(**options)(args[0])
    inline = options.get("inline") == "always"
    if inline:
        options["inline"] = "never"
        options["forceinline"] = True
    else:
        options.setdefault("forceinline", False)
    options.setdefault("no_cfunc_wrapper", True)

    def decorate(fn):
        params = fn.__code__.co_varnames[:fn.__code__.co_argcount]
        if inline and params and params[0] in TUPLES:
            return numba.njit(**{"_nrt": False, **options})(fn)
        return numba.njit(**options)(fn)

    return decorate


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


def kind_switch(name: str, params: str, tag: str, cases: dict[int, Any], default: str, *, doc: str = "",
                passes: str | None = None, **options: Any):
    """The one switch of a family on a kind tag, written out from its registry: ``name(params)`` returns
    ``cases[k](passes)`` (`passes` defaults to `params`) for the ``k`` that the expression `tag` equals, else
    `default`, jitted with `options`.

    pbrt dispatches a TaggedPointer with a template; numba types neither a tuple of kernels nor a call through
    one, so the branch chain is generated here from the registered kinds, and a new kind is its module plus its
    registration line, never a new branch. The chain is compiled from source text attributed to the calling
    module's file, so numba's ``cache=True`` keeps it; its name carries a digest of the cases, so a changed
    registry is a new cache entry, never a stale one.
    """
    import hashlib
    import sys

    caller = sys._getframe(1).f_globals
    names = {k: f"_case_{int(k)}" for k in sorted(cases)}
    passes = params if passes is None else passes
    lines = [f"    if _tag == {int(k)}:\n        return {n}({passes})\n" for k, n in names.items()]
    identity = ";".join(f"{k}={f.py_func.__module__}.{f.py_func.__qualname__}" for k, f in sorted(cases.items()))
    signature = params if passes == params else f"{params}->{passes}"
    digest = hashlib.sha256(f"{signature}|{tag}|{default}|{identity}".encode()).hexdigest()[:12]
    source = f"def {name}({params}):\n    _tag = {tag}\n{''.join(lines)}    return {default}\n"
    scope = {n: cases[k] for k, n in names.items()}
    exec(compile(source, caller["__file__"], "exec"), scope)   # noqa: S102 - the source is built above, from names
    fn = scope[name]
    fn.__module__ = caller["__name__"]
    fn.__qualname__ = f"{name}_{digest}"
    fn.__doc__ = doc
    return njit(**options)(fn)


def _case_chain(name: str, cases: dict[int, Any], filename: str):
    """``name(table, k, args)``: the branch chain that returns ``cases[k](*args)`` (the last case for any other k),
    as plain Python a device compiles into its kernel; its source attributed to `filename` (the family's module)."""
    ordered = sorted(int(k) for k in cases)
    names = {k: f"_case_{k}" for k in ordered}
    lines = [f"    if k == {k}:\n        return {names[k]}(*args)\n" for k in ordered[:-1]]
    source = f"def {name}(table, k, args):\n{''.join(lines)}    return {names[ordered[-1]]}(*args)\n"
    scope = {names[k]: cases[k] for k in ordered}
    exec(compile(source, filename, "exec"), scope)   # noqa: S102 - the source is built above, from names
    return scope[name]


def _binder(name: str, cases: dict[int, Any], signature, returns, layout: str):
    """`kind_table`'s ``bind(table, head, kinds)``: write into `table` ((max kind + 1,) int64) the address of each of
    `kinds` that has a case, compiled (or loaded) for the argument types ``signature(head)``, refusing a kind whose
    result is not laid out as `returns` (`layout`); the other entries are left as they are."""
    from numba.core.registry import cpu_target

    def bind(table, head: tuple, kinds) -> None:
        want = tuple(signature(tuple(head)))
        for k in sorted(set(int(k) for k in kinds) & set(int(c) for c in cases)):
            if table[k]:
                continue
            kernel = cases[k]
            kernel.compile(want)
            cres = kernel.overloads[want]
            returned = str(cpu_target.target_context.get_value_type(cres.signature.return_type))
            if returned != layout:   # the caller reads the result as `returns`
                raise TypeError(f"{name}: {kernel.py_func.__qualname__} returns {cres.signature.return_type}, "
                                f"laid out as {returned}; the family's kinds return {returns} ({layout})")
            table[k] = cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)

    bind.__doc__ = _binder.__doc__
    return bind


def kind_table(name: str, cases: dict[int, Any], signature, returns, *, doc: str = ""):
    """The call of a family's kinds through a table of addresses: ``name(table, k, args)`` returns ``cases[k](*args)``,
    where `table` (int64 array) holds, at index k, the address of ``cases[k]`` compiled for the argument types
    ``signature(head)`` (`head`: the types of the leading arguments that are the kernels' tuples) and returning
    `returns` (a numba type: the family's contract), which ``name.bind(table, head, kinds)`` writes for the kinds a
    scene holds (compiling or loading each from numba's cache).

    On the CPU the call goes through the address: a kind's code is compiled once, on its own, and only where a scene
    holds it, and no kernel that calls it holds a copy to type, lower and optimise again (a new kind adds no compile
    to any kernel). The addresses are data, so a kernel is cached as usual; a kind whose address is not bound is a
    RuntimeError naming the family, never a jump to 0. On a CUDA device, which cannot call the CPU's code, the same
    call is the branch chain over the cases (`kind_switch`'s), compiled into the kernel as before. Scalar arguments
    are converted to `signature`'s types; an array or tuple of another type is a typing error, and a kind that
    returns another layout than `returns` a TypeError when it is bound, never a call with the wrong layout.
    """
    import sys

    from numba.core import cgutils, errors
    from numba.core.cpu import CPUContext
    from numba.core.registry import cpu_target
    from numba.extending import intrinsic

    ordered = sorted(int(k) for k in cases)
    chain = _case_chain(name, cases, sys._getframe(1).f_globals["__file__"])
    layout = str(cpu_target.target_context.get_value_type(returns))

    def entry(table, k):
        return table[k]

    @intrinsic
    def call(typingctx, table, k, args):
        if not isinstance(table, types.Array) or not isinstance(k, types.Integer) \
                or not isinstance(args, types.BaseTuple):
            return None
        want = tuple(signature(tuple(args)))
        if len(want) != len(args):
            raise errors.TypingError(f"{name}: {len(args)} arguments, the kinds take {len(want)}")
        for i, (got, need) in enumerate(zip(args, want, strict=True)):
            if got != need and not (isinstance(got, types.Number) and isinstance(need, types.Number)):
                raise errors.TypingError(f"{name}: argument {i} is {got}, the kinds take {need}")

        def codegen(context, builder, sig, llargs):
            values = [context.cast(builder, builder.extract_value(llargs[2], i), got, need)
                      for i, (got, need) in enumerate(zip(args, want, strict=True))]
            if not isinstance(context, CPUContext):   # a device: the chain, compiled in
                packed = context.make_tuple(builder, types.Tuple(want), values)
                return context.compile_internal(builder, chain, returns(table, k, types.Tuple(want)),
                                                [llargs[0], llargs[1], packed])
            address = context.compile_internal(builder, entry, types.int64(table, k), llargs[:2])
            with cgutils.if_unlikely(builder, cgutils.is_null(builder, address)):
                context.call_conv.return_user_exc(builder, RuntimeError, (
                    f"{name}: the kind table holds no address for this kind; bind it in this process first",))
            fnty = context.call_conv.get_function_type(returns, want)
            pointer = builder.inttoptr(address, fnty.as_pointer())
            status, result = context.call_conv.call_function(builder, pointer, returns, want, values)
            with cgutils.if_unlikely(builder, status.is_error):
                context.call_conv.return_status_propagate(builder, status)
            return result

        return returns(table, k, args), codegen

    call.bind = _binder(name, cases, signature, returns, layout)
    call.size = ordered[-1] + 1
    call.__doc__ = doc
    return call
