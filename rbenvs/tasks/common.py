"""What every task shares: the effort term of the rewards, written once.

A task (:class:`rbenvs.contracts.Task`) also declares, as class attributes, its observation
(``observation_names`` and ``observation_units``: the env turns each unit into a bound, e.g.
``rad/s`` into ``max_angular_velocity``), its ``metric_names`` (``is_success`` last), the
``final_measure`` that summarises an episode's end and the name of its reference
``controller`` in :mod:`rbenvs.controllers`.
"""

from __future__ import annotations

import math

from ..draws import draw
from ..jit import jitable

__all__ = ["effort", "TwoStageStart", "speed_bound"]


class TwoStageStart:
    """Starts drawn in two parts (every task): ``draw_kinds``, the kinds of the generator's raw
    numbers for one start (:mod:`rbenvs.draws`: ``"u"`` uniform, ``"n"`` normal, in order), and
    ``initial_from_draws(system, d)``, the arithmetic that turns them into components, on floats
    or on rows of a batch. A vector env restarting thousands of sub-envs then makes only the
    generator calls per sub-env (compiled, where numba is installed) and the arithmetic once
    (:mod:`rbenvs.vector`); :meth:`initial_state` is the two in a row (the single env). A
    uniform on ``[a, b)`` is ``a + (b - a) U`` (numpy's own formula), so ``rng.random`` draws
    give the same numbers as ``rng.uniform``."""

    draw_kinds: str = ""

    def kernel_start(self, system):
        """``(start, P)``: the pure form of :meth:`initial_from_draws`, ``start(P, d) -> y`` on a
        start's draws ``d`` (floats, rows of a batch, or in compiled code), or ``None``."""
        return None

    def initial_from_draws(self, system, d):
        """A start's components from its draws ``d`` (floats, or rows of a batch)."""
        fn, p = self.kernel_start(system)
        return fn(p, d)

    def initial_draws(self, rng):
        """The generator's numbers for one start, in the order of :attr:`draw_kinds`."""
        return draw(rng, self.draw_kinds)

    def initial_state(self, system, rng, shape=()):
        if tuple(shape) != ():
            raise ValueError(
                "initial_state draws one state; a batch draws per sub-env (initial_draws) and "
                "converts at once (initial_from_draws)"
            )
        return self.initial_from_draws(system, self.initial_draws(rng))


def speed_bound(task, observation_high) -> float:
    """An upper bound of ``|Omega|`` [rad/s] over the states inside the observation bounds: the
    norm of the bounds of the task's ``rad/s`` components (the episode ends, at the observation
    limit, once one leaves its bound)."""
    return math.sqrt(
        sum(
            float(h) ** 2
            for h, unit in zip(observation_high, task.observation_units)
            if unit == "rad/s"
        )
    )


@jitable
def effort(u):
    """``mean(u^2)`` of the normalised action (every reward's control-cost term); floats or
    arrays, any number of components."""
    s = 0.0
    for c in u:
        s = s + c * c
    return s / len(u)
