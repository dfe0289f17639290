"""What every task shares: the effort term of the rewards, written once.

A task (:class:`rbenvs.contracts.Task`) also declares, as class attributes, its observation
(``observation_names`` and ``observation_units``: the env turns each unit into a bound, e.g.
``rad/s`` into ``max_angular_velocity``), its ``metric_names`` (``is_success`` last), the
``final_measure`` that summarises an episode's end and the name of its reference
``controller`` in :mod:`rbenvs.controllers`.
"""

from __future__ import annotations

from ..jit import jitable

__all__ = ["effort"]


@jitable
def effort(u):
    """``mean(u^2)`` of the normalised action (every reward's control-cost term); floats or
    arrays, any number of components."""
    s = 0.0
    for c in u:
        s = s + c * c
    return s / len(u)
