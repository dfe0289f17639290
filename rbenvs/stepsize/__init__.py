"""The step controller (:mod:`rbenvs.stepsize.controller`) and its pure forms
(:mod:`rbenvs.stepsize.forms`): every decision about a period's internal steps and every
estimate of its error, for the single env, the vector env and the compiled kernels."""
