"""rbenvs verify on other simulators (issue 23): the contract, a user's step function, MuJoCo."""

import json

import numpy as np
import pytest

from rbenvs import testing, verify
from rbenvs.verify.simulator import IntegratorSimulator, parse_simulator

INTERMEDIATE = "intermediate axis: growth rate [1/s]"


def euler_equations_rk4(problem, y, u, dt):
    """An engine written apart from rbenvs: classical RK4 on Euler's equations, on floats."""
    if problem.system != "free_body":
        raise NotImplementedError("this engine has the free body only")
    i1, i2, i3 = problem.params.inertia
    t1, t2, t3 = (0.0, 0.0, 0.0) if u is None else u

    def f(p1, p2, p3):  # dPi/dt = Pi x Omega + tau
        w1, w2, w3 = p1 / i1, p2 / i2, p3 / i3
        return p2 * w3 - p3 * w2 + t1, p3 * w1 - p1 * w3 + t2, p1 * w2 - p2 * w1 + t3

    k1 = f(*y)
    k2 = f(*(a + 0.5 * dt * k for a, k in zip(y, k1)))
    k3 = f(*(a + 0.5 * dt * k for a, k in zip(y, k2)))
    k4 = f(*(a + dt * k for a, k in zip(y, k3)))
    return tuple(
        a + dt / 6.0 * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(y, k1, k2, k3, k4)
    )


def without_gyroscopic_term(problem, y, u, dt):
    """The Brax bug: Euler's equations without ``Pi x Omega`` (dPi/dt = tau)."""
    if problem.system != "free_body":
        raise NotImplementedError("this engine has the free body only")
    return tuple(np.array(y) + dt * (np.zeros(3) if u is None else np.array(u)))


# dt = 0.02 s is rbenvs' own rk4 verify step on the free body (|Omega| = 1 rad/s): the checks
# cost 1/20 of what they cost at 1e-3, and the tolerances scale to it by the declared order
def test_a_correct_step_function_passes_and_what_it_lacks_reads_n_a():
    rows = testing.verify(euler_equations_rk4, dt=0.02, order=4)
    free = [r for r in rows if r.system == "free_body"]
    assert free and all(r.applies and r.passed for r in free), testing.failures(free)
    assert any(r.check == INTERMEDIATE for r in free)
    others = [r for r in rows if r.system != "free_body"]
    assert others and all(not r.applies and r.passed and r.result == "n/a" for r in others)
    # declined by the engine, but for the rows of rbenvs' own tippe-top model (hops, t90)
    assert all("free body only" in r.reason or "rbenvs' own model" in r.reason for r in others)
    assert sum("free body only" in r.reason for r in others) >= 11 + 8
    # the scaled tolerances: rk4's at its own step (1e-6 on the exact solution), plus round-off
    exact = next(r for r in free if r.check.startswith("exact solution"))
    assert 1e-6 <= exact.tolerance < 1.1e-6


def test_dropping_the_gyroscopic_term_fails_the_intermediate_axis():
    rows = testing.verify(without_gyroscopic_term, systems=("free_body",), dt=0.02, order=4)
    bad = {r.check for r in rows if not r.passed}
    assert INTERMEDIATE in bad
    assert any(c.startswith("exact solution") for c in bad)
    # it conserves what a missing term cannot change: those rows are no test of it
    assert "energy drift (rel.)" not in bad and "|Pi| drift (rel.)" not in bad


def test_rbenvs_through_the_adapter_at_a_fixed_step_matches_its_own_step():
    """The adapter for rbenvs' own rk4 at dt = 0.02 (its verify step) gives the default rows'
    numbers (but the torque balance's, which rbenvs' own run samples at 0.01 s)."""
    own = verify.free_body_checks(["rk4"], n_cases=1)
    fixed = verify.free_body_checks([IntegratorSimulator("rk4", dt=0.02)], n_cases=1)
    assert [(r.check, r.measured) for r in own if "torque" not in r.check] == [
        (r.check, r.measured) for r in fixed if "torque" not in r.check
    ]
    assert all(r.passed for r in fixed)


