"""Free rigid body checks of ``rbenvs verify`` (docs/physics.md §1), per integrator, on a batch of
random bodies:

* ``exact solution``: max ``|Pi - Pi_exact| / |Pi0|`` over ``[0, T]`` against
  :func:`rbenvs.oracles.exact_solution`;
* ``energy drift``, ``|Pi| drift``: relative change after ``T`` (zero torque);
* ``axis <name>: growth rate``: the exponential rate of a ``1e-8`` perturbation of a spin
  about the intermediate axis, fitted from the simulation, against ``lambda`` of the theorem;
* ``torque: d|Pi|^2 = 2 Pi.tau dt``: the momentum balance under a constant torque (catches a
  torque with the wrong sign, axis or scale; tolerance 1e-3 of ``2 |Pi| |tau| T``: the Simpson
  quadrature of the sampled power and the scheme's own error are both below 1e-4 at these steps);
* ``<major|minor> axis: max transverse |Pi|``: about the stable axes a ``1e-3`` perturbation
  stays bounded over 50 rotations (Lyapunov stability), and its largest size matches that of
  the exact orbit through the same state within 2%;
* ``fast tumble``: a body thrown tumbling at ``|Omega| = 30`` rad/s (about five turns a second)
  for 5 s (150 radians): two starts near the intermediate axis (``Omega`` along it, plus a
  transverse part ``U(0.05, 0.2)`` of it: the body flips over and back every half period, the
  Dzhanibekov effect) and two of uniformly random direction, on random bodies whose moments
  differ by at least 20% (``FAST_DISTINCT``: in a nearly symmetric body ``Pi`` turns slowly in
  the body whatever ``|Omega|``, and a step error with it), :data:`FAST_TUMBLE_BODIES` of them:
  the largest error against the exact solution (relative to
  ``|Pi0|``) and the largest relative drifts of the energy and ``|Pi|`` over the run. Here a step
  of ``1e-3`` s is ``|Omega| dt = 0.03``: a first-order engine's error is then no longer small,
  and its tolerance is the physical bound of :mod:`rbenvs.verify.common` (2% of ``|Pi|``, 4% of
  the energy), not what its order would promise.

Parameter ranges: moments ``I_i ~ U(0.5, 2)`` kg m^2 (triangle inequality enforced by
rejection, distinct by at least 5% for the axis checks), body angular velocity of uniformly
random direction and ``|Omega| = 1`` rad/s but for the fast tumble (faster spins belong to the
extremes tests). The fast tumble's bodies and starts come from a generator of their own
(``[seed, 1]``), so that the other rows' draws do not depend on it.
"""

from __future__ import annotations

import math

import numpy as np

from ..dynamics import FreeBody, FreeBodyParams
from ..oracles import exact_solution, intermediate_axis_growth_rate, orbit_period
from .common import (
    ENERGY_BOUND,
    MOMENTUM_BOUND,
    ROUND_OFF,
    Check,
    not_applicable,
    reference_scheme,
    scaled_tolerance,
)
from .settings import FAST_TUMBLE_SETTINGS, FREE_BODY_SETTINGS
from .simulator import advance, as_simulators, start

__all__ = ["FREE_BODY_SETTINGS", "FAST_TUMBLE_SETTINGS", "FAST_TUMBLE_BODIES", "free_body_checks"]


# The fast tumble (module docstring): |Omega| [rad/s], horizon [s], bodies (quick, full), and per
# integrator ``omega h`` (for dop853 the sampling interval), the exact-solution and invariant
# tolerances over its 150 radians. Measured worst over 3 seeds x 3 bodies x 4 starts in brackets:
# euler at omega h = 5e-4: exact [7.4e-3], energy [9.8e-3], |Pi| [6.1e-3]: the error of a
# first-order scheme grows with the rate Pi turns at in the body, below |Omega|, and 2e-2 is the
# physical bound (rbenvs.verify.common); rk4 at 2e-2: exact [2.3e-8], energy [2.4e-10];
# splitting at 1e-2: exact [1.8e-3], energy [1.3e-5] (bounded: symplectic), |Pi| round-off;
# exact: [4.5e-11] near the separatrix (the elliptic functions' conditioning), invariants
# round-off; dop853 (seed 0): exact [1.0e-11], energy [1.0e-12].
FAST_SPIN = 30.0
FAST_HORIZON = 5.0
FAST_TUMBLE_BODIES = (1, 3)
# each moment at least 1.2 times the next smaller: a tumbling body, not a near-symmetric spinner
FAST_DISTINCT = 0.2


