"""``rbenvs bench accuracy``: the measured orders, drifts and the command's outputs."""

from __future__ import annotations

import dataclasses
import json

import pytest

from rbenvs.bench import accuracy
from rbenvs.cli import main as cli_main
from rbenvs.integrators import get_integrator
from rbenvs.verify.common import ROUND_OFF

CASES = {c.key: c for c in accuracy.CASES}

# Small grids: three halvings in the asymptotic range of each scheme (errors 1e-9 to 1e-2).
HORIZON = {"free_body": 10.0, "heavy_top": 1.0, "tippe_top": 0.05}
GRIDS = {
    ("free_body", "euler"): (0.0125, 0.00625, 0.003125),
    ("free_body", "rk4"): (0.2, 0.1, 0.05),
    ("free_body", "splitting"): (0.05, 0.025, 0.0125),
    ("heavy_top", "euler"): (4e-5, 2e-5, 1e-5),
    ("heavy_top", "rk4"): (0.01, 0.005, 0.0025),
    ("heavy_top", "splitting"): (0.01, 0.005, 0.0025),
    ("tippe_top", "euler"): (1e-5, 5e-6, 2.5e-6),
    ("tippe_top", "rk4"): (1e-3, 5e-4, 2.5e-4),
}


def small(key, name):
    grid = GRIDS[(key, name)]
    return dataclasses.replace(CASES[key], horizon=HORIZON[key], grid=grid, euler_grid=grid)


@pytest.mark.parametrize("key, name", list(GRIDS))
def test_measured_order_matches_declared(key, name):
    row = accuracy.convergence(small(key, name), name, min_time=1e-3)
    assert row["order"] is not None, row["points"]
    assert abs(row["order"] - get_integrator(name).order) < 0.3, row
    # the error falls with the step at every halving (no point is past the reference's floor)
    errors = [p["error"] for p in row["points"]]
    assert all(b < a for a, b in zip(errors, errors[1:])), errors


def test_exact_free_flow_is_at_round_off():
    row = accuracy.convergence(small("free_body", "rk4"), "exact", min_time=1e-3)
    assert max(p["error"] for p in row["points"]) < 1e-12, row["points"]
    assert row["order"] is None  # nothing to fit at round-off


def test_splitting_keeps_momentum_norm_and_bounds_energy_while_rk4_drifts():
    case = CASES["free_body"]
    steps = 10**4
    split = accuracy.drift(case, "splitting", steps)
    rk4 = accuracy.drift(case, "rk4", steps)
    # |Pi| is the splitting's Casimir: round-off, growing at most like sqrt(steps)
    assert split["drift_long"]["|Pi|"] < ROUND_OFF * steps**0.5
    # its energy error does not grow from 1e3 to 1e4 steps (bounded: a symplectic scheme)...
    assert split["drift_long"]["energy"] < 1.5 * split["drift_short"]["energy"]
    # ...while rk4's grows about linearly with the number of steps
    assert rk4["drift_long"]["energy"] > 5.0 * rk4["drift_short"]["energy"]
    assert split["diverged_at"] is None and rk4["diverged_at"] is None


def test_fit_order_uses_only_the_asymptotic_range():
    hs = [0.1, 0.05, 0.025, 0.0125, 0.00625]
    errors = [
        0.5,
        1e-4 * 16,
        1e-4,
        1e-4 / 16,
        1e-15,
    ]  # one point above the ceiling, one at the floor
    assert accuracy.fit_order(hs, errors, floor=1e-12) == pytest.approx(4.0)
    assert accuracy.fit_order(hs[:3], errors[:3], floor=1e-12) is None  # two usable points


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("accuracy")
    json_path, png_path = out / "accuracy.json", out / "accuracy.png"
    rc = cli_main(
        [
            "bench",
            "accuracy",
            "--quick",
            "--system",
            "free_body",
            "--no-mujoco",
            "--no-progress",
            "--json",
            str(json_path),
            "--plot",
            str(png_path),
        ]
    )
    return rc, json_path, png_path


def test_json_has_the_documented_keys(quick_run):
    rc, json_path, _ = quick_run
    assert rc == 0
    data = json.loads(json_path.read_text())
    assert set(data) >= {"cases", "convergence", "drift", "settings"}
    assert set(data["cases"]["free_body"]) >= {
        "label",
        "horizon",
        "states",
        "drift_h",
        "reference",
        "reference_check",
    }
    names = {
        c["integrator"] for c in data["convergence"] if not c["integrator"].startswith("mujoco ")
    }  # (mujoco: when installed)
    assert names == {"euler", "rk4", "splitting", "exact", "dop853"}
    for c in data["convergence"]:
        assert set(c) >= {"case", "integrator", "declared_order", "order", "points"}
        for p in c["points"]:
            assert set(p) >= {
                "h",
                "steps",
                "error",
                "seconds_per_step",
                "rhs_per_step",
                "seconds_per_simulated_second",
            }
            assert p["seconds_per_step"] > 0
    for d in data["drift"]:
        assert set(d) >= {
            "case",
            "integrator",
            "h",
            "short_steps",
            "long_steps",
            "drift_short",
            "drift_long",
            "diverged_at",
        }
    rk4 = next(c for c in data["convergence"] if c["integrator"] == "rk4")
    assert rk4["points"][0]["rhs_per_step"] == 4