def test_simulator_specs(tmp_path, monkeypatch):
    (sim,) = parse_simulator("rbenvs:integrator=rk4,dt=0.02")
    assert sim.dt == 0.02 and sim.order == 4
    assert [s.name for s in parse_simulator("rbenvs:integrator=euler+rk4")] == ["euler", "rk4"]
    (tmp_path / "my_engine.py").write_text(
        "import numpy as np\n\ndef step(problem, y, u, dt):\n    raise "
        "NotImplementedError('nothing')\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    (sim,) = parse_simulator("my_engine:step,dt=0.5,order=2,name=mine")
    assert (sim.dt, sim.order, sim.name) == (0.5, 2, "mine")
    for bad in (
        "nosuchmodule_xyz:f",
        "my_engine:nope",
        "my_engine:step,dt",
        "my_engine:step,colour=red",
        "rbenvs:dt=x",
        "bogus",
    ):
        with pytest.raises(ValueError):
            parse_simulator(bad)


def test_cli_with_a_step_function_writes_json_and_fails_on_failure(tmp_path, monkeypatch, capsys):
    module = tmp_path / "broken_engine.py"
    module.write_text(
        "import numpy as np\n\ndef step(problem, y, u, dt):\n"
        "    if problem.system != 'free_body':\n"
        "        raise NotImplementedError('free body only')\n"
        "    return tuple(np.array(y) + dt * (np.zeros(3) if u is None else np.array(u)))\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    path = tmp_path / "report.json"
    status = verify.main(
        [
            "--quick",
            "--no-progress",
            "--system",
            "free_body",
            "--system",
            "heavy_top",
            "--simulator",
            "broken_engine:step,dt=0.02,order=4",
            "--json",
            str(path),
        ]
    )
    assert status == 1
    out = capsys.readouterr().out
    assert "n/a (free body only)" in out and "FAIL" in out
    report = json.loads(path.read_text())
    assert {r["result"] for r in report} == {"PASS", "FAIL", "n/a"}
    assert any(r["check"] == INTERMEDIATE and r["result"] == "FAIL" for r in report)
    # --comparison: the same rows as one Markdown table, a report: exit 0 though a row fails
    status = verify.main(
        [
            "--quick",
            "--no-progress",
            "--system",
            "free_body",
            "--simulator",
            "broken_engine:step,dt=0.02,order=4",
            "--simulator",
            "rbenvs:integrator=rk4,dt=0.02",
            "--comparison",
        ]
    )
    lines = capsys.readouterr().out.strip().splitlines()
    assert status == 0 and all(line.startswith("|") for line in lines)
    assert lines[0].count("`") == 4  # a column per simulator
    row = next(line for line in lines if INTERMEDIATE.replace("|", "&#124;") in line)
    assert row.count("FAIL") == 1 and row.count("PASS") == 1  # the broken engine fails, rk4 passes


def test_cli_refuses_mixing_integrator_and_simulator():
    with pytest.raises(SystemExit):
        verify.main(["--simulator", "rbenvs", "--integrator", "rk4"])
    with pytest.raises(SystemExit):
        verify.main(["--comparison"])


def test_comparison_is_one_markdown_table_a_column_per_simulator():
    from rbenvs.verify.comparison import comparison_table

    rows = [
        verify.Check("free_body", "a", "x", 0.0, 1e-3, 1e-2),
        verify.Check("free_body", "b", "x", 0.0, 1.0, 1e-2),
        verify.Check("free_body", "a", "y", 0.0, 0.0, 1e-2),
    ]
    lines = comparison_table(rows)
    assert lines[0] == "| system | check | `a` | `b` |" and all(
        line.startswith("|") for line in lines
    )
    assert (
        "| free_body | x | PASS 0.001 | FAIL 1 |" in lines
        and "| free_body | y | PASS 0 | - |" in lines
    )
    assert lines[-1] == "| all | passed / failed / n/a | 2 / 0 / 0 | 0 / 1 / 0 |"


# ---------------------------------------------------------------------------------------------
# MuJoCo (the `mujoco` extra)


def test_mujoco_at_a_coarse_step_finds_what_is_known():
    """At dt = 0.01 s (|Omega| dt = 0.01 on the free body): RK4's free body passes every row;
    Euler's stable-axis orbits grow (its outward drift) beyond the 2% of the exact orbit over
    50 turns; both find the heavy top's threshold."""
    pytest.importorskip("mujoco")
    rows = testing.verify("mujoco:integrator=Euler+RK4,dt=0.01", systems=("free_body", "heavy_top"))
    by = {}
    for r in rows:
        by.setdefault((r.integrator.split()[1], r.system), []).append(r)
    assert all(r.passed for r in by[("RK4", "free_body")]), testing.failures(
        by[("RK4", "free_body")]
    )
    assert any(
        "axis: max transverse" in r.check and not r.passed for r in by[("Euler", "free_body")]
    )
    for name in ("Euler", "RK4"):
        assert any(
            r.check.startswith("critical spin") and r.passed for r in by[(name, "heavy_top")]
        )


def test_mujoco_tippe_top_rows_and_what_it_does_not_model():
    pytest.importorskip("mujoco")
    rows = testing.verify("mujoco:integrator=RK4+implicitfast,dt=1e-3", systems=("tippe_top",))
    jellett = [r for r in rows if r.check.startswith("Jellett held (coulomb)")]
    assert len(jellett) == 2 and all(r.applies and np.isfinite(r.measured) for r in jellett)
    na = {r.check.split(":")[0] for r in rows if not r.applies}
    assert {"Jellett held (viscous)", "Jellett held (rolling)", "Jellett held (moving table)"} <= na


# ---------------------------------------------------------------------------------------------
# rows at rates where a step of 1e-3 matters; the physical bound on the step-scaled tolerances

from rbenvs.verify import free_body as fb  # noqa: E402
from rbenvs.verify import heavy_top as ht  # noqa: E402
from rbenvs.verify.common import ENERGY_BOUND, MOMENTUM_BOUND, ROUND_OFF, scaled_tolerance  # noqa: E402
from rbenvs.verify.simulator import CallableSimulator, as_simulators  # noqa: E402

FAST_ROWS = set(fb.FAST_ROWS.values())


def _fast_tumble(sim, seed=0):
    return fb._fast_tumble_checks(
        sim, fb._fast_tumble_cases(np.random.default_rng([seed, 1]), 1), None
    )


def _small_top(sim, seed=0):
    (top,) = ht._random_small_tops(np.random.default_rng([seed, 3]), 1)
    setting = ht.HEAVY_TOP_SETTINGS[
        sim.integrator.name if sim.dt is None else verify.common.reference_scheme(sim.order)
    ]
    rows = []
    ht.threshold_checks(ht.HeavyTop(top.params), sim, setting, top, rows.append)
    return rows


def test_the_fast_rows_pass_on_rbenvs_own_integrators():
    """The fast tumble (30 rad/s, 5 s) and the small fast top (critical spin ~100 rad/s) pass on
    rbenvs' own schemes at their verify steps: rk4 on the tumble, rk4 and the splitting on the
    top, rk4 from two seeds (the others run in `rbenvs verify --quick`)."""
    for seed in (0, 1):
        rows = _fast_tumble(as_simulators(["rk4"])[0], seed)
        assert {r.check for r in rows} == FAST_ROWS and all(r.passed for r in rows), (
            testing.failures(rows)
        )
        assert max(r.measured for r in rows) < 1e-7  # rk4 at its step
    for seed, names in ((0, ("rk4", "splitting")), (1, ("rk4",))):
        rows = [r for name in names for r in _small_top(as_simulators([name])[0], seed)]
        assert len(rows) == 3 * len(names) and all(r.passed for r in rows), testing.failures(rows)
        assert 70.0 < rows[0].predicted < 160.0  # a small fast top: the critical spin ~100 rad/s


def test_dropping_the_gyroscopic_term_fails_the_fast_tumble_but_keeps_its_invariants():
    rows = {
        r.check: r
        for r in _fast_tumble(CallableSimulator(without_gyroscopic_term, dt=1e-3, order=4))
    }
    assert not rows[fb.FAST_ROWS["exact"]].passed and rows[fb.FAST_ROWS["exact"]].measured > 0.5
    assert rows[fb.FAST_ROWS["energy"]].passed and rows[fb.FAST_ROWS["momentum"]].passed
    # and a correct engine at the same step passes all three
    assert all(
        r.passed for r in _fast_tumble(CallableSimulator(euler_equations_rk4, dt=1e-3, order=4))
    )


def test_a_first_order_tolerance_is_bounded_by_the_physics():
    """A first-order engine at a step 100x Euler's verify step was held to 100x Euler's
    tolerance (2 = 200% on the free body's energy); the bound holds it to 2% of |Pi| and 4% of
    the energy. An engine that damps |Pi| by 3% in 10 s (energy 6%) now fails both rows."""
    h_ref, _, tol_ref = fb.FREE_BODY_SETTINGS["euler"]
    assert (
        scaled_tolerance(tol_ref, 100 * h_ref, h_ref, 1, 1, ENERGY_BOUND)
        == ENERGY_BOUND + ROUND_OFF
    )
    assert scaled_tolerance(tol_ref, 0.1 * h_ref, h_ref, 1, 1, ENERGY_BOUND) == pytest.approx(
        0.1 * tol_ref + ROUND_OFF
    )
    from rbenvs.integrators import get_integrator

    rk4 = get_integrator("rk4")

    def damped(problem, y, u, dt):
        if problem.system != "free_body":
            raise NotImplementedError("free body only")
        return tuple(np.array(rk4.step(problem.model, y, u, dt)) * (1.0 - 0.003 * dt))

    rows = {
        r.check: r
        for r in testing.verify(damped, systems=("free_body",), dt=0.02, order=1)
        if "fast" not in r.check
    }
    for check, bound in (
        ("energy drift (rel.)", ENERGY_BOUND),
        ("|Pi| drift (rel.)", MOMENTUM_BOUND),
    ):
        assert not rows[check].passed and rows[check].tolerance == pytest.approx(bound, abs=1e-9)


def test_mujoco_at_1e_3_damps_the_fast_tumble_and_its_euler_family_misses_the_threshold():
    """What is known of MuJoCo at dt = 1e-3 (docs/verification.md): implicitfast damps the fast
    tumble (energy and |Pi| lost beyond the physical bound) and lets Jellett's integral drift
    through a tippe top's inversion; Euler, implicit and implicitfast miss the small fast top's
    threshold; RK4 passes all three."""
    pytest.importorskip("mujoco")
    from rbenvs.verify.mujoco_adapter import MujocoSimulator

    sims = {
        name: MujocoSimulator(name, 1e-3) for name in ("RK4", "implicitfast", "implicit", "Euler")
    }
    rows = {r.check: r for r in _fast_tumble(sims["implicitfast"])}
    energy = rows[fb.FAST_ROWS["energy"]]
    assert (
        not energy.passed
        and energy.measured > 0.1
        and energy.tolerance == pytest.approx(ENERGY_BOUND, abs=1e-9)
    )
    assert (
        max(energy.case["energy change at T (rel.)"]) < -0.05
    )  # every start loses energy: damping
    assert all(not r.passed for r in rows.values())
    rk4 = _fast_tumble(sims["RK4"])
    assert all(r.passed for r in rk4) and max(r.measured for r in rk4) < 1e-7, testing.failures(rk4)
    assert all(r.passed for r in _small_top(sims["RK4"]))
    # Jellett's integral through a whole inversion of the default top: the Euler family drifts
    # beyond the 2% bound, RK4 keeps it
    from rbenvs.verify.tippe_top.inversion import _inversion_jellett_row

    row = _inversion_jellett_row(sims["implicitfast"])
    assert (
        not row.passed
        and row.measured > 0.03
        and row.tolerance == pytest.approx(MOMENTUM_BOUND, abs=1e-9)
    )
    assert row.case["max tilt [deg]"] > 150.0  # it did invert
    row = _inversion_jellett_row(sims["RK4"])
    assert row.passed and row.measured < 1e-4
    for name in ("Euler", "implicitfast", "implicit"):
        bisection, above, below = _small_top(sims[name])
        assert not bisection.passed and not above.passed, name  # the threshold missed
        assert above.measured > 0.1 or name == "implicit"  # Euler's family: the stable top falls


USER_MODULE = """
def unpacks_two(problem, y, u, dt):
    pi, gamma = y  # reads the heavy top's state as (Pi, Gamma): it is one flat 6-tuple
    return y


def nests(problem, y, u, dt):
    return (y[:3], y[3:])
"""


@pytest.mark.parametrize(
    "function, expected",
    [
        (
            "unpacks_two",
            [
                r"the simulator function usersim\.unpacks_two\(problem\[heavy_top\], y, u, 0\.01\) "
                r"raised ValueError; its traceback:",
                r'File ".*usersim\.py", line 3, in unpacks_two',
                r"pi, gamma = y",
                r"ValueError: too many values to unpack",
            ],
        ),
        (
            "nests",
            [
                r"the simulator function usersim\.nests\(problem\[heavy_top\], y, u, 0\.01\) "
                r"returned \(\(.*\)\) \(tuple\): "
                r"expected a flat tuple of 6 floats \(Pi1, Pi2, Pi3, Gamma1, Gamma2, Gamma3\)"
            ],
        ),
    ],
)
def test_a_broken_step_function_is_shown_from_the_users_side(tmp_path, function, expected):
    """The installed ``rbenvs`` command (not ``python -m``) imports the module from the current
    folder; a function that raises gets its own traceback lines, one that returns the wrong shape
    the layout it should have returned, each naming the function and the call (exit status 2)."""
    import os
    import re
    import subprocess
    import sys

    (tmp_path / "usersim.py").write_text(USER_MODULE)
    script = os.path.join(os.path.dirname(sys.executable), "rbenvs")
    out = subprocess.run(
        [
            script,
            "verify",
            "--quick",
            "--no-progress",
            "--system",
            "heavy_top",
            "--simulator",
            f"usersim:{function},dt=0.01",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert out.returncode == 2, (out.returncode, out.stderr[-2000:])
    assert (
        "No module named" not in out.stderr and "rbenvs/verify" not in out.stderr
    )  # (no rbenvs frame in what the user reads)
    for pattern in expected:
        assert re.search(pattern, out.stderr), (pattern, out.stderr)
