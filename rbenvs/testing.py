"""The theorems as a test suite for any simulator: :func:`verify` runs ``rbenvs verify``'s checks
on a :class:`~rbenvs.verify.simulator.Simulator`, or on a plain step function, and returns the
rows (docs/verification.md, "Any simulator"), for a user's own test suite:

.. code-block:: python

    from rbenvs.testing import verify

    def test_my_engine_keeps_the_theorems():
        rows = verify(my_step, systems=("free_body",), dt=1e-3, order=4)
        assert all(row.passed for row in rows), [row.check for row in rows if not row.passed]
"""

from __future__ import annotations

from .verify.common import Check
from .verify.simulator import CallableSimulator, Problem, Simulator, parse_simulator

__all__ = ["verify", "Check", "Problem", "Simulator", "CallableSimulator", "failures"]


def verify(
    simulator,
    systems=("free_body", "heavy_top", "tippe_top"),
    quick=True,
    seed=0,
    dt=1e-3,
    order=1,
    show_progress=False,
) -> list[Check]:
    """Every check of ``systems`` on ``simulator``: a :class:`Simulator`, a ``--simulator``
    spec string (``"mujoco:integrator=RK4"``, ``"module:function,dt=1e-3"``), or a step function
    ``step(problem, y, u, dt) -> y`` run at ``dt`` with the declared ``order`` (which scales the
    accuracy rows' tolerances). Returns the :class:`Check` rows: ``row.passed``, ``row.result``
    (``PASS``, ``FAIL`` or ``n/a``), ``row.measured`` against ``row.predicted`` within
    ``row.tolerance``."""
    from .verify import run_checks

    if isinstance(simulator, str):
        sims = parse_simulator(simulator)
    elif isinstance(simulator, Simulator):
        sims = [simulator]
    else:
        sims = [CallableSimulator(simulator, dt=dt, order=order)]
    return run_checks(
        systems=tuple(systems), quick=quick, seed=seed, show_progress=show_progress, simulators=sims
    )


def failures(rows) -> list[str]:
    """``system/simulator/check`` of every failing row (an assert's message)."""
    return [f"{r.system}/{r.integrator}/{r.check}" for r in rows if not r.passed]
