"""The step controller (:mod:`rbenvs.stepsize.controller`), its pure forms
(:mod:`rbenvs.stepsize.forms`) and its report for a vector env (:mod:`rbenvs.stepsize.report`):
every decision about a period's internal steps and every estimate of its error, for the single
env, the vector env and the compiled kernels."""
