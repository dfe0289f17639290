"""The step core: what every env and vector env runs, written once.

* :mod:`rbenvs.core.guard`: the internal step count of a control period, from the integrator's
  declared :class:`~rbenvs.contracts.StepRegion` and the system's declared
  :class:`~rbenvs.contracts.GuardRates`.
"""
