"""The integrator interface shared by every system.

What to integrate (a system: vector field, invariants, exact sub-flows) is separate from how
(an integrator). An integrator is a stateless, immutable object that declares its order and
what it conserves, and advances components ``y`` under a control ``u`` held constant for a
step ``h``. A system offers, as far as it can:

* ``rhs(y, u) -> dy``: the vector field (every integrator but the geometric ones);
* ``normalize(y) -> y``: projection back onto the state manifold (unit quaternions);
* ``split_flows() -> (flow, ...)``: exact flows ``flow(y, u, h)`` of pieces of the dynamics,
  for :class:`~rbenvs.integrators.splitting.Splitting`;
* ``kick(y, u, h)`` and ``free_flow(y, h)``: the exact flow of the control alone and of the
  uncontrolled system, for :class:`~rbenvs.integrators.exact.Exact`.

Components are floats (one state) or arrays of one batch shape (many states), so one
integrator object serves the single env, the vector env and the benchmarks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ..contracts import StepRegion

__all__ = ["Integrator", "StepRegion"]


@dataclass(frozen=True)
class Integrator:
    """Base class. Subclasses set the class attributes and implement :meth:`step`.

    Attributes:
        name: registry name.
        order: global order of accuracy for smooth problems (with a control held constant
            over the step).
        evaluations: right-hand-side evaluations per step (``None``: not rhs-based or adaptive;
            :meth:`step_counted` reports the real count).
        conserves: what it keeps to round-off for the uncontrolled system: ``"casimirs"`` (the
            system's :attr:`casimirs`, the invariants of the Lie-Poisson bracket: ``|Pi|`` for
            the free body, ``|Gamma|`` and ``Pi.Gamma`` for the heavy top) and/or ``"energy"``.
        region: where its step can be trusted (:class:`~rbenvs.contracts.StepRegion`): what the
            step guard reads. A scheme without one cannot be guarded: the envs refuse it.
        error_constant: ``C`` of its global error ``C lambda T (lambda h)^order`` on a rotation
            at rate ``lambda`` (measured by
            :func:`rbenvs.integrators.error.measure_error_constant`): what ``tolerance=`` turns into
            a step count. ``None``: no such constant (exact sub-flows, whose error comes from the
            system's commutators rather than one rate; adaptive schemes, which control their own):
            ``tolerance=`` is refused.
    """

    # Class-level constants, not dataclass fields: a field's default would be stamped onto
    # every instance by __init__ and hide the subclass's value.
    name: ClassVar[str] = "base"
    order: ClassVar[int] = 0
    evaluations: ClassVar[int | None] = None
    conserves: ClassVar[tuple[str, ...]] = ()
    # the system's optional capabilities the scheme needs (of its ``provides``)
    requires: ClassVar[tuple[str, ...]] = ()
    region: ClassVar[StepRegion | None] = None
    error_constant: ClassVar[float | None] = None
    # whether the leading error on a rotation is in the phase (|R(i z)| = 1 + O(z^(p+2))): then
    # tolerance= may count the state's own speed (rbenvs.stepsize.forms.motion_rates)
    error_in_phase: ClassVar[bool] = False
    # the error constant of a forced (decaying) mode, where it differs from error_constant's
    # (rbenvs.stepsize.forms.relaxation_steps); None: none declared
    forced_error_constant: ClassVar[float | None] = None
    # one scalar step for a whole batch (an adaptive solve whose step follows all members): a
    # batch whose members need different step counts runs in groups of equal counts
    uniform_step_only: ClassVar[bool] = False

    def supports(self, system) -> bool:
        """Whether ``system`` offers everything this scheme needs."""
        return set(self.requires) <= system.provides

    def step(self, system, y, u, h):
        """Advance ``y`` by ``h`` under control ``u`` (``None`` = zero)."""
        raise NotImplementedError

    def bind(self, system, dim: int, compensated: bool = False):
        """``step(y, u, h)`` for ``system``'s states of ``dim`` components: :meth:`step` with the
        system bound once, for a hot loop (the same arithmetic, bit for bit). A system whose
        ``needs_projection`` is false has an identity ``normalize`` that may be skipped.

        ``compensated``: the step with compensated summation, ``step(y, c, u, h) -> (y, c)``:
        ``c`` carries what adding the increment to ``y`` rounded away into the next step's sum
        (Kahan 1965; ``c`` zero gives the plain step's ``y``, bit for bit), or ``None`` where
        the scheme has none (the engine then takes the plain step)."""
        if compensated:
            return None
        return lambda y, u, h: self.step(system, y, u, h)

    def kernel_step(self, system, compensated: bool = False):
        """``(step, P)`` with ``step(P, y, u, h)`` a pure function equal to :meth:`step` for
        ``system`` (for :mod:`rbenvs.compiled`), or ``None`` where this scheme or this system
        offers none (the batch then runs on numpy arrays); ``compensated``: the pure form of
        :meth:`bind`'s compensated step, ``step(P, y, c, u, h) -> (y, c)``, or ``None``."""
        return None

    def kernel_step_first_stage(self, system, compensated: bool = False):
        """``(step, P)`` with ``step(P, y, k0, u, h)`` equal to :meth:`kernel_step`'s step given
        its first stage ``k0 = f(y, u)``, or ``None`` (a scheme whose first stage is not the
        vector field at ``y``, or one without a pure form)."""
        return None

    def step_counted(self, system, y, u, h):
        """:meth:`step` plus the number of rhs evaluations it made (for cost accounting)."""
        return self.step(system, y, u, h), self.evaluations or 0
