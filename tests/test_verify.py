"""rbenvs verify: passes on the real simulator and catches broken ones."""

import dataclasses
import json

import pytest

from rbenvs import verify
from rbenvs.dynamics import HeavyTopParams
from rbenvs.dynamics import free_body as fb
from rbenvs.dynamics import heavy_top as ht


def failed(checks):
    return [c for c in checks if not c.passed]


def test_quick_verify_passes_and_writes_json(tmp_path, capsys):
    path = tmp_path / "report.json"
    assert verify.main(["--quick", "--no-progress", "--integrator", "rk4", "--integrator", "exact", "--json", str(path)]) == 0
    out = capsys.readouterr().out
    assert "0 failed" in out and "FAIL" not in out.replace("0 failed", "")
    report = json.loads(path.read_text())
    assert report and all(r["passed"] for r in report)
    assert {r["integrator"] for r in report} == {"rk4", "exact"}
    for key in ("system", "integrator", "check", "predicted", "measured", "tolerance"):
        assert key in report[0]


def test_flipped_torque_sign_is_caught(monkeypatch):
    original = fb.FreeBody.rhs

    def flipped(self, y, u):
        return original(self, y, None if u is None else tuple(-c for c in u))

    monkeypatch.setattr(fb.FreeBody, "rhs", flipped)
    bad = failed(verify.free_body_checks(["rk4"], n_cases=1))
    assert any("torque" in c.check for c in bad)


def test_wrong_inertia_ordering_is_caught(monkeypatch):
    # A simulator that reverses the moments (I3, I2, I1) while the oracle uses (I1, I2, I3).
    original = fb.FreeBody.__init__

    def reversed_moments(self, params, attitude=False):
        original(self, fb.FreeBodyParams(tuple(reversed(params.inertia))), attitude)

    monkeypatch.setattr(fb.FreeBody, "__init__", reversed_moments)
    bad = failed(verify.free_body_checks(["rk4"], n_cases=1))
    assert any("exact solution" in c.check for c in bad)
    assert any("axis" in c.check for c in bad)


def test_flipped_gyroscopic_sign_is_caught(monkeypatch):
    # Time-reversed Euler equations keep every invariant and the growth rate's magnitude:
    # only the comparison with the exact solution can see it.
    original = fb.FreeBody.rhs

    def flipped(self, y, u):
        d = original(self, y, None)
        out = tuple(-c for c in d)
        return out if u is None else tuple(a + b for a, b in zip(out, u))

    monkeypatch.setattr(fb.FreeBody, "rhs", flipped)
    bad = failed(verify.free_body_checks(["rk4"], n_cases=1))
    assert [c.check for c in bad] and all(c.integrator == "rk4" for c in bad)
    assert any("exact solution" in c.check for c in bad)


def test_failing_row_prints_replay_parameters(capsys):
    check = verify.Check("free_body", "rk4", "demo", 1.0, 2.0, 0.1, case={"inertia": [1, 2, 3]})
    verify.print_table([check])
    out = capsys.readouterr().out
    assert "FAIL" in out and "replay with {'inertia': [1, 2, 3]}" in out and "0 passed, 1 failed" in out


@pytest.mark.parametrize("bad", [[], ["--integrator", "leapfrog"]])
def test_cli_entry(bad, capsys):
    if bad:
        with pytest.raises(ValueError, match="integrator"):
            verify.main(["--quick", "--no-progress"] + bad)


# ---------------------------------------------------------------------------------------------
# heavy top


class FlippedGravity(ht.HeavyTop):
    """A simulator whose gravity pulls up: torque ``-M g l Gamma x chi`` in rhs and kick alike."""

    def __init__(self, params, attitude=False):
        super().__init__(params, attitude)
        flipped = dataclasses.replace(params)
        object.__setattr__(flipped, "weight", tuple(-w for w in params.weight))
        self.params = flipped


class HeavierTop(ht.HeavyTop):
    """A simulator whose gravity torque is 10% too strong (a wrong ``M g l``, say)."""

    def __init__(self, params, attitude=False):
        super().__init__(params, attitude)
        heavier = dataclasses.replace(params)
        object.__setattr__(heavier, "weight", tuple(1.1 * w for w in params.weight))
        self.params = heavier


@pytest.mark.parametrize("integrator", ["rk4", "splitting"])
def test_heavy_top_checks_pass(integrator):
    checks = verify.heavy_top_checks([integrator], n_tops=1)
    assert checks and not failed(checks)
    assert {c.system for c in checks} == {"heavy_top"}
    names = " ".join(c.check for c in checks)
    for word in ("critical spin by bisection", "regular precession held", "fast top: nutation amplitude",
                 "fast top: nutation period", "fast top: mean precession rate", "energy drift", "Pi.Gamma drift",
                 "|Gamma|", "1.2 x critical", "0.5 x critical: growth rate"):
        assert word in names
    bisection = next(c for c in checks if "bisection" in c.check)
    # the 50 t_g horizon puts the measured threshold 0.1-0.2% below the theorem's (module docstring)
    assert 0.0 < (bisection.predicted - bisection.measured) / bisection.predicted < 3e-3


@pytest.mark.parametrize("integrator", ["rk4", "splitting"])
def test_flipped_gravity_is_caught(integrator):
    bad = {c.check for c in failed(verify.heavy_top_checks([integrator], n_tops=1, system_class=FlippedGravity))}
    assert any("bisection" in c for c in bad)
    assert any("regular precession held" in c for c in bad)
    assert any("growth rate" in c for c in bad)
    assert any("fast top" in c for c in bad)


def test_ten_percent_too_much_gravity_is_caught():
    bad = {c.check for c in failed(verify.heavy_top_checks(["rk4"], n_tops=1, system_class=HeavierTop))}
    assert any("bisection" in c for c in bad)  # n_c ~ sqrt(M g l): 5% off
    assert any("regular precession" in c for c in bad)
    assert any("fast top" in c for c in bad)
    # the invariants hold for any gravity: they are no test of it
    assert not any("drift" in c or "Gamma|" in c for c in bad)


def test_failing_heavy_top_row_carries_its_parameters():
    bad = failed(verify.heavy_top_checks(["rk4"], n_tops=1, system_class=FlippedGravity))
    case = next(c for c in bad if "bisection" in c.check).case
    for key in ("inertia", "mass", "length", "gravity", "start tilt", "fall tilt", "T"):
        assert key in case
    # replay: the same parameters rebuild the same top
    params = HeavyTopParams(inertia=tuple(case["inertia"]), mass=case["mass"], length=case["length"], gravity=case["gravity"])
    assert params.is_lagrange


def test_heavy_top_has_no_exact_rows_and_system_filter(tmp_path):
    assert verify.run_checks(systems=("heavy_top",), integrators=["exact"], quick=True, show_progress=False) == []
    path = tmp_path / "top.json"
    assert verify.main(["--quick", "--no-progress", "--system", "heavy_top", "--integrator", "splitting", "--json", str(path)]) == 0
    report = json.loads(path.read_text())
    assert report and {r["system"] for r in report} == {"heavy_top"} and all(r["passed"] for r in report)
    with pytest.raises(SystemExit):
        verify.main(["--system", "tippe_top"])


def test_heavy_top_ranges_are_physical_and_seeded():
    import numpy as np

    a = verify.heavy_top.random_tops(np.random.default_rng(3), 20)
    b = verify.heavy_top.random_tops(np.random.default_rng(3), 20)
    assert a == b
    for p in a:
        ratio = p.inertia[2] / p.inertia[0]
        assert p.is_lagrange and 0.5 <= ratio <= 1.5