def _random_inertia(rng, n, distinct=0.0):
    out = []
    while len(out) < n:
        i = rng.uniform(0.5, 2.0, 3)
        s = np.sort(i)
        if s[0] + s[1] < s[2]:
            continue
        if distinct and (s[1] / s[0] - 1 < distinct or s[2] / s[1] - 1 < distinct):
            continue
        out.append(i)
    return np.array(out)


def free_body_checks(
    integrators, seed=0, n_cases=6, horizon=10.0, progress=None, n_fast=0
) -> list[Check]:
    """The free-body rows of each of ``integrators``: rbenvs integrator names or
    :class:`~rbenvs.verify.simulator.Simulator` objects (at their own step, the tolerance rule of
    :func:`~rbenvs.verify.common.scaled_tolerance`); ``n_fast`` bodies tumble fast (``rbenvs
    verify``: :data:`FAST_TUMBLE_BODIES`)."""
    rng = np.random.default_rng(seed)
    checks: list[Check] = []
    inertias = _random_inertia(rng, n_cases)
    axis_inertias = _random_inertia(rng, max(2, n_cases // 2), distinct=0.05)
    fast = _fast_tumble_cases(np.random.default_rng([seed, 1]), n_fast)
    for sim in as_simulators(integrators):
        try:
            checks.extend(_checks_of(sim, inertias, axis_inertias, rng, horizon, progress))
        except NotImplementedError as exc:
            names = [EXACT_ROW.format(horizon=horizon), ENERGY_ROW, MOMENTUM_ROW, TORQUE_ROW]
            names += [
                AXIS_ROWS[label]
                for _ in axis_inertias
                for label in ("major", "intermediate", "minor")
            ]
            checks.extend(not_applicable("free_body", sim.name, names, str(exc)))
            if progress:
                progress(len(inertias) + 1)
        try:
            checks.extend(_fast_tumble_checks(sim, fast, progress))
        except NotImplementedError as exc:
            checks.extend(not_applicable("free_body", sim.name, list(FAST_ROWS.values()), str(exc)))
            if progress:
                progress(len(fast))
    return checks


EXACT_ROW = "exact solution over {horizon:g} s (max rel. error)"
ENERGY_ROW = "energy drift (rel.)"
MOMENTUM_ROW = "|Pi| drift (rel.)"
TORQUE_ROW = "torque: d|Pi|^2 = 2 Pi.tau dt over 2 s"
AXIS_ROWS = {
    "major": "major axis: max transverse |Pi| / initial (stable)",
    "intermediate": "intermediate axis: growth rate [1/s]",
    "minor": "minor axis: max transverse |Pi| / initial (stable)",
}
_FAST = f"fast tumble ({FAST_SPIN:g} rad/s, {FAST_HORIZON:g} s)"
FAST_ROWS = {
    "exact": f"{_FAST}: exact solution (max rel. error)",
    "energy": f"{_FAST}: energy drift (rel.)",
    "momentum": f"{_FAST}: |Pi| drift (rel.)",
}


def _sampled(run, steps, every, u, h, last=False):
    """``(k, y)`` after every ``every``-th of ``steps`` steps (and after the last with ``last``)."""
    k = 0
    while k + every <= steps:
        y = advance(run, every, u, h)
        k += every
        yield k, y
    if k < steps:
        y = advance(run, steps - k, u, h)
        if last:
            yield steps, y


def _checks_of(sim, inertias, axis_inertias, rng, horizon, progress) -> list[Check]:
    """The rows of ``sim`` but the fast tumble's: the exact solution and the invariants on the
    bodies ``inertias``, the torque balance, and the axes of ``axis_inertias``."""
    name = sim.name
    h, steps, tol_exact, tol_e, tol_p = _run_tolerances(sim, horizon)
    worst_err, worst_e, worst_p, worst_case = _exact_rows_worst(
        sim, inertias, rng, h, steps, horizon, progress
    )
    checks = [
        Check(
            "free_body",
            name,
            EXACT_ROW.format(horizon=horizon),
            0.0,
            worst_err,
            tol_exact,
            case=worst_case,
        ),
        Check("free_body", name, ENERGY_ROW, 0.0, worst_e, tol_e),
        Check("free_body", name, MOMENTUM_ROW, 0.0, worst_p, tol_p),
    ]
    try:
        checks.append(_torque_balance_check(sim, inertias[0], h, rng))
    except NotImplementedError as exc:
        checks.extend(not_applicable("free_body", name, [TORQUE_ROW], str(exc)))
    checks.extend(_axis_checks(sim, axis_inertias, h))
    if progress:
        progress()
    return checks


def _run_tolerances(sim, horizon):
    """``(h, steps, exact, energy, |Pi|)``: the step and number of steps over ``horizon`` and the
    tolerances of the exact-solution, energy and ``|Pi|`` rows (rbenvs' integrator at its verify
    settings, round-off for an invariant it conserves; a simulator's scaled to its own step)."""
    own = sim.dt is None
    if own:
        h, tol_exact, tol_inv = FREE_BODY_SETTINGS[sim.name]
    else:
        ref_h, ref_exact, ref_inv = FREE_BODY_SETTINGS[reference_scheme(sim.order)]
        h = sim.dt
    steps = int(round(horizon / h))
    if not own:  # |Omega| = 1 rad/s: omega h is h
        tol_exact = scaled_tolerance(ref_exact, h, ref_h, sim.order, steps, MOMENTUM_BOUND)
        tol_inv = scaled_tolerance(ref_inv, h, ref_h, sim.order, steps, ENERGY_BOUND)
        tol_inv_p = scaled_tolerance(ref_inv, h, ref_h, sim.order, steps, MOMENTUM_BOUND)
    else:
        tol_inv_p = tol_inv
    conserves = sim.integrator.conserves if own else ()
    tol_e = ROUND_OFF * steps**0.5 if "energy" in conserves else tol_inv
    # |Pi|: the free body's Casimir
    tol_p = ROUND_OFF * steps**0.5 if "casimirs" in conserves else tol_inv_p
    return h, steps, tol_exact, tol_e, tol_p


def _exact_rows_worst(sim, inertias, rng, h, steps, horizon, progress):
    """``(error, energy drift, |Pi| drift, case)``: the worst of each over the bodies
    ``inertias`` (four random starts each), the case that of the largest error."""
    worst_err, worst_e, worst_p = 0.0, 0.0, 0.0
    worst_case = {}
    for inertia in inertias:
        err, de, dp, pi0 = _exact_run(sim, inertia, rng, h, steps)
        if err > worst_err:
            worst_case = {"inertia": inertia.tolist(), "pi0": pi0.T.tolist(), "h": h, "T": horizon}
        worst_err, worst_e, worst_p = max(worst_err, err), max(worst_e, de), max(worst_p, dp)
        if progress:
            progress()
    return worst_err, worst_e, worst_p, worst_case


def _exact_run(sim, inertia, rng, h, steps):
    """``(error, energy drift, |Pi| drift, Pi0)`` of four random starts of the body ``inertia``
    run together: the largest error against the exact solution (relative to ``|Pi0|``, sampled
    about ten times) and relative drifts after ``steps`` steps of ``h``."""
    system = FreeBody(FreeBodyParams(tuple(inertia)))
    # uniform directions of Omega, scaled to |Omega| = 1 rad/s (the tolerances assume it)
    omega = rng.standard_normal((3, 4))
    pi0 = omega / np.linalg.norm(omega, axis=0) * inertia[:, None]
    y = tuple(pi0)
    run = start(sim, system, y)
    n_rec = 10
    every = max(1, steps // n_rec)
    err = 0.0
    for k, y in _sampled(run, steps, every, None, h, last=True):
        ref = exact_solution(inertia, pi0, k * h)
        err = max(err, float(np.max(np.abs(np.array(y) - ref) / np.linalg.norm(pi0, axis=0))))
    e0, e1 = system.energy(tuple(pi0)), system.energy(y)
    p0, p1 = system.momentum_norm(tuple(pi0)), system.momentum_norm(y)
    de = float(np.max(np.abs(e1 - e0) / e0))
    dp = float(np.max(np.abs(p1 - p0) / p0))
    return err, de, dp, pi0


def _torque_balance_check(sim, inertia, h, rng) -> Check:
    """With a constant body torque, ``d|Pi|^2/dt = 2 Pi . tau`` (the gyroscopic term is normal
    to ``Pi``). Predicted: the integral of ``2 Pi . tau`` along the simulated path (composite
    Simpson on every step, error O(h^4)); measured: the change of ``|Pi|^2``. A torque applied
    with the wrong sign, axis or scale breaks it by O(1)."""
    system = FreeBody(FreeBodyParams(tuple(inertia)))
    pi0 = rng.standard_normal(3) * inertia
    tau = 0.5 * rng.standard_normal(3)
    if sim.dt is None:
        h = min(h, 0.01)  # the quadrature needs fine samples whatever the scheme's own step
    horizon = 2.0
    steps = 2 * int(math.ceil(horizon / (2 * h)))  # even, for Simpson
    y = tuple(pi0)
    run = start(sim, system, y)
    power = [2.0 * float(np.dot(pi0, tau))]
    for _ in range(steps):
        y = run.step(tuple(tau), h)
        power.append(2.0 * float(np.dot(y, tau)))
    w = np.ones(steps + 1)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    predicted = float(h / 3.0 * np.dot(w, power))
    measured = float(np.dot(y, y) - np.dot(pi0, pi0))
    # Tolerance relative to the scale of the balance, 2 |Pi| |tau| T, not to its value (which a
    # random draw can make nearly zero).
    scale = (
        2.0
        * max(np.linalg.norm(pi0), float(np.linalg.norm(y)))
        * float(np.linalg.norm(tau))
        * horizon
    )
    return Check(
        "free_body",
        sim.name,
        TORQUE_ROW,
        predicted,
        measured,
        1e-3 * scale,
        case={"inertia": inertia.tolist(), "pi0": pi0.tolist(), "tau": tau.tolist(), "h": h},
    )


def _axis_checks(sim, inertias, h) -> list[Check]:
    """The three axes' rows of each body ``inertias``: the growth rate about the intermediate
    axis, the bounded transverse ``|Pi|`` about the major and minor ones."""
    out = []
    names = ("major", "intermediate", "minor")
    for inertia in inertias:
        params = FreeBodyParams(tuple(inertia))
        system = FreeBody(params)
        order = params.axis_order
        for label, j in zip(names, order):
            if label == "intermediate":
                out.append(_intermediate_axis_check(sim, system, inertia, j, h))
            else:
                out.append(_stable_axis_check(sim, system, inertia, label, j, h))
    return out


def _intermediate_axis_check(sim, system, inertia, j, h) -> Check:
    """The growth rate of a ``1e-8`` perturbation of a spin about the intermediate axis ``j``,
    fitted to the simulated amplitude, against ``lambda`` of the theorem."""
    a, b = (j + 1) % 3, (j + 2) % 3
    p = inertia[j]  # |Omega| = 1 rad/s about the axis
    lam = intermediate_axis_growth_rate(inertia, p)
    eps = 1e-8
    pi0 = np.zeros(3)
    pi0[j], pi0[a], pi0[b] = p, eps * p, eps * p
    t_end = math.log(1e-3 / eps) / lam  # until the perturbation is ~1e-3 p
    steps = int(math.ceil(t_end / h))
    ts, amp = [], []
    run = start(sim, system, tuple(pi0))
    every = max(1, steps // 200)
    for k, y in _sampled(run, steps, every, None, h):
        ts.append(k * h)
        amp.append(math.hypot(y[a], y[b]) / p)
    ts, amp = np.array(ts), np.array(amp)
    # fit after 2/lambda (the decaying mode has died out) while still linear
    sel = (ts > 2.0 / lam) & (amp < 1e-4)
    rate = float(np.polyfit(ts[sel], np.log(amp[sel]), 1)[0]) if sel.sum() >= 5 else float("nan")
    return Check(
        "free_body",
        sim.name,
        AXIS_ROWS["intermediate"],
        lam,
        rate,
        0.02,
        relative=True,
        case={"inertia": inertia.tolist(), "axis": int(j), "h": h},
    )


def _stable_axis_check(sim, system, inertia, label, j, h) -> Check:
    """The largest transverse ``|Pi|`` of a ``1e-3`` perturbation of a spin about the stable axis
    ``j`` (``label``: major or minor) over 50 rotations, against the exact orbit's."""
    a, b = (j + 1) % 3, (j + 2) % 3
    p = inertia[j]  # |Omega| = 1 rad/s about the axis
    eps = 1e-3
    pi0 = np.zeros(3)
    pi0[j], pi0[a], pi0[b] = p, eps * p, eps * p
    steps = int(math.ceil(50 * 2 * math.pi / h))  # 50 rotation periods at |Omega| = 1
    run = start(sim, system, tuple(pi0))
    worst = 0.0
    every = max(1, steps // 500)
    for _, y in _sampled(run, steps, every, None, h):
        worst = max(worst, math.hypot(y[a], y[b]))
    # The theorem says bounded; the exact orbit says by how much (an ellipse around the axis
    # whose size ratio grows as the moments approach each other).
    period = float(orbit_period(inertia, pi0))
    ref = exact_solution(inertia, pi0, np.linspace(0.0, period, 4001))
    predicted = float(np.max(np.hypot(ref[a], ref[b])))
    return Check(
        "free_body",
        sim.name,
        AXIS_ROWS[label],
        predicted / (math.sqrt(2) * eps * p),
        worst / (math.sqrt(2) * eps * p),
        0.02,
        relative=True,
        case={"inertia": inertia.tolist(), "axis": int(j), "h": h},
    )


def _fast_tumble_cases(rng, n) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` (inertia, ``Pi0`` of shape (3, 4)) of the fast tumble (module docstring)."""
    cases = []
    for inertia in _random_inertia(rng, n, distinct=FAST_DISTINCT):
        j = int(np.argsort(inertia)[1])  # the intermediate axis
        directions = []
        for _ in range(2):
            transverse = rng.standard_normal(3)
            transverse[j] = 0.0
            d = np.zeros(3)
            d[j] = 1.0
            directions.append(d + rng.uniform(0.05, 0.2) * transverse / np.linalg.norm(transverse))
        directions += [rng.standard_normal(3) for _ in range(2)]
        omega = np.array(directions).T
        omega *= FAST_SPIN / np.linalg.norm(omega, axis=0)
        cases.append((inertia, omega * inertia[:, None]))
    return cases


def _fast_tumble_checks(sim, cases, progress) -> list[Check]:
    """The fast tumble's rows: the worst over ``cases`` of the exact-solution error and the
    energy and ``|Pi|`` drifts (the largest over the run, sampled 50 times)."""
    own = sim.dt is None
    name = sim.name
    ref = sim.integrator.name if own else reference_scheme(sim.order)
    omega_h, tol_exact, tol_inv = FAST_TUMBLE_SETTINGS[ref]
    h = omega_h / FAST_SPIN if own else sim.dt
    steps = int(round(FAST_HORIZON / h))
    worst = {"exact": (0.0, {}), "energy": (0.0, {}), "momentum": (0.0, {})}
    for inertia, pi0 in cases:
        system = FreeBody(FreeBodyParams(tuple(inertia)))
        run = start(sim, system, tuple(pi0))
        e0, p0 = system.energy(tuple(pi0)), np.linalg.norm(pi0, axis=0)
        errors = {"exact": 0.0, "energy": 0.0, "momentum": 0.0}
        for k, y in _sampled(run, steps, max(1, steps // 50), None, h, last=True):
            exact = exact_solution(inertia, pi0, k * h)
            errors["exact"] = max(errors["exact"], float(np.max(np.abs(np.array(y) - exact) / p0)))
            errors["energy"] = max(
                errors["energy"], float(np.max(np.abs(system.energy(y) - e0) / e0))
            )
            errors["momentum"] = max(
                errors["momentum"], float(np.max(np.abs(system.momentum_norm(y) - p0) / p0))
            )
        # the signed changes over the run (a loss is damping, a gain Euler's outward drift)
        case = {
            "inertia": inertia.tolist(),
            "pi0": pi0.T.tolist(),
            "h": h,
            "T": FAST_HORIZON,
            "energy change at T (rel.)": (np.asarray(system.energy(y)) / e0 - 1.0).tolist(),
            "|Pi| change at T (rel.)": (np.asarray(system.momentum_norm(y)) / p0 - 1.0).tolist(),
        }
        for key, err in errors.items():
            if not err <= worst[key][0]:  # a nan is kept
                worst[key] = (err, case)
        if progress:
            progress()
    conserves = sim.integrator.conserves if own else ()
    round_off = ROUND_OFF * steps**0.5
    if own:
        tols = {
            "exact": tol_exact,
            "energy": round_off if "energy" in conserves else tol_inv,
            "momentum": round_off if "casimirs" in conserves else tol_inv,
        }
    else:
        scaled = (FAST_SPIN * h, omega_h, sim.order, steps)
        tols = {
            "exact": scaled_tolerance(tol_exact, *scaled, MOMENTUM_BOUND),
            "energy": scaled_tolerance(tol_inv, *scaled, ENERGY_BOUND),
            "momentum": scaled_tolerance(tol_inv, *scaled, MOMENTUM_BOUND),
        }
    return [
        Check("free_body", name, FAST_ROWS[key], 0.0, worst[key][0], tols[key], case=worst[key][1])
        for key in FAST_ROWS
    ]
