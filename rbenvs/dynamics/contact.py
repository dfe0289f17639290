"""Friction laws at a sliding contact, as objects: what the force is, and how stiff it is.

A law gives the friction force per unit normal force as a multiple of the slip velocity,
``F / N = k v_P`` (``k <= 0``, :meth:`~FrictionLaw.coefficient`), and the rate at which it
relaxes the slip near zero slip, ``lambda_d`` (:meth:`~FrictionLaw.stiffness`): what the step
guard must resolve with an explicit scheme. Adding a law is one class here and one entry in
:data:`FRICTION_LAWS`; the tippe top (:mod:`rbenvs.dynamics.tippe_top`), its env's
``friction_law=`` choices and its step guard read them from there.

Components are floats (one state) or arrays of one batch shape; the coefficient ``mu`` may be
either too (a friction coefficient set by the action, per sub-env).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..rotations import sqrt

__all__ = ["FrictionLaw", "Coulomb", "Viscous", "FRICTION_LAWS"]


@dataclass(frozen=True)
class FrictionLaw:
    """Base class: ``name`` (the ``friction_law=`` value) and the two methods below."""

    name = "base"

    def coefficient(self, mu, s1, s2, s3, eps):
        """``k`` with ``F = N k (s1, s2, s3)``, ``(s1, s2, s3)`` the slip velocity [m/s] and
        ``eps`` the slip regularisation [m/s]."""
        raise NotImplementedError

    def stiffness(self, mu, normal, mobility, eps):
        """``lambda_d`` [1/s]: the slip's relaxation rate near zero slip under normal force
        ``normal`` [N] with contact mobility ``mobility`` [1/kg] (the contact point's
        acceleration per unit force): ``mu normal mobility`` for a law linear in the slip
        there, divided by its slip scale."""
        raise NotImplementedError


@dataclass(frozen=True)
class Coulomb(FrictionLaw):
    """Coulomb's law (seed 2, 3.96) regularised below ``eps``: ``F = -mu N v_P / sqrt(|v_P|^2 +
    eps^2)``. Near zero slip it is the viscous law ``-mu N v_P / eps``: stiff for small ``eps``."""

    name = "coulomb"

    def coefficient(self, mu, s1, s2, s3, eps):
        return -mu / sqrt(s1 * s1 + s2 * s2 + s3 * s3 + eps * eps)

    def stiffness(self, mu, normal, mobility, eps):
        return mu * normal * mobility / eps


@dataclass(frozen=True)
class Viscous(FrictionLaw):
    """Viscous friction ``F = -mu N v_P`` (``mu`` in s/m): linear in the slip everywhere."""

    name = "viscous"

    def coefficient(self, mu, s1, s2, s3, eps):
        return -mu

    def stiffness(self, mu, normal, mobility, eps):
        return mu * normal * mobility


# friction_law= name -> law (the tippe top's choices)
FRICTION_LAWS = {law.name: law for law in (Coulomb(), Viscous())}
