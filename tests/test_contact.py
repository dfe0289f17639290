"""Friction laws as objects (rbenvs.dynamics.contact): each law is one class, read by the tippe
top's vector field, its env's choices and its step guard."""

import math

import numpy as np
import pytest
from conftest import HalfViscous

from rbenvs.dynamics import contact
from rbenvs.dynamics.contact import FRICTION_LAWS, Coulomb, Viscous
from rbenvs.dynamics.tippe_top import TippeTop, TippeTopParams
from rbenvs.envs import TippeTopEnv
from rbenvs.integrators import get_integrator


def test_coulomb_and_viscous_coefficients_and_stiffness():
    c, v = Coulomb(), Viscous()
    # Coulomb: |F| / N -> mu at slips far above eps, -> mu |v| / eps far below
    assert c.coefficient(0.3, 10.0, 0.0, 0.0, 1e-3) * 10.0 == pytest.approx(-0.3, rel=1e-8)
    assert c.coefficient(0.3, 1e-6, 0.0, 0.0, 1e-3) * 1e-6 == pytest.approx(-0.3 * 1e-3, rel=1e-6)
    assert v.coefficient(2.0, 1.0, 2.0, 3.0, 1e-3) == -2.0
    assert c.stiffness(0.3, 2.0, 500.0, 1e-3) == pytest.approx(0.3 * 2.0 * 500.0 / 1e-3)
    assert v.stiffness(0.3, 2.0, 500.0, 1e-3) == pytest.approx(0.3 * 2.0 * 500.0)
    # arrays (a batch) alike
    s = np.array([1e-6, 10.0])
    assert np.allclose(
        c.coefficient(0.3, s, 0.0 * s, 0.0 * s, 1e-3) * s, [-0.3e-3, -0.3], rtol=1e-6
    )
    assert {"coulomb", "viscous"} <= set(FRICTION_LAWS)  # (a new law adds an entry, no edit here)


def test_a_new_law_is_one_class_and_one_registry_entry(monkeypatch):
    """Registered, a new law is an env choice; its force enters the dynamics and its stiffness
    the guard: half the viscous coefficient gives the viscous law's trajectory at half mu, and
    the viscous guard's step count at half mu."""
    monkeypatch.setitem(contact.FRICTION_LAWS, "half_viscous", HalfViscous())
    new = TippeTopEnv(friction_law="half_viscous", friction=6.0, spin=150.0)
    old = TippeTopEnv(friction_law="viscous", friction=3.0, spin=150.0)
    a = np.zeros(2, dtype=np.float32)
    new.reset(seed=0)
    old.reset(seed=0)
    for _ in range(20):
        i_new, i_old = new.step(a)[4], old.step(a)[4]
        assert i_new["internal_step"] == i_old["internal_step"]
        assert i_new["tilt"] == pytest.approx(i_old["tilt"], rel=1e-12, abs=1e-15)
        assert i_new["slip_speed"] == pytest.approx(i_old["slip_speed"], rel=1e-9, abs=1e-15)
    with pytest.raises(ValueError, match="friction_law"):
        TippeTopEnv(friction_law="stribeck")


def test_the_guard_reads_the_law_stiffness():
    system = TippeTop(TippeTopParams(friction=0.3), "gliding")
    prm = system.params
    rate = 0.3 * 2.0 * prm.mass * prm.gravity * prm.contact_mobility() / prm.slip_regularization
    assert system.friction_stiffness(0.3) == pytest.approx(rate, rel=1e-15)
    assert system.max_stable_step(get_integrator("rk4")) == pytest.approx(1.39 / rate, rel=1e-15)
    assert system.max_stable_step(get_integrator("euler")) == pytest.approx(1.0 / rate, rel=1e-15)
    assert system.max_stable_step(get_integrator("dop853")) == math.inf
    assert TippeTop(TippeTopParams(), "frictionless").friction_stiffness(0.3) == 0.0
