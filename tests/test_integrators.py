"""Integrators on the free rigid body: convergence order, geometric properties, batch/single
equivalence, and the intermediate-axis theorem (docs/physics.md §1, §4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rbenvs.dynamics import FreeBody, FreeBodyParams
from rbenvs.integrators import INTEGRATORS, Integrator, get_integrator
from rbenvs.rotations import quat_random

INERTIA = (0.9, 0.6, 0.5)  # distinct moments, a generic body
TORQUE = (0.3, -0.2, 0.25)


def _initial_states(rng, n, attitude, omega=1.5):
    d = rng.standard_normal((3, n))
    d /= np.linalg.norm(d, axis=0)
    pi = tuple(d * omega * float(np.mean(INERTIA)))
    return pi + (quat_random(rng, (n,)) if attitude else ())


def _run(integ, body, y, u, h, steps):
    for _ in range(steps):
        y = integ.step(body, y, u, h)
    return y


# ---------------------------------------------------------------------------- order
# h ranges in the asymptotic regime (errors 3e-2 .. 4e-10 at T = 2, |Omega| = 1.5, measured),
# well above round-off (the smallest error, rk4's ~4e-10, is ~1e6 ulp).
_H = {
    "euler": [0.02, 0.01, 0.005, 0.0025],
    "rk4": [0.2, 0.1, 0.05, 0.025],
    "splitting": [0.1, 0.05, 0.025, 0.0125],
    "exact": [0.2, 0.1, 0.05, 0.025],
}
# (name, attitude, torque): 'exact' only with torque, since without it the step is exact
# (test_exact_without_torque_is_exact_for_any_step).
ORDER_CASES = [
    (name, attitude, torque)
    for name in ("euler", "rk4", "splitting", "exact")
    for attitude in (False, True)
    for torque in (False, True)
    if torque or name != "exact"
]


def _fitted_order(name, attitude, hs, torque):
    rng = np.random.default_rng(30)
    n, t_end = 4, 2.0
    body = FreeBody(FreeBodyParams(INERTIA), attitude=attitude)
    y0 = _initial_states(rng, n, attitude)
    if torque:
        u = tuple(np.full(n, c) for c in TORQUE)
        ref = get_integrator("dop853", rtol=1e-13, atol=1e-15).step(body, y0, u, t_end)
    else:
        u = None
        ref = body.free_flow(y0, t_end)  # the exact elliptic flow (tested in test_free_body)
    ref = np.array(ref)
    integ = get_integrator(name)
    errors = []
    for h in hs:
        y = _run(integ, body, y0, u, h, int(round(t_end / h)))
        errors.append(np.max(np.abs(np.array(y) - ref)))
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    return slope, errors


@pytest.mark.parametrize(
    "name, attitude, torque",
    ORDER_CASES,
    ids=[f"{n}-{'att' if a else 'pi'}-{'torque' if t else 'free'}" for n, a, t in ORDER_CASES],
)
def test_empirical_order(name, attitude, torque):
    slope, errors = _fitted_order(name, attitude, _H[name], torque)
    declared = get_integrator(name).order
    # Halving h three times: the fitted slope of a clean power law is within a few 0.01 of the
    # order (measured 0.99-1.01, 3.91-4.01, 1.96-2.00); 0.3 allows pre-asymptotic terms while
    # still separating 1, 2 and 4.
    assert abs(slope - declared) <= 0.3, (slope, errors)
    assert errors[-1] < errors[0]


@pytest.mark.parametrize("attitude", [False, True])
def test_exact_without_torque_is_exact_for_any_step(attitude):
    rng = np.random.default_rng(31)
    body = FreeBody(FreeBodyParams(INERTIA), attitude=attitude)
    y0 = _initial_states(rng, 4, attitude)
    integ = get_integrator("exact")
    ref = np.array(get_integrator("dop853", rtol=1e-13, atol=1e-15).step(body, y0, None, 2.0))
    for h in (2.0, 0.5, 0.1):
        y = np.array(_run(integ, body, y0, None, h, int(round(2.0 / h))))
        # Independent of h: DOP853 at rtol 1e-13 over 2 time units (~1e-13) plus round-off.
        assert np.max(np.abs(y - ref)) <= 1e-11


def test_dop853_reference_matches_exact_flow():
    rng = np.random.default_rng(32)
    body = FreeBody(FreeBodyParams(INERTIA))
    y0 = _initial_states(rng, 4, False)
    got = np.array(get_integrator("dop853").step(body, y0, None, 5.0))
    # Default rtol 1e-12, atol 1e-14 over a few periods: error ~1e-11 of |Pi| ~ 1.
    np.testing.assert_allclose(got, np.array(body.free_flow(y0, 5.0)), atol=1e-10)
    exact = np.array(body.free_flow(y0, 5.0))
    for i in range(
        y0[0].shape[0]
    ):  # one state at a time: the vector field on floats, each start against the exact flow
        single, nfev = get_integrator("dop853").step_counted(
            body, tuple(float(c[i]) for c in y0), None, 5.0
        )
        assert all(isinstance(c, float) for c in single) and nfev > 0
        np.testing.assert_allclose(single, exact[:, i], atol=1e-10)  # same tolerance, one state
    # under a constant torque (the controls passed as floats): one state as the batch's row
    u = tuple(np.full(y0[0].shape[0], c) for c in TORQUE)
    batch = np.array(get_integrator("dop853", rtol=1e-13, atol=1e-15).step(body, y0, u, 2.0))
    for i in range(y0[0].shape[0]):
        single = get_integrator("dop853", rtol=1e-13, atol=1e-15).step(
            body, tuple(float(c[i]) for c in y0), tuple(float(c) for c in TORQUE), 2.0
        )
        np.testing.assert_allclose(single, batch[:, i], atol=1e-11)


# ---------------------------------------------------------------------------- long runs
def _energy_errors(body, integ, y0, h, steps, every=50):
    h0 = body.energy(y0)
    n0 = body.momentum_norm(y0)
    e_h, e_n = [], []
    y = y0
    for k in range(steps):
        y = integ.step(body, y, None, h)
        if k % every == every - 1:
            e_h.append(np.abs(body.energy(y) - h0) / h0)
            e_n.append(np.abs(body.momentum_norm(y) - n0) / n0)
    return np.array(e_h), np.array(e_n)


def test_splitting_long_run_keeps_casimir_and_bounded_energy():
    """1e5 Strang steps on 64 states at |Omega| h = 0.1 (~3.5 s)."""
    rng = np.random.default_rng(33)
    body = FreeBody(FreeBodyParams(INERTIA))
    y0 = _initial_states(rng, 64, False, omega=2.0)
    e_h, e_n = _energy_errors(body, get_integrator("splitting"), y0, 0.05, 100_000)
    # Every sub-flow is an exact rotation: |Pi| changes only by rounding, a random walk of
    # ~sqrt(7e5) * 1e-16 ~ 1e-13 (measured 1e-13).
    assert np.max(e_n) < 1e-12
    half = len(e_h) // 2
    first, second = e_h[:half].max(axis=0), e_h[half:].max(axis=0)
    # Bounded (backward-error) energy oscillation: the second half's worst equals the first's
    # (measured ratio 0.99-1.01); a drifting method would double it.
    assert np.all(second <= 2.0 * first)
    assert np.max(e_h) < 1e-2  # O(h^2) oscillation, measured 1e-3


def test_rk4_energy_drifts_at_large_step():
    """The contrast: rk4 at |Omega| h = 0.5 drifts linearly in energy and in |Pi|."""
    rng = np.random.default_rng(33)
    body = FreeBody(FreeBodyParams(INERTIA))
    y0 = _initial_states(rng, 64, False, omega=2.0)
    e_h, e_n = _energy_errors(body, get_integrator("rk4"), y0, 0.25, 20_000)
    half = len(e_h) // 2
    first, second = e_h[:half].max(axis=0), e_h[half:].max(axis=0)
    # A linear drift doubles from the first half to the second (measured 1.98-2.01).
    assert np.all(second >= 1.5 * first)
    assert np.min(e_n[-1]) > 1e-6  # the Casimir drifts too (measured ~2.5e-3 max)


# ---------------------------------------------------------------------------- batch = loop
ONE_IMPLEMENTATION = ["euler", "rk4", "splitting", "exact"]


def _batch_vs_loop(name, attitude, torque, steps=5, h=0.3):
    rng = np.random.default_rng(34)
    n = 24
    body = FreeBody(FreeBodyParams(INERTIA), attitude=attitude)
    y0 = _initial_states(rng, n, attitude, omega=3.0)
    u = tuple(rng.standard_normal((3, n))) if torque else None
    integ = get_integrator(name)
    batch = np.array(_run(integ, body, y0, u, h, steps), dtype=float)
    loop = np.empty_like(batch)
    for i in range(n):
        yi = tuple(float(c[i]) for c in y0)
        ui = None if u is None else tuple(float(c[i]) for c in u)
        out = _run(integ, body, yi, ui, h, steps)
        loop[:, i] = [float(c) for c in out]
    return batch, loop


@pytest.mark.parametrize("torque", [False, True], ids=["free", "torque"])
@pytest.mark.parametrize("name", ONE_IMPLEMENTATION)
def test_batch_equals_loop_bitwise_without_attitude(name, torque):
    batch, loop = _batch_vs_loop(name, False, torque)
    # One implementation for floats and arrays: the same operations in the same order.
    np.testing.assert_array_equal(batch, loop)


@pytest.mark.parametrize("torque", [False, True], ids=["free", "torque"])
@pytest.mark.parametrize("name", ["euler", "rk4", "splitting", "exact"])
def test_batch_equals_loop_bitwise_with_attitude(name, torque):
    batch, loop = _batch_vs_loop(name, True, torque)
    np.testing.assert_array_equal(batch, loop)


@pytest.mark.parametrize("torque", [False, True], ids=["free", "torque"])
@pytest.mark.parametrize("name", ONE_IMPLEMENTATION)
def test_batch_equals_loop_to_round_off_with_attitude(name, torque):
    """Whatever the bitwise outcome, batch and loop agree to round-off (measured <= 1.4e-15)."""
    batch, loop = _batch_vs_loop(name, True, torque)
    np.testing.assert_allclose(batch, loop, rtol=0.0, atol=1e-13)  # 5 steps x a few ulp x |y| <= 3


# ---------------------------------------------------------------------------- stability theorem
def _random_distinct_inertia(rng, gap=0.05):
    """I1 > I2 > I3 with relative gaps >= ``gap`` (so lambda is not tiny) and a real body."""
    while True:
        i1, i2, i3 = np.sort(rng.uniform(0.3, 1.0, 3))[::-1]
        if i2 + i3 >= i1 and i1 - i2 > gap * i1 and i2 - i3 > gap * i1:
            return float(i1), float(i2), float(i3)


@pytest.mark.parametrize("seed", range(5))
def test_intermediate_axis_instability_rate(seed):
    rng = np.random.default_rng(400 + seed)
    inertia = _random_distinct_inertia(rng)
    i1, i2, i3 = inertia
    body = FreeBody(FreeBodyParams(inertia))
    p = float(rng.uniform(0.5, 2.0)) * rng.choice([-1.0, 1.0])
    lam = abs(p / i2) * math.sqrt((i1 - i2) * (i2 - i3) / (i1 * i3))  # docs/physics.md §1
    eps = 1e-8 * abs(p)
    rk4 = get_integrator("rk4")
    h = 0.02 / lam  # rk4 error per unit time ~ (lam h)^4 ~ 1e-7: the growth rate to ~1e-7
    y = (eps, p, eps)
    times, norms = [], []
    t = 0.0
    while True:
        transverse = math.hypot(y[0], y[2])
        if transverse > 1e-3 * abs(p):
            break
        times.append(t)
        norms.append(transverse)
        y = rk4.step(body, y, None, h)
        t += h
    times, norms = np.array(times), np.array(norms)
    # Skip ~3 e-folds so the decaying (stable) eigen-component has died out; below 1e-3 |p| the
    # nonlinear correction to the rate is ~1e-6.
    sel = times > 3.0 / lam
    assert sel.sum() > 100
    rate = np.polyfit(times[sel], np.log(norms[sel]), 1)[0]
    assert rate == pytest.approx(lam, rel=0.02)  # measured within 5e-5; 2% as asked


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("axis", [0, 2], ids=["major", "minor"])
def test_major_and_minor_axis_spins_are_stable(seed, axis):
    rng = np.random.default_rng(500 + seed)
    inertia = _random_distinct_inertia(rng)
    body = FreeBody(FreeBodyParams(inertia))
    p = 1.0
    eps = 1e-8 * p
    y = [eps, eps, eps]
    y[axis] = p
    y = tuple(y)
    omega = p / inertia[axis]
    h = 0.05 / omega
    steps = int(round(1000.0 / omega / h))  # 1000 time units / |Omega|
    others = [i for i in range(3) if i != axis]
    rk4 = get_integrator("rk4")
    worst = 0.0
    for _ in range(steps):
        y = rk4.step(body, y, None, h)
        worst = max(worst, math.hypot(y[others[0]], y[others[1]]))
    # Linearly stable: the perturbation moves on a small ellipse of size eps * O(axis ratio)
    # (measured <= 1.1e-7 for these inertias); rk4 near an equilibrium is slightly damping.
    assert worst < 1e-6 * p
    assert abs(y[axis]) == pytest.approx(p, rel=1e-12)  # still spinning about the same axis


# ---------------------------------------------------------------------------- registry
def test_get_integrator_registry():
    for name in ("euler", "rk4", "splitting", "exact", "dop853"):
        integ = get_integrator(name)
        assert isinstance(integ, Integrator) and integ.name == name
        assert integ.supports(FreeBody(FreeBodyParams(INERTIA)))
    assert {"euler", "rk4", "splitting", "exact", "dop853"} <= set(INTEGRATORS)
    assert [get_integrator(n).order for n in ("euler", "rk4", "splitting", "exact")] == [1, 4, 2, 2]
    inst = get_integrator("rk4")
    assert get_integrator(inst) is inst  # instances pass through
    assert get_integrator("dop853", rtol=1e-10).rtol == 1e-10


@pytest.mark.parametrize("bad", ["rk5", "", "RK4", None, 4, ("rk4",)])
def test_get_integrator_rejects_unknown(bad):
    with pytest.raises(ValueError, match="integrator"):
        get_integrator(bad)


def test_declared_casimirs_are_kept_to_round_off_by_the_schemes_that_say_so():
    """``conserves = ("casimirs", ...)`` is a claim about every system's ``casimirs`` read-outs:
    check it on the free body (|Pi|) and the heavy top (|Gamma|, Pi.Gamma), 2000 steps of a
    random state, against round-off x sqrt(steps); and the schemes that do not claim it drift."""
    from rbenvs.dynamics import FreeBody, FreeBodyParams, HeavyTop, HeavyTopParams
    from rbenvs.integrators import INTEGRATORS, get_integrator

    rng = np.random.default_rng(3)
    g = rng.standard_normal(3)
    g /= np.linalg.norm(g)
    systems = [
        (FreeBody(FreeBodyParams((2.0, 1.5, 1.0))), rng.standard_normal(3).tolist()),
        (HeavyTop(HeavyTopParams()), rng.standard_normal(3).tolist() + g.tolist()),
        (
            HeavyTop(HeavyTopParams(inertia=(0.5, 0.45, 0.3), com_direction=(0.1, 0.2, 1.0))),
            rng.standard_normal(3).tolist() + g.tolist(),
        ),
    ]
    steps = 2000
    for system, y0 in systems:
        for name in INTEGRATORS:
            integ = get_integrator(name)
            if name == "dop853" or not integ.supports(system):
                continue
            y0 = tuple(y0)
            y = y0
            for _ in range(steps):
                y = integ.step(system, y, None, 0.01)
            drift = max(
                abs(getattr(system, c)(y) - getattr(system, c)(y0)) / abs(getattr(system, c)(y0))
                for c in system.casimirs
            )
            if "casimirs" in integ.conserves:
                assert drift < 1e-13 * steps**0.5 * 10, (type(system).__name__, name, drift)
            elif name == "euler":
                assert not drift < 1e-6, (
                    type(system).__name__,
                    name,
                    drift,
                )  # it does not keep them


def _bind_cases():
    from rbenvs.envs import FreeRigidBodyEnv, LagrangeTopEnv, TippeTopEnv

    for env in (
        FreeRigidBodyEnv(),
        FreeRigidBodyEnv(task="reorient"),
        LagrangeTopEnv(),
        TippeTopEnv(free_flight=True),
    ):
        env.reset(seed=3)
        yield env.system, env._y, env.actuator.control(env.action_space.sample().tolist())[1]


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_bind_is_step_bit_for_bit(name):
    """The hot path's bound step (Integrator.bind) computes exactly what step computes, with
    and without something to project (a free body without attitude skips normalize)."""
    integ = get_integrator(name)
    for system, y, u in _bind_cases():
        if not integ.supports(system):
            continue
        bound = integ.bind(system, system.dim)
        h = 1e-3
        assert bound(y, u, h) == integ.step(system, y, u, h)
