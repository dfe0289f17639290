"""The free-flight rows: a fast top's hops (Jellett's integral, the energy) and the plastic
impact."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...dynamics import TippeTop
from ..common import (
    Check,
)
from .settings import SYSTEM

# ------------------------------------------------------------------------------------------
# hops (free flight)

HOP_CASE = {"spin": 2000.0, "friction": 1.0, "tilt": 0.1, "seconds": 0.3}
HOP_JELLETT_TOL = 1e-7  # relative; rk4 at the automatic step keeps it to ~1e-9 over 0.3 s
IMPACT_TOL = 1e-8  # relative; E_before - E_after cancels ~8 digits of E


def _hop_rows(system_class=TippeTop):
    """A fast top (2000 rad/s, mu = 1) hops hundreds of times: Jellett's integral kept, the
    energy never rising in a control period; and the plastic impact's energy loss
    ``lambda^2 M_zz / 2`` against the energy read-out, on random touchdowns."""
    case = dict(HOP_CASE)
    engine, dt = _hop_engine(case, system_class)
    j0, e0, dj, rise, hops = _hop_run(engine, round(case["seconds"] / dt))
    case["hops"] = hops
    return [
        Check(
            SYSTEM,
            "rk4",
            f"hops ({case['hops']}): Jellett held, max |dJ| / |J|",
            0.0,
            dj / abs(j0),
            HOP_JELLETT_TOL,
            case=case,
        ),
        Check(
            SYSTEM,
            "rk4",
            "hops: energy never rises in a control period, max rise / E0",
            0.0,
            max(rise, 0.0) / e0,
            1e-13,
            case=case,
        ),
        _impact_row(engine.system),
    ]


def _hop_engine(case, system_class):
    """The step core running the hop ``case`` as the env does, on ``system_class``; and the
    env's control period [s]."""
    from ...core.step import Engine
    from ...envs import TippeTopEnv
    from ...envs.base import compiled_backend

    # the rolling start (its centre of mass moving at R n sin(theta)) and the stability bound's
    # steps: the case as measured (the system under test below is built with that bound)
    env = TippeTopEnv(
        spin=case["spin"],
        friction=case["friction"],
        tilt=case["tilt"],
        free_flight=True,
        max_speed=40.0,
        start="rolling",
        friction_bound="stability",
    )
    # the env's model with the system under test (a mutant in the tests), run by the step core
    # the env runs (its hybrid layer makes the switches between internal steps)
    engine = Engine(
        dataclasses.replace(env.model, system=system_class(env.params, "gliding", flight=True)),
        backend=compiled_backend,
    )
    return engine, env.dt


def _hop_run(engine, periods):
    """``(J0, E0, max |dJ|, max rise of the energy in a period, hops)`` over ``periods`` control
    periods from the model's initial state (the drift and rise ``nan`` if the episode ends)."""
    from gymnasium.utils import seeding

    from ...contracts import StepResult

    y = tuple(float(c) for c in engine.model.initial_state(seeding.np_random(0)[0]))
    _, info = engine.reset_one(y)
    j0, e0 = info["jellett"], info["energy"]
    dj, rise = 0.0, -math.inf
    energy = e0
    plain = engine.plain
    for _ in range(periods):
        result = StepResult._make(engine.step_one(y, [0.0, 0.0], plain))
        y, terminated, info, plain = result.y, result.terminated, result.info, result.plain
        dj = max(dj, abs(info["jellett"] - j0))
        rise = max(rise, info["energy"] - energy)
        energy = info["energy"]
        if terminated:
            dj = rise = math.nan
            break
    return j0, e0, dj, rise, info["hops"]


def _impact_row(system) -> Check:
    """The plastic impact's energy loss against ``lambda^2 M_zz / 2``, worst of 20 random
    touchdowns."""
    rng = np.random.default_rng(0)
    worst_loss = 0.0
    for _ in range(20):
        worst_loss = max(worst_loss, _impact_error(system, _touchdown_state(system, rng)))
    return Check(
        SYSTEM,
        "rk4",
        "plastic impact: energy loss / (lambda^2 M_zz / 2) - 1, 20 touchdowns",
        0.0,
        worst_loss,
        IMPACT_TOL,
    )


def _impact_error(system, y) -> float:
    """``|loss / (lambda^2 M_zz / 2) - 1|`` of the impact at the touchdown ``y`` (``M_zz``: the
    inverse effective mass along the normal at the contact point)."""
    after, lam = system.impact(y)
    rm = system.frame(y)
    r = system.contact_arm(rm[6], rm[7], rm[8])
    t = (r[1] * rm[8] - r[2] * rm[7], r[2] * rm[6] - r[0] * rm[8], r[0] * rm[7] - r[1] * rm[6])
    big_a, big_c = system.params.inertia
    m_zz = 1.0 / system.params.mass + (t[0] ** 2 + t[1] ** 2) / big_a + t[2] ** 2 / big_c
    loss = system.energy(y) - system.energy(after)
    expected = 0.5 * lam * lam * m_zz
    return abs(loss / expected - 1.0) if expected > 0.0 else math.inf


def _touchdown_state(system, rng):
    """A flight state at the table, its contact point moving down."""
    prm = system.params
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w = tuple(rng.normal(size=3) * np.array([20.0, 20.0, 300.0]))
    y = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0) + tuple(q) + w + (0.0, 0.0)
    y = y[:2] + (prm.radius - prm.height * system.frame(y)[8],) + y[3:]  # gap 0
    wanted = -abs(system.gap_rate(y)) - 0.05  # the gap closing
    return y[:5] + (y[5] + wanted - system.gap_rate(y),) + y[6:]
