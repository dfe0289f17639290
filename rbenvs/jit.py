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

__all__ = ["jitable", "compiled_form", "available", "register_all", "register", "DISABLE_VARIABLE"]

# set to "0" to keep the numpy path even where numba is installed (comparisons, debugging)
DISABLE_VARIABLE = "RBENVS_COMPILED"

_JITABLE: list = []  # pure functions compiled code may call, in definition order
_registered = False
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
            raise RuntimeError(f"{of.__name__} was registered with numba before its compiled form was declared")
        of.__compiled_form__ = alt
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
    overload(fn, inline="never", strict=False)(lambda *args, **kwargs: impl)
    _done.add(id(fn))


def register_all() -> None:
    """Register every jitable function not yet registered (those of modules imported since the
    last call included); every kernel build calls it."""
    global _registered
    for fn in _JITABLE:
        if id(fn) not in _done:
            register(fn)
    _registered = True

