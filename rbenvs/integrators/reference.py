"""The accuracy reference: scipy's adaptive DOP853 at tight tolerances."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .base import Integrator, StepRegion

__all__ = ["Dop853", "REFERENCE"]


@dataclass(frozen=True)
class Dop853(Integrator):
    """Dormand-Prince 8(5,3) via ``scipy.integrate.solve_ivp`` with ``rtol``/``atol``.

    The whole batch is one ODE system (the step size follows its stiffest member). Expensive
    per call; use it to check the others. scipy clamps ``rtol`` below ``100 eps`` (~2.2e-14).
    """

    name = "dop853"
    order = 8
    evaluations = None
    region: ClassVar[StepRegion] = StepRegion.unbounded("adaptive error control (rtol, atol)")
    uniform_step_only: ClassVar[bool] = True  # one solve, one step size, for the whole batch
    rtol: float = 1e-12
    atol: float = 1e-14

    def step(self, system, y, u, h):
        return self.step_counted(system, y, u, h)[0]

    def step_counted(self, system, y, u, h):
        arrays = np.broadcast_arrays(*(np.asarray(c, dtype=float) for c in y))
        shape = arrays[0].shape
        dim = len(arrays)
        y0 = np.stack(arrays).reshape(-1)
        if shape == ():
            # One state: the vector field on Python floats (the forms are written for floats and
            # arrays alike), not on solve_ivp's (1,)-arrays, where every operation is a numpy call.
            uf = None if u is None else tuple(float(c) for c in u)

            def fun(_t, flat):
                return np.array(system.rhs(tuple(flat.tolist()), uf), dtype=float)

        else:
            if u is not None:
                u = tuple(np.broadcast_to(np.asarray(c, dtype=float), shape).reshape(-1) for c in u)

            def fun(_t, flat):
                comps = tuple(flat.reshape(dim, -1))
                return np.concatenate(
                    [
                        np.broadcast_to(np.asarray(d, dtype=float), comps[0].shape)
                        for d in system.rhs(comps, u)
                    ]
                )

        from scipy.integrate import (
            solve_ivp,
        )  # (here: importing it is a large share of every env's start; rbenvs bench startup)

        sol = solve_ivp(fun, (0.0, float(h)), y0, method="DOP853", rtol=self.rtol, atol=self.atol)
        if not sol.success:
            raise RuntimeError(f"dop853 failed: {sol.message}")
        out = sol.y[:, -1].reshape((dim,) + shape)
        if shape == ():
            comps = tuple(float(c) for c in out)
        else:
            comps = tuple(out)
        return system.normalize(comps), int(sol.nfev)


# the benches' and tests' reference: tight enough that its own error (about 1e-13 relative over
# their runs) is far below any tolerance they compare against
REFERENCE = Dop853(rtol=1e-13, atol=1e-15)
