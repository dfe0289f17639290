"""The one code generator (rbenvs.codegen) and explicit Runge-Kutta schemes from their
Butcher tableaus (rbenvs.integrators.runge_kutta)."""

import inspect
import linecache
import math
import traceback
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import pytest

from rbenvs import codegen
from rbenvs.dynamics import (
    FreeBody,
    FreeBodyParams,
    HeavyTop,
    HeavyTopParams,
    TippeTop,
    TippeTopParams,
)
from rbenvs.integrators import RK4, ButcherTableau, Euler, ExplicitRungeKutta, get_integrator
from rbenvs.oracles import exact_solution


# ----------------------------------------------------------------- the generator
def test_generated_code_shows_its_source_in_tracebacks():
    ns = codegen.generate(
        "def f(x):\n    y = x + 1\n    return 1 / (y - y)\n", "test zero division"
    )
    with pytest.raises(ZeroDivisionError) as err:
        ns["f"](2.0)
    text = "".join(traceback.format_exception(err.value))
    assert "<rbenvs generated: test zero division #" in text and "return 1 / (y - y)" in text


def test_generated_code_is_readable_with_inspect_and_survives_checkcache():
    """Each source has its own pseudo-file (even under one label), kept by linecache.checkcache."""
    first = codegen.generate("def f(x):\n    return x * 3\n", "same label")["f"]
    second = codegen.generate("def f(x):\n    return x * 4\n", "same label")["f"]
    linecache.checkcache()
    assert inspect.getsourcefile(first) != inspect.getsourcefile(second)
    assert "return x * 3" in inspect.getsource(first) and "return x * 4" in inspect.getsource(
        second
    )
    step = RK4().bind(FreeBody(FreeBodyParams((2.0, 1.5, 1.0))), 3)
    assert "h_sum = h / 6.0" in inspect.getsource(step)


def test_the_dump_variable_writes_every_generated_source(tmp_path, monkeypatch):
    monkeypatch.setenv(codegen.DUMP_VARIABLE, str(tmp_path / "gen"))
    codegen.generate("def g():\n    return 41 + 1\n", "dumped answer")
    (path,) = (tmp_path / "gen").glob("*dumped_answer.py")
    assert "return 41 + 1" in path.read_text()


# ----------------------------------------------------------------- bit for bit
def euler_reference(f, y, u, h):
    """Forward Euler as it was written by hand: y + h k."""
    k = f(y, u)
    return tuple(a + h * b for a, b in zip(y, k))


def rk4_reference(f, y, u, h):
    """Classical RK4 as it was written by hand: stages at y + (h/2) k, the sum h/6 (a + 2 (b + c) +
    d)."""
    hh = 0.5 * h
    a = f(y, u)
    b = f(tuple(p + hh * q for p, q in zip(y, a)), u)
    c = f(tuple(p + hh * q for p, q in zip(y, b)), u)
    d = f(tuple(p + h * q for p, q in zip(y, c)), u)
    h6 = h / 6.0
    return tuple(p + h6 * (ka + 2.0 * (kb + kc) + kd) for p, ka, kb, kc, kd in zip(y, a, b, c, d))


def _systems():
    rng = np.random.default_rng(0)
    free = FreeBody(FreeBodyParams((2.0, 1.5, 1.0)))
    free_att = FreeBody(FreeBodyParams((2.0, 1.5, 1.0)), attitude=True)
    top = HeavyTop(HeavyTopParams())
    tippe = TippeTop(TippeTopParams(), "gliding")
    q = rng.normal(size=4)
    q = tuple(q / np.linalg.norm(q))
    g = rng.normal(size=3)
    g = tuple(g / np.linalg.norm(g))
    yield free, tuple(rng.normal(size=3)), tuple(rng.normal(size=3))
    yield free_att, tuple(rng.normal(size=3)) + q, tuple(rng.normal(size=3))
    yield top, tuple(rng.normal(size=3)) + g, tuple(rng.normal(size=3))
    yield tippe, tippe.state((0.0, 0.0), q, (3.0, -2.0, 150.0)), (0.5, -0.2, 0.3, 0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    "scheme,reference", [(Euler(), euler_reference), (RK4(), rk4_reference)], ids=["euler", "rk4"]
)
def test_tableau_steps_equal_the_hand_written_formulas_bit_for_bit(scheme, reference):
    """Generated from the tableaus, Euler's and RK4's steps make the hand-written formulas'
    operations in their order: equal with ==, on floats and arrays, in every flavour (step,
    bound step, the compiled kernel's pure step)."""
    for system, y, u in _systems():
        want = system.normalize(reference(system.rhs, y, u, 1e-3))
        assert scheme.step(system, y, u, 1e-3) == want
        bound = scheme.bind(system, system.dim)(y, u, 1e-3)
        assert bound == (
            want if getattr(system, "needs_projection", True) else reference(system.rhs, y, u, 1e-3)
        )
        y2 = tuple(2.0 * c for c in y)
        want2 = system.normalize(reference(system.rhs, y2, u, 1e-3))
        batch = tuple(np.array([c, c2]) for c, c2 in zip(y, y2))
        ub = tuple(np.array([c, c]) for c in u)
        got = scheme.step(system, batch, ub, 1e-3)
        assert all(g[0] == w and g[1] == w2 for g, w, w2 in zip(got, want, want2))
        pure = scheme.kernel_step(system)
        if pure is not None:
            step, params = pure
            # (a system that projects, projects in the pure step too, as in the bound one)
            assert step(params, y, u, 1e-3) == (
                want
                if getattr(system, "needs_projection", True)
                else reference(system.rhs, y, u, 1e-3)
            )