def test_plot_is_written(quick_run):
    rc, _, png_path = quick_run
    assert rc == 0
    assert png_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_scene_errors_follow_the_order_and_pick_a_scheme_that_meets_the_target():
    row = accuracy.run_scenes(["spin_major"], seeds=1, min_time=1e-3)[0]
    euler = [c for c in row["candidates"] if c["integrator"] == "euler"]
    # doubling the substeps halves euler's error over the episode (first order)
    for a, b in zip(euler, euler[1:]):
        assert b["error"] / a["error"] == pytest.approx(0.5, abs=0.1)
    rec = row["recommended"]
    chosen = next(
        c
        for c in row["candidates"]
        if (c["integrator"], c["substeps"]) == (rec["integrator"], rec["substeps"])
    )
    assert chosen["error"] <= accuracy.TARGET


def test_cheapest_picks_the_least_cost_point_within_the_tolerance():
    from rbenvs.bench.accuracy import cheapest

    rows = [
        {
            "integrator": "a",
            "points": [
                {"error": 1e-2, "seconds_per_simulated_second": 1.0},
                {"error": 1e-7, "seconds_per_simulated_second": 4.0},
            ],
        },
        {
            "integrator": "b",
            "points": [
                {"error": 1e-7, "seconds_per_simulated_second": 3.0},
                {"error": 1e-10, "seconds_per_simulated_second": 9.0},
            ],
        },
    ]
    assert cheapest(rows, 1e-1) == ("a", 1.0)
    assert cheapest(rows, 1e-6) == ("b", 3.0)
    assert cheapest(rows, 1e-9) == ("b", 9.0)
    assert cheapest(rows, 1e-12) is None


def test_a_block_zero_in_start_and_reference_is_no_error_unless_the_state_leaves_zero():
    """The accuracy bench's relative error per block (``max(|ref_b|, |y0_b|)`` as the scale): a
    frictionless tippe top spun from rest keeps ``v_G = 0`` exactly, and that block is no error
    (it was 0/0, reported as an infinite reference error); a state that leaves zero there is an
    infinite error, and a block with a scale keeps its relative error."""
    import math

    from rbenvs.bench.accuracy import _block_error
    from rbenvs.dynamics.tippe_top import TippeTop, TippeTopParams

    system = TippeTop(TippeTopParams(), fidelity="frictionless")
    layout = system.layout
    (va, _vb), (wa, _) = layout["velocity"], layout["angular_velocity"]
    y0 = [[0.0] for _ in range(system.dim)]
    y0[layout["attitude"][0]] = [1.0]
    y0[wa + 2] = [150.0]
    ref = [list(c) for c in y0]
    assert _block_error(system, "tippe_frictionless", y0, ref, y0) == 0.0
    moved = [list(c) for c in y0]
    moved[va] = [1e-12]
    assert _block_error(system, "tippe_frictionless", moved, ref, y0) == math.inf
    spun = [list(c) for c in y0]
    spun[wa + 2] = [150.0 * (1 + 1e-9)]
    assert _block_error(system, "tippe_frictionless", spun, ref, y0) == pytest.approx(
        1e-9, rel=1e-6
    )


def test_the_roundoff_table_runs_from_the_cli(monkeypatch, capsys, tmp_path):
    """``rbenvs bench accuracy --roundoff`` (one distance, one start here): the plain and the
    compensated rows, apart and against the exact solution, printed and written as JSON; the
    compensated sum's runs closer together than the plain one's 0.01 rad/s off the axis."""
    from rbenvs.bench import roundoff

    monkeypatch.setattr(roundoff, "OFF", (0.01,))
    monkeypatch.setattr(roundoff, "STARTS", 1)
    path = tmp_path / "roundoff.json"
    assert cli_main(["bench", "accuracy", "--roundoff", "--no-progress", "--json", str(path)]) == 0
    out = capsys.readouterr().out
    assert "roundoff near the intermediate axis" in out and "compensated" in out and "plain" in out
    rows = {r["mode"]: r for r in json.loads(path.read_text())["rows"]}
    assert rows["compensated"]["apart"][0] < rows["plain"]["apart"][0] / 100
    assert rows["compensated"]["exact"][0] < 1e-11


def test_the_floor_table_runs_from_the_cli(monkeypatch, capsys, tmp_path):
    """``rbenvs bench accuracy --floor`` (one start, 0.0001 rad/s off the intermediate axis, at
    1e-9, here): tolerance_check=True ends the episode before the horizon (float64 cannot carry
    1e-9 through it) and every period it returns is within the tolerance of the Taylor solution;
    printed and written as JSON."""
    from rbenvs.bench import floor

    monkeypatch.setattr(floor, "OFF", (1e-4,))
    monkeypatch.setattr(floor, "TOLERANCES", (1e-9,))
    path = tmp_path / "floor.json"
    assert cli_main(["bench", "accuracy", "--floor", "--no-progress", "--json", str(path)]) == 0
    out = capsys.readouterr().out
    assert (
        "tolerance_check near the separatrix" in out
        and "within the tolerance on every period returned: 1 of 1" in out
    )
    rows = json.loads(path.read_text())["rows"]
    assert len(rows) == 1
    for r in rows:
        assert r["end"] is not None and r["end"] < floor.PERIODS and r["worst"] <= r["tolerance"]
