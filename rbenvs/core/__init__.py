"""The step core: what every env and vector env runs, written once (the model, the engine's
period and finish, the terminal reasons, the hybrid switches). How many
internal steps a period takes and what error it commits is the step controller's:
:mod:`rbenvs.stepsize`.
"""
