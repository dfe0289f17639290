"""Analytic results as code: what the simulator is checked against (``rbenvs verify``).

Pure functions with no dependency on the environments; each names its source (an equation of
the seeds in ``docs/physics.md`` or a paper) and raises ``ValueError`` outside its domain.
"""

from . import free_body, heavy_top, tippe_top
from .free_body import (
    axis_stability,
    exact_solution,
    intermediate_axis_growth_rate,
    linearization,
    linearization_eigenvalues,
    orbit_period,
    taylor_solution,
)
from .heavy_top import (
    critical_spin,
    fast_top_nutation,
    regular_precession_rates,
    upright_eigenvalues,
)
from .tippe_top import (
    energy_star,
    final_tilt,
    inversion_criterion,
    inversion_spin_threshold,
    jellett,
    jellett_upright,
)

__all__ = [
    "free_body",
    "heavy_top",
    "tippe_top",
    "critical_spin",
    "upright_eigenvalues",
    "regular_precession_rates",
    "fast_top_nutation",
    "jellett",
    "jellett_upright",
    "energy_star",
    "inversion_criterion",
    "inversion_spin_threshold",
    "final_tilt",
    "exact_solution",
    "taylor_solution",
    "orbit_period",
    "linearization",
    "linearization_eigenvalues",
    "axis_stability",
    "intermediate_axis_growth_rate",
]
