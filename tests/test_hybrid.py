"""The hybrid layer (rbenvs.core.hybrid): events located inside a step, on the integrator's own
step; the dynamics never calls an integrator."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from rbenvs.core.hybrid import Switching, locate
from rbenvs.dynamics.tippe_top import TippeTop, TippeTopParams
from rbenvs.integrators import get_integrator

ROOT = Path(__file__).resolve().parents[1]


def test_locate_finds_the_crossing_to_the_tolerance():
    """A falling mass y(t) = 1 - t^2/2 (exact steps): the crossing at sqrt(2) to 1e-12."""

    def step(y, t):
        return (y[0] + y[1] * t - 0.5 * t * t, y[1] - t)

    y0 = (1.0, 0.0)
    y1 = step(y0, 2.0)
    t, yt = locate(y0, y1, y1[0], step, 2.0, lambda y: y[0], 1e-12)
    assert t == pytest.approx(math.sqrt(2.0), rel=1e-10) and -1e-12 <= yt[0] < 0.0


def test_a_lift_off_is_located_and_counted():
    """A top spinning at 2000 rad/s lifts off within a step: the layer stops at N = 0 (to the
    tolerance), goes to flight, counts the hop; the float and the batch path agree bit for bit."""
    system = TippeTop(TippeTopParams(friction=1.0), "gliding", flight=True)
    integ = get_integrator("rk4")
    q = (math.cos(0.05), math.sin(0.05), 0.0, 0.0)
    y = system.state((0.0, 0.0), q, (0.0, 0.0, 2000.0))
    layer = Switching(system, integ)
    u = (0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    h = 1e-5
    for _ in range(20000):
        y_prev, y_new = y, integ.step(system, y, u, h)
        y = layer.after_step(y_prev, y_new, u, h)
        batch = layer.after_step(
            tuple(np.array([c, c]) for c in y_prev), tuple(np.array([c, c]) for c in y_new), u, h
        )
        assert all(np.array_equal(b, [c, c]) for b, c in zip(batch, y))
        if y[13] == 0.0:
            break
    assert y[13] == 0.0 and y[14] == 1.0  # in flight, one hop
    assert system.constraint_normal_force(y_prev, u) >= 0.0


def test_the_dynamics_never_calls_an_integrator():
    """No module of rbenvs.dynamics imports rbenvs.integrators or calls a ``.step(`` method."""
    for path in (ROOT / "rbenvs" / "dynamics").glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                assert "integrators" not in (node.module or ""), path
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
                assert node.func.attr != "step", (path, node.lineno)
