"""Every tippe-top row for the integrators and simulators asked for (:func:`tippe_top_checks`)."""

from __future__ import annotations

import numpy as np

from ...dynamics import TippeTop
from ...integrators import get_integrator
from ..common import (
    Check,
    not_applicable,
    reference_scheme,
    worst,
)
from ..settings import REGIMES, TIPPE_TOP_SETTINGS
from ..simulator import as_simulators
from .hops import _hop_rows
from .invariants import _invariant_rows
from .inversion import INVERSION_ROW, T90_ROW, _inversion_jellett_row, _inversion_rows, _t90_rows
from .settings import SYSTEM, random_tops

# ------------------------------------------------------------------------------------------
# all rows


def tippe_top_checks(
    integrators, seed=0, quick=False, system_class=TippeTop, progress=None, t90=True, regimes=None
) -> list[Check]:
    """The tippe-top rows for each of ``integrators``: rbenvs integrator names in
    :data:`TIPPE_TOP_SETTINGS` (others are left out), or
    :class:`~rbenvs.verify.simulator.Simulator` objects at their own step, on the random tops of
    their :func:`~rbenvs.verify.common.reference_scheme` and held to its settings scaled to
    their step (rows of rbenvs' own models, the hops and ``t90``, read n/a for them).
    ``system_class(params, fidelity)`` builds the simulated system (tests pass broken ones);
    ``regimes`` overrides the settings' regimes of the inversion rows; ``t90``: whether rk4 runs
    the default top's long runs, the time-to-90-degrees row and Jellett's integral through an
    inversion (a simulator at its own step runs the latter whatever ``t90``)."""
    checks: list[Check] = []
    mode = 0 if quick else 1
    for sim in as_simulators(integrators):
        verified = _verified_setting(sim)
        if verified is None:
            continue
        sim, name, setting = verified
        rows = _random_top_rows(sim, name, setting, seed, mode, system_class, progress, regimes)
        checks.extend(worst(c) for c in rows.values())
        if sim.dt is not None or (name == "rk4" and t90):
            checks.extend(_inversion_jellett_rows(sim, system_class))
        if sim.dt is not None:
            checks.extend(_own_model_na_rows(sim, name, t90))
        else:
            checks.extend(_own_model_rows(name, quick, t90, system_class, progress))
    return checks


def _verified_setting(sim):
    """``(sim, name, setting)``: the simulator to run (dop853 at its setting's tolerances), the
    name of its settings' scheme (its reference scheme at its own step) and the settings; ``None``
    for an rbenvs integrator without tippe-top settings."""
    if sim.dt is not None:
        name = reference_scheme(sim.order)
        return sim, name, TIPPE_TOP_SETTINGS[name]
    name = sim.integrator.name
    if name not in TIPPE_TOP_SETTINGS:
        return None
    setting = TIPPE_TOP_SETTINGS[name]
    if name == "dop853":
        sim = as_simulators([get_integrator(name, rtol=setting.rtol, atol=setting.rtol * 1e-2)])[0]
    return sim, name, setting


def _random_top_rows(sim, name, setting, seed, mode, system_class, progress, regimes):
    """The rows on random tops, by row (each a list of cases): the invariants' and the inversion
    rows of each regime (``regimes``, else the setting's)."""
    rng = np.random.default_rng([seed, 3, list(TIPPE_TOP_SETTINGS).index(name)])
    rows = _invariant_rows(
        sim,
        setting,
        random_tops(rng, 1, "inside"),
        rng,
        setting.states[mode],
        system_class,
        progress,
    )
    for regime in setting.regimes[mode] if regimes is None else regimes:
        tops = random_tops(
            np.random.default_rng([seed, 4, REGIMES.index(regime)]),
            setting.inversion_tops[mode],
            regime,
            setting.alpha_max,
        )
        rows |= _inversion_rows(sim, setting, tops, system_class, progress)
    return rows


def _inversion_jellett_rows(sim, system_class) -> list[Check]:
    """Jellett's integral through an inversion: its row, or n/a where it is not modelled."""
    try:
        return [_inversion_jellett_row(sim, system_class)]
    except NotImplementedError as exc:
        return not_applicable(SYSTEM, sim.name, [INVERSION_ROW], str(exc))


def _own_model_na_rows(sim, name, t90) -> list[Check]:
    """The n/a rows of a simulator at its own step for the rows of rbenvs' own model."""
    own = [
        "hops: Jellett held, max |dJ| / |J|",
        "hops: energy never rises in a control period, max rise / E0",
        "plastic impact: energy loss / (lambda^2 M_zz / 2) - 1, 20 touchdowns",
    ]
    if name == "rk4" and t90:
        own.insert(0, T90_ROW)
    return not_applicable(
        SYSTEM,
        sim.name,
        own,
        "a row of rbenvs' own model (its free flight, its rk4's convergence)",
    )


def _own_model_rows(name, quick, t90, system_class, progress) -> list[Check]:
    """The rows of rbenvs' own model, run by its rk4 alone: ``t90`` (with ``t90``) and the
    hops."""
    out: list[Check] = []
    if name == "rk4" and t90:
        out.extend(_t90_rows(order=not quick, system_class=system_class))
        if progress:
            progress()
    if name == "rk4":
        out.extend(_hop_rows(system_class))
        if progress:
            progress()
    return out


def progress_total(integrators, quick=False, t90=True) -> int:
    mode = 0 if quick else 1
    total = 0
    for name in integrators:
        if name in TIPPE_TOP_SETTINGS:
            s = TIPPE_TOP_SETTINGS[name]
            total += (
                1
                + len(s.regimes[mode]) * s.inversion_tops[mode]
                + (1 if name == "rk4" and t90 else 0)
            )
            total += 1 if name == "rk4" else 0  # the hop rows
    return total
