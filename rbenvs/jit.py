"""The marker that lets compiled code call the package's own pure functions.

:func:`jitable` leaves a function exactly what it was (the single env calls it on Python
floats, the numpy batch on arrays, with no wrapper in between) and, once numba is in use,
registers it so that compiled kernels (:mod:`rbenvs.compiled`) may call it too. It sits at the
bottom of the package's layers: rotations, dynamics and tasks mark their functions with it.

numba is optional (the ``fast`` extra); ``RBENVS_COMPILED=0`` in the environment keeps every
path on numpy even where it is installed (:func:`available`).
"""

from __future__ import annotations

import os

__all__ = [
    "jitable",
    "compiled_form",
    "scalar_form",
    "available",
    "register_all",
    "register",
    "elementwise",
    "DISABLE_VARIABLE",
    "COMPILE_AFTER",
]

# set to "0" to keep the numpy path even where numba is installed (comparisons, debugging)
DISABLE_VARIABLE = "RBENVS_COMPILED"

# the elements (array entries, sub-envs drawn) a helper loop (elementwise, GeneratorTable.draws)
# runs on numpy or in Python (the same bits) before it is compiled: a one-off call (a reset's
# rows) does not pay a compile that costs more than the pass, and a large batch soon stops paying
# the slower form (rbenvs bench startup counts the kernels a cold start compiles)
COMPILE_AFTER = 1 << 15

_JITABLE: list = []  # pure functions compiled code may call, in definition order
_done: set = set()  # ids of the functions registered with numba (each once)


def jitable(fn):
    """Mark ``fn`` as callable from a compiled kernel; returns ``fn`` itself, unchanged.

    ``fn`` must be pure arithmetic on floats and tuples of floats (it is also run on numpy
    arrays by the batched numpy path): ``math``/``numpy`` scalar functions, ``if`` on ``is
    None`` and ``isinstance`` (resolved at compile time), calls to other jitable functions.
    """
    _JITABLE.append(fn)  # registered with numba by the next register_all (a kernel's build), so
    # that a compiled form declared after the function is the one registered
    return fn


def compiled_form(of):
    """Decorator: the decorated function is what compiled code runs for the jitable ``of``.

    For functions whose float form branches on the data (which interval an argument lies in,
    whether a norm vanished): compiled, a branch per element keeps a batch loop out of SIMD
    registers and mispredicts on random data. The compiled form computes the same operations
    for each outcome and selects (a ``select`` per branch), so it returns the same bits as the
    float form for every argument (each such pair is tested on floats, arrays and compiled).
    Python floats keep the branches: they cannot divide by zero, and one path costs less
    there."""

    def mark(alt):
        if id(of) in _done:
            raise RuntimeError(
                f"{of.__name__} was registered with numba before its compiled form was declared"
            )
        of.__compiled_form__ = alt
        return alt

    return mark


def scalar_form(of):
    """Decorator: the decorated function is what compiled code runs for the jitable ``of`` when
    its first argument is a bool (one state's condition), ``of`` itself otherwise.

    For :func:`rbenvs.rotations.select` and ``every``, which branch on ``isinstance(cond, bool)``
    between one state and a batch: inside the kernels numba compiled their batch branch
    (``np.where`` and ``all`` on scalars) for every scalar signature, a cost ``rbenvs bench
    startup``'s cold rows pay. The scalar form is the one-state branch's own code: the same
    operations, so the same bits."""

    def mark(alt):
        if id(of) in _done:
            raise RuntimeError(
                f"{of.__name__} was registered with numba before its scalar form was declared"
            )
        of.__scalar_form__ = alt
        return alt

    return mark


def available() -> bool:
    """Whether compiled kernels can be used: numba importable and not disabled."""
    if os.environ.get(DISABLE_VARIABLE, "1") == "0":
        return False
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def register(fn) -> None:
    if id(fn) in _done:
        return
    from numba.extending import overload

    # what numba.extending.register_jitable does, with the compiled form where one is declared
    impl = getattr(fn, "__compiled_form__", fn)
    scalar_form = getattr(fn, "__scalar_form__", None)
    if scalar_form is None:
        overload(fn, inline="never", strict=False)(lambda *args, **kwargs: impl)
    else:  # (the form chosen by the first argument's numba type)
        from numba.core import types

        overload(fn, inline="never", strict=False)(
            lambda x, *args, **kwargs: scalar_form if isinstance(x, types.Boolean) else impl
        )
    _done.add(id(fn))


def register_all() -> None:
    """Register every jitable function not yet registered (those of modules imported since the
    last call included); every kernel build calls it."""
    for fn in _JITABLE:
        if id(fn) not in _done:
            register(fn)


def elementwise(fn, n_in: int, n_out: int):
    """``fn`` (a jitable function of ``n_in`` floats returning ``n_out`` floats) over every
    element of arrays, as one compiled loop: ``loop(*xs) -> n_out arrays`` shaped as the
    arguments, or ``None`` where no loop can run (numba unavailable or disabled, or the
    arguments not float64 arrays of one shape): the caller then runs its numpy form.

    Why: a function written once for floats and selections (:func:`rbenvs.rotations.sincos`,
    :func:`rbenvs.rotations.atan2`) runs on arrays as a few dozen numpy operations, each a pass
    over the array, far slower than libm's ``np.sin`` on a small array; compiled, it is one pass.
    The loop runs the compiled form, which gives the same bits as the numpy form element for
    element (each pair is tested), so a result does not depend on which ran. Built once
    :data:`COMPILE_AFTER` elements have gone through the numpy form, once per process."""
    cache: dict = {}

    def loop(*xs):
        import numpy as np

        x = xs[0]
        if type(x) is not np.ndarray or x.dtype != np.float64 or not available():
            return None
        for other in xs[1:]:
            if type(other) is not np.ndarray or other.dtype != np.float64 or other.shape != x.shape:
                return None
        run = cache.get("run")
        if run is None:
            done = cache.get("done", 0)
            if done < COMPILE_AFTER:
                cache["done"] = done + x.size
                return None
            run = cache["run"] = _elementwise_loop(fn, n_in, n_out)
        if x.ndim == 1 and all(a.flags.c_contiguous for a in xs):  # (the batches' components)
            outs = tuple(np.empty(x.shape[0]) for _ in range(n_out))
            run(*xs, *outs)
            return outs
        flats = tuple(np.ascontiguousarray(a).reshape(-1) for a in xs)
        outs = tuple(np.empty_like(flats[0]) for _ in range(n_out))
        run(*flats, *outs)
        return tuple(o.reshape(x.shape) for o in outs)

    return loop


def _elementwise_loop(fn, n_in: int, n_out: int):
    from .codegen import generate
    from .kernel_cache import njit

    register_all()
    ins = ", ".join(f"x{j}" for j in range(n_in))
    outs = ", ".join(f"o{j}" for j in range(n_out))
    lines = [
        f"def run({ins}, {outs}):",
        "    for i in range(x0.shape[0]):",
        f"        r = fn({', '.join(f'x{j}[i]' for j in range(n_in))})",
    ]
    lines += (
        [f"        o{j}[i] = r[{j}]" for j in range(n_out)] if n_out > 1 else ["        o0[i] = r"]
    )
    namespace = generate("\n".join(lines), f"elementwise {fn.__name__}", {"fn": fn})
    # forceinline: fn inlined into the loop (a call left in it keeps the loop scalar)
    return njit(
        namespace["run"], f"elementwise {fn.__name__}", error_model="numpy", forceinline=True
    )
