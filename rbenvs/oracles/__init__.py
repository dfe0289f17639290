"""Analytic results as code: what the simulator is checked against (``rbenvs verify``).

Pure functions with no dependency on the environments; each names its source (an equation of
the seeds in ``physics.md`` or a paper) and raises ``ValueError`` outside its domain.
"""

from .free_body import (
    axis_stability,
    exact_solution,
    intermediate_axis_growth_rate,
    linearization,
    linearization_eigenvalues,
    orbit_period,
)

__all__ = [
    "exact_solution",
    "orbit_period",
    "linearization",
    "linearization_eigenvalues",
    "axis_stability",
    "intermediate_axis_growth_rate",
]
