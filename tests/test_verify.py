"""rbenvs verify: passes on the real simulator and catches broken ones."""

import json

import pytest

from rbenvs import verify
from rbenvs.dynamics import free_body as fb


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