@pytest.mark.parametrize("scheme", [Euler(), RK4()], ids=["euler", "rk4"])
def test_the_compensated_step_is_the_plain_step_and_what_its_sum_rounded_away(scheme):
    """The compensated flavour (a tolerance's steps: Kahan's summation, the compensation carried
    by the caller) from a zero compensation gives the plain step's state bit for bit, bound and
    pure, on floats and arrays, and a compensation of at most about half an ulp of the new
    state: what adding the increment rounded away. For Euler on the free body, whose increment
    ``h f(y)`` the test forms itself, state plus compensation is ``y + h f(y)`` exactly."""
    h = 1e-3
    for system, y, u in _systems():
        zero = (0.0,) * system.dim
        plain, comp = (
            scheme.bind(system, system.dim),
            scheme.bind(system, system.dim, compensated=True),
        )
        t, c = comp(y, zero, u, h)
        assert t == plain(y, u, h)
        assert any(ci != 0.0 for ci in c) and all(abs(ci) <= math.ulp(ti) for ti, ci in zip(t, c))
        pure, pure_c = scheme.kernel_step(system), scheme.kernel_step(system, compensated=True)
        assert (pure is None) == (pure_c is None)
        if pure_c is not None:
            assert pure_c[0](pure_c[1], y, zero, u, h) == (t, c)
        batch, ub = tuple(np.array([v, v]) for v in y), tuple(np.array([v, v]) for v in u)
        tb, cb = comp(batch, zero, ub, h)
        assert all(a[1] == b for a, b in zip(tb, t)) and all(a[0] == b for a, b in zip(cb, c))
        if isinstance(scheme, Euler) and not getattr(system, "needs_projection", True):
            k = system.rhs(y, u)
            assert all(
                Fraction(ti) + Fraction(ci) == Fraction(yi) + Fraction(h * ki)
                for yi, ki, ti, ci in zip(y, k, t, c)
            )


# ----------------------------------------------------------------- a new scheme is a tableau
@dataclass(frozen=True)
class Kutta3(ExplicitRungeKutta):
    """Kutta's third-order method, defined only by its tableau here."""

    name = "kutta3"
    tableau = ButcherTableau(
        a=((), (Fraction(1, 2),), (-1, 2)),
        b=(Fraction(1, 6), Fraction(2, 3), Fraction(1, 6)),
        c=(0, Fraction(1, 2), 1),
    )
    order = 3
    evaluations = 3
    region = RK4.region


@dataclass(frozen=True)
class ThreeEighths(ExplicitRungeKutta):
    """The 3/8 rule (order 4): rows with several coefficients."""

    name = "three_eighths"
    tableau = ButcherTableau(
        a=((), (Fraction(1, 3),), (Fraction(-1, 3), 1), (1, -1, 1)),
        b=(Fraction(1, 8), Fraction(3, 8), Fraction(3, 8), Fraction(1, 8)),
        c=(0, Fraction(1, 3), Fraction(2, 3), 1),
    )
    order = 4
    evaluations = 4
    region = RK4.region


@pytest.mark.parametrize("scheme", [Euler(), Kutta3(), ThreeEighths(), RK4()], ids=lambda s: s.name)
def test_a_tableau_integrates_at_its_order(scheme):
    """The fitted slope of the error against the exact elliptic solution (free body, 2 s,
    tilted intermediate-axis spin) matches the tableau's order within 0.15."""
    params = FreeBodyParams((2.0, 1.5, 1.0))
    system = FreeBody(params)
    y0 = (0.3, 1.5, 0.2)
    t_end = 2.0
    exact = np.array(exact_solution(params.inertia, y0, t_end), dtype=float)
    errors, steps = [], [40, 80, 160] if scheme.order > 1 else [4000, 8000, 16000]
    for n in steps:
        y = y0
        for _ in range(n):
            y = scheme.step(system, y, None, t_end / n)
        errors.append(np.linalg.norm(np.array(y) - exact))
    slope = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - scheme.order) < 0.15, (scheme.name, slope, errors)


def test_a_new_tableau_needs_nothing_else():
    """Kutta3 runs in an env (guarded by its region), as a bound step and as a compiled pure
    step."""
    from rbenvs.envs import FreeRigidBodyEnv

    env = FreeRigidBodyEnv(integrator=Kutta3())
    env.reset(seed=0)
    info = env.step(np.zeros(3, dtype=np.float32))[4]
    assert info["numerical_failure"] is False and env.integrator.name == "kutta3"
    assert Kutta3().kernel_step(env.system) is not None


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(a=((), (1,)), b=(1,), c=(0,)), "s rows"),
        (dict(a=((), (1, 0)), b=(0.5, 0.5), c=(0, 1)), "strictly lower triangular"),
        (dict(a=((), (1,)), b=(0.5, 0.5), c=(0, 0.5)), "sum to its node"),
        (dict(a=((), (1,)), b=(0.5, 0.6), c=(0, 1)), "sum to 1"),
    ],
)
def test_bad_tableaus_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ButcherTableau(**kwargs)


def test_the_registry_schemes_are_tableaus():
    for name in ("euler", "rk4"):
        scheme = get_integrator(name)
        assert (
            isinstance(scheme, ExplicitRungeKutta) and scheme.tableau.stages == scheme.evaluations
        )
    assert math.isclose(float(sum(RK4.tableau.b)), 1.0)
