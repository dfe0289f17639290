"""``rbenvs verify``'s rows for ``tolerance=`` (docs/integrators.md, "Accuracy: tolerance="), per
integrator that a tolerance takes (an error constant, its leading error in the phase: rk4 today),
on random free bodies against the exact solution (:func:`rbenvs.oracles.exact_solution`):

* ``tolerance=1e-6 over 400 periods: max |Pi - Pi_exact| / |Pi_exact|``: the env built with the
  tolerance and ``tolerance_check=True`` keeps the error of its episode within it (up to the
  state it keeps where the global error estimate ended the episode: the contract either way);
* ``tolerance_check: error - global error estimate``: the companion run's estimate
  (:mod:`rbenvs.stepsize.controller`) is at least the error on every period whose error is above
  roundoff (``1e-11``): the largest shortfall over the periods, relative to the tolerance, is 0;
* ``tolerance_check=True at 1e-9, 0.01 rad/s off the intermediate axis``: a start near the
  separatrix (``|Omega| = 5`` rad/s about the intermediate axis, 0.01 rad/s about each of the
  others), where the motion amplifies the steps' error and roundoff: the error of every period
  the episode runs is within the tolerance (the episode ends, flagged, where the estimate passes
  it: the row measures the periods before);
* ``tolerance_check=True at 1e-10, 0.001 rad/s off the intermediate axis``: ten times closer,
  where float64's roundoff, amplified at every passage by the saddle, is about the tolerance. The
  exact solution is exact enough here (4e-15 from mpmath's Taylor series on the default body).

Parameter ranges: moments ``I_i ~ U(0.5, 2)`` kg m^2 (triangle inequality by rejection, distinct
by at least 5%), the body angular velocity ``|Omega| = 5`` rad/s along a uniformly random
direction, 400 control periods of the env's ``dt`` (its episode), no torque. A start near the
intermediate axis is drawn as often as any other: its error grows like the horizon squared, the
case the global error estimate is for.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..oracles import exact_solution
from ..stepsize.controller import tolerance_blocks
from ..stepsize.forms import relative_difference
from .common import Check
from .free_body import _random_inertia

__all__ = ["TOLERANCE", "PERIODS", "SPIN", "ROWS", "tolerance_integrators", "tolerance_checks"]

TOLERANCE = 1e-6
NEAR_TOLERANCE = 1e-9  # the near-separatrix row's
NEAR_OFF = 0.01  # its start's Omega about the major and minor axes [rad/s]
FLOOR_TOLERANCE, FLOOR_OFF = 1e-10, 0.001  # the floor row's
PERIODS = 400
SPIN = 5.0  # |Omega| [rad/s] of the starts
ROUND_OFF_ERROR = 1e-11  # errors below this are roundoff: the estimate is not held to them
ROWS = {
    "error": f"tolerance={TOLERANCE:g} over {PERIODS} periods: max |Pi - Pi_exact| / |Pi_exact|",
    "bound": "tolerance_check: max (error - global error estimate) / tolerance",
    "near": (
        f"tolerance_check=True at {NEAR_TOLERANCE:g}, {NEAR_OFF:g} rad/s off the intermediate "
        "axis: max |Pi - Pi_exact| / |Pi_exact|"
    ),
    "floor": (
        f"tolerance_check=True at {FLOOR_TOLERANCE:g}, {FLOOR_OFF:g} rad/s off the intermediate "
        "axis: max |Pi - Pi_exact| / |Pi_exact|"
    ),
}


def tolerance_integrators(integrators) -> list[str]:
    """The named integrators that ``tolerance=`` takes."""
    from ..integrators import get_integrator
    from ..stepsize.controller import takes_tolerance

    return [name for name in integrators if takes_tolerance(type(get_integrator(name)))]


def tolerance_checks(integrators, seed=0, n_cases=2, progress=None) -> list[Check]:
    """Four rows per integrator that ``tolerance=`` takes (the module's), each the worst of
    ``n_cases`` random bodies and starts (``progress`` called three times a body)."""
    rng = np.random.default_rng([seed, 2])
    inertias = _random_inertia(rng, n_cases, distinct=0.05)
    directions = rng.normal(size=(n_cases, 3))
    out = []
    for name in tolerance_integrators(integrators):
        out.extend(_random_start_checks(name, inertias, directions, seed, progress))
        for row, tolerance, off in (
            (ROWS["near"], NEAR_TOLERANCE, NEAR_OFF),
            (ROWS["floor"], FLOOR_TOLERANCE, FLOOR_OFF),
        ):
            out.append(_separatrix_check(name, inertias, seed, progress, row, tolerance, off))
    return out


def _random_start_checks(name, inertias, directions, seed, progress) -> list[Check]:
    """The ``error`` and ``bound`` rows of integrator ``name``: the worst over the bodies
    ``inertias`` started spinning along ``directions``."""
    worst = {"error": (0.0, {}), "bound": (0.0, {})}
    for inertia, d in zip(inertias, directions):
        omega = SPIN * d / np.linalg.norm(d)
        pi0 = inertia * omega
        case = {
            "inertia": inertia.tolist(),
            "angular_momentum": pi0.tolist(),
            "integrator": name,
            "tolerance": TOLERANCE,
        }
        env = _checked_env(name, inertia, pi0, TOLERANCE, seed)
        error, shortfall = _episode_error_and_shortfall(env, inertia, pi0, TOLERANCE)
        for key, value in (("error", error), ("bound", shortfall)):
            if not value <= worst[key][0]:  # (NaN too)
                worst[key] = (value, case)
        if progress:
            progress()
    error, error_case = worst["error"]
    shortfall, bound_case = worst["bound"]
    return [
        Check("free_body", name, ROWS["error"], 0.0, error, TOLERANCE, case=error_case),
        Check("free_body", name, ROWS["bound"], 0.0, max(shortfall, 0.0), 0.0, case=bound_case),
    ]


def _checked_env(name, inertia, pi0, tolerance, seed):
    """The free-body env of integrator ``name`` at ``tolerance`` with ``tolerance_check=True``,
    reset to ``pi0``."""
    from ..envs import FreeRigidBodyEnv, UnstableMotionWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableMotionWarning)
        env = FreeRigidBodyEnv(
            inertia=tuple(inertia),
            max_torque=0.0,
            integrator=name,
            max_angular_velocity=10.0 * SPIN,
            tolerance=tolerance,
            tolerance_horizon=PERIODS,
            tolerance_check=True,
        )
    env.reset(seed=seed, options={"state": {"angular_momentum": pi0}})
    return env


def _episode_error_and_shortfall(env, inertia, pi0, tolerance):
    """``(max error, max (error - global error estimate) / tolerance)`` over the periods
    ``env``'s episode runs from ``pi0``, against the exact solution (the shortfall over the
    periods whose error is above roundoff)."""
    blocks = tolerance_blocks(env.system)
    a = np.zeros(env.action_space.shape, np.float32)
    error = shortfall = 0.0
    with warnings.catch_warnings():
        # (an episode the estimate ends warns: the contract, measured up to there)
        warnings.simplefilter("ignore")
        for k in range(1, PERIODS + 1):
            _, _, terminated, _, info = env.step(a)
            if info["numerical_failure"]:
                break  # (the state kept is the last one within: measured above)
            ref = exact_solution(tuple(inertia), pi0, k * env.dt)
            err = float(relative_difference(blocks, ref, env.state_components))
            error = max(error, err)
            if err > ROUND_OFF_ERROR:
                shortfall = max(shortfall, (err - info["global_error_estimate"]) / tolerance)
            if terminated:
                break
    return error, shortfall


def _separatrix_check(name, inertias, seed, progress, row, tolerance, off) -> Check:
    """A near-separatrix row (the module's ``row``: ``tolerance`` at ``off`` rad/s off the
    intermediate axis) of integrator ``name``, the worst of the bodies ``inertias``."""
    worst, worst_case = 0.0, {}
    for inertia in inertias:
        omega = np.full(3, off)
        omega[int(np.argsort(inertia)[1])] = SPIN  # about the intermediate axis
        pi0 = inertia * omega
        case = {
            "inertia": inertia.tolist(),
            "angular_momentum": pi0.tolist(),
            "integrator": name,
            "tolerance": tolerance,
            "tolerance_check": True,
        }
        env = _checked_env(name, inertia, pi0, tolerance, seed)
        error, _ = _episode_error_and_shortfall(env, inertia, pi0, tolerance)
        if not error <= worst:  # (NaN too)
            worst, worst_case = error, case
        if progress:
            progress()
    return Check("free_body", name, row, 0.0, worst, tolerance, case=worst_case)
