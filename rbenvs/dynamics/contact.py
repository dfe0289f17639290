"""Friction laws at a sliding contact, as objects: what the force is, and how stiff it is.

A law gives the friction force per unit normal force as a multiple of the slip velocity,
``F / N = k v_P`` (``k <= 0``, :meth:`~FrictionLaw.coefficient`), and the rate at which it
relaxes the slip near zero slip, ``lambda_d`` (:meth:`~FrictionLaw.stiffness`): what the step
guard must resolve with an explicit scheme. Adding a law is one class here and one entry in
:data:`FRICTION_LAWS`; the tippe top (:mod:`rbenvs.dynamics.tippe_top`), its env's
``friction_law=`` choices and its step guard read them from there.

Each law of the package is written as two pure functions (:func:`rbenvs.jit.jitable`), its
``kernel_coefficient`` and ``kernel_stiffness``, which its methods call: the tippe top builds its
own pure forms around them, so a compiled kernel calls the law as the single env does. A law
defined with the two methods alone (no pure functions) works on floats and arrays, not compiled.

Components are floats (one state) or arrays of one batch shape; the coefficient ``mu`` may be
either too (a friction coefficient set by the action, per sub-env).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..jit import jitable
from ..rotations import sqrt

__all__ = [
    "FrictionLaw",
    "Coulomb",
    "Viscous",
    "FRICTION_LAWS",
    "coulomb_coefficient",
    "coulomb_stiffness",
    "viscous_coefficient",
    "viscous_stiffness",
    "coulomb_slope",
    "viscous_slope",
    "no_friction",
]


@jitable
def coulomb_coefficient(mu, s1, s2, s3, eps):
    """Regularised Coulomb: ``k = -mu / sqrt(|s|^2 + eps^2)`` ([T 3.96])."""
    return -mu / sqrt(s1 * s1 + s2 * s2 + s3 * s3 + eps * eps)


@jitable
def coulomb_stiffness(mu, normal, mobility, eps):
    """Regularised Coulomb near zero slip: ``mu N |M| / eps`` [1/s]."""
    return mu * normal * mobility / eps


@jitable
def viscous_coefficient(mu, s1, s2, s3, eps):
    """Viscous: ``k = -mu`` (``mu`` in s/m)."""
    return -mu


@jitable
def viscous_stiffness(mu, normal, mobility, eps):
    """Viscous: ``mu N |M|`` [1/s]."""
    return mu * normal * mobility


@jitable
def coulomb_slope(mu, s1, s2, s3, eps):
    """``2 dk/d|s|^2`` of regularised Coulomb: ``mu / (|s|^2 + eps^2)^(3/2)``, so that the
    slope of the force per unit normal force is ``dF/ds = k I + slope s s^T`` (negative
    semidefinite: ``-mu / rho (I - s s^T / rho^2)``, ``rho^2 = |s|^2 + eps^2``)."""
    rho2 = s1 * s1 + s2 * s2 + s3 * s3 + eps * eps
    return mu / (rho2 * sqrt(rho2))


@jitable
def viscous_slope(mu, s1, s2, s3, eps):
    """Viscous: ``k`` does not depend on the slip, ``0``."""
    return 0.0 * mu


@jitable
def no_friction(mu, s1, s2, s3, eps):
    """``k = 0``: a contact without friction (the tippe top's ``frictionless`` level)."""
    return 0.0


@dataclass(frozen=True)
class FrictionLaw:
    """Base class: ``name`` (the ``friction_law=`` value) and the two methods below, which call
    the law's pure functions ``kernel_coefficient`` and ``kernel_stiffness`` (class attributes,
    ``staticmethod`` of a :func:`~rbenvs.jit.jitable` function; ``None``: a law given by its
    methods alone, which compiled code cannot call)."""

    name = "base"
    # whether the force saturates beyond the slip scale eps (Coulomb: at mu N): a slip can then
    # leave the stiff band and grow to a sliding speed, carrying the error it had relative to
    # itself (tolerance='s share of the slip relaxation, rbenvs.dynamics.tippe_top.implicit_forms)
    saturates = False
    # friction_bound="accuracy"'s scale K (rbenvs.dynamics.tippe_top.ACCURACY_MARGIN): near zero
    # slip rk4's error in the time to 90 degrees follows h^2 lambda_d w per unit time, so the law's
    # step is h <= 1.25 / (K sqrt(lambda_d w)); K holds the time to 90 degrees within 1e-4 s over a
    # sweep of tops across the inversion band (tests/test_tippe_stiff.py). A law not measured takes
    # the largest measured scale.
    accuracy_scale = 19.0
    kernel_coefficient = None
    kernel_stiffness = None
    kernel_slope = None  # optional: 2 dk/d|s|^2, for schemes that treat the friction implicitly

    def coefficient(self, mu, s1, s2, s3, eps):
        """``k`` with ``F = N k (s1, s2, s3)``, ``(s1, s2, s3)`` the slip velocity [m/s] and
        ``eps`` the slip regularisation [m/s]."""
        if self.kernel_coefficient is None:
            raise NotImplementedError
        return self.kernel_coefficient(mu, s1, s2, s3, eps)

    def stiffness(self, mu, normal, mobility, eps):
        """``lambda_d`` [1/s]: the slip's relaxation rate near zero slip under normal force
        ``normal`` [N] with contact mobility ``mobility`` [1/kg] (the contact point's
        acceleration per unit force): ``mu normal mobility`` for a law linear in the slip
        there, divided by its slip scale."""
        if self.kernel_stiffness is None:
            raise NotImplementedError
        return self.kernel_stiffness(mu, normal, mobility, eps)

    def slope(self, mu, s1, s2, s3, eps):
        """``2 dk/d|s|^2``: the slope of the force per unit normal force is ``dF/ds = k I +
        slope s s^T`` (what a linearly implicit scheme needs,
        :mod:`rbenvs.integrators.rosenbrock`)."""
        if self.kernel_slope is None:
            raise NotImplementedError
        return self.kernel_slope(mu, s1, s2, s3, eps)

    def pure_forms(self) -> tuple:
        """``(coefficient, stiffness)`` as functions of the methods' arguments: the pure ones,
        or the bound methods of a law that has none (floats and arrays only)."""
        coefficient = (
            self.kernel_coefficient if self.kernel_coefficient is not None else self.coefficient
        )
        stiffness = self.kernel_stiffness if self.kernel_stiffness is not None else self.stiffness
        return coefficient, stiffness

    @property
    def compilable(self) -> bool:
        """Whether both pure functions exist (compiled code can run the law)."""
        return self.kernel_coefficient is not None and self.kernel_stiffness is not None


@dataclass(frozen=True)
class Coulomb(FrictionLaw):
    """Coulomb's law ([T 3.96]) regularised below ``eps``: ``F = -mu N v_P / sqrt(|v_P|^2 +
    eps^2)``. Near zero slip it is the viscous law ``-mu N v_P / eps``: stiff for small ``eps``."""

    name = "coulomb"
    saturates = True
    # (a slow top creeps near rolling for tens of seconds, gathering the error: the largest scale)
    accuracy_scale = 19.0
    kernel_coefficient = staticmethod(coulomb_coefficient)
    kernel_stiffness = staticmethod(coulomb_stiffness)
    kernel_slope = staticmethod(coulomb_slope)


@dataclass(frozen=True)
class Viscous(FrictionLaw):
    """Viscous friction ``F = -mu N v_P`` (``mu`` in s/m): linear in the slip everywhere."""

    name = "viscous"
    # (linear everywhere, no creeping phase: a smaller scale holds it; tests/test_tippe_stiff.py)
    accuracy_scale = 10.4
    kernel_coefficient = staticmethod(viscous_coefficient)
    kernel_stiffness = staticmethod(viscous_stiffness)
    kernel_slope = staticmethod(viscous_slope)


# friction_law= name -> law (the tippe top's choices)
FRICTION_LAWS = {law.name: law for law in (Coulomb(), Viscous())}
