"""The tippe top's parameters and the settings its step rule reads (:class:`TippeTopParams`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

from ...jit import jitable
from ...rotations import maximum, sqrt
from ..contact import FRICTION_LAWS
from ..validation import (
    require_choice,
    require_finite_nonnegative,
    require_finite_positive,
    require_finite_result,
    require_real_vector,
)


class Event(NamedTuple):
    """A switching event of a hybrid system (:meth:`TippeTop.events`): where it can happen
    (``applies(y)``), the function whose sign change (``>= 0`` to ``< 0``) it is, the tolerance
    to locate it to, and the state in the new mode at the event (``switch(y)``)."""

    name: str
    applies: Callable
    function: Callable
    tolerance: float
    switch: Callable


FIDELITIES = ("gliding", "frictionless", "rolling")
# Free flight: the lift-off is located to |N| <= LIFT_OFF_TOL m g and the touchdown to
# |gap| <= TOUCHDOWN_TOL a (a few ulp of the height), by rbenvs.core.hybrid.
LIFT_OFF_TOL = 1e-12
TOUCHDOWN_TOL = 1e-13
# The step guard: the contact geometry turns with the body, so every scheme takes at most
# SPIN_STEP rad of max(|Omega|, omega_g) per internal step (an accuracy bound), and at most
# FRICTION_MARGIN of its real-axis stability interval of the friction's stiffness.
SPIN_STEP = 0.1
FRICTION_MARGIN = 0.5
# friction_bound="accuracy": h <= ACCURACY_MARGIN of the scheme's real-axis interval over
# lambda_a(lambda) = max(lambda, K sqrt(lambda w)), w = max(|Omega|, omega_g), K the friction law's
# accuracy_scale (rbenvs.dynamics.contact). For rk4: h <= 1.25 / lambda (stable with the tight
# rate growing up to about twice within a period: 2.5 < 2.78) and h <= 1.25 / (K
# sqrt(lambda w)): near zero slip the slip relaxes at lambda while the contact geometry that
# drives it turns at w, and rk4's error in the time to 90 degrees follows h^2 lambda w per unit
# time there, so a top that rises slowly (long near rolling) gathers more of it; the error falls
# like K^-4. lambda is the law's stiffness at the smallest slip the period can reach, kappa
# lambda_d (lambda_d the tight rate at zero slip: actual N, mobility along the table), taken whole
# within the band where K was fitted (STIFF_BAND kappa >= 1: |s| <= sqrt(15) eps under Coulomb):
# a sliding top's saturated friction is not stiff. There the step is held by rk4's error on the
# rotation, which Jellett's integral gathers like w (w h)^4 per unit time: lambda_a >=
# JELLETT_SCALE w (0.025 rad a step for rk4), never above the zero-slip rate's lambda_a.
FRICTION_BOUNDS = ("stability", "accuracy")
ACCURACY_MARGIN = 0.45
STIFF_BAND = 4.0
JELLETT_SCALE = 50.0


@jitable
def tippe_rotation_rate(p, y):
    """``max(|Omega|, omega_g)`` [rad/s], ``p = (index of Omega_1 in the state, omega_g)``."""
    o, omega_g = p
    w0, w1, w2 = y[o], y[o + 1], y[o + 2]
    return maximum(sqrt(w0 * w0 + w1 * w1 + w2 * w2), omega_g)


def _require_finite_products(a, m, g, alpha, big_a, big_c) -> None:
    """The products the dynamics forms, refused here by name rather than overflowing in a step."""
    require_finite_result(
        "mass, radius and inertia", m * a * a + big_a + big_c, "m a^2 + A + C [kg m^2]"
    )
    require_finite_result(
        "radius and inertia",
        (a + alpha * a) * (a + alpha * a) / min(big_a, big_c),
        "(a + h)^2 / min(A, C) [1/kg]",
    )
    require_finite_result("mass and gravity", m * g * a, "m g a [J]")


@dataclass(frozen=True)
class TippeTopParams:
    """Physical parameters. Defaults: the tippe top of Leine and Glocker (2003), docs/physics.md §3.

    * ``radius`` ``a`` [m]; ``offset`` ``alpha = h / a`` in (0, 1); ``mass`` [kg]; ``gravity``.
    * ``inertia = (A, C)`` about the centre of mass [kg m^2], ``C <= 2 A`` (a real symmetric
      body: triangle inequality ``A + A >= C``).
    * ``friction``: the coefficient ``mu`` (>= 0): dimensionless for Coulomb, [s/m] for the
      viscous law ``F = -mu N v_P``.
    * ``friction_law``: ``"coulomb"``: ``F = -mu N v_P / sqrt(|v_P|^2 + slip_regularization^2)``
      (Coulomb's law, [T 3.96], smoothed for slips below ``slip_regularization`` [m/s]) or
      ``"viscous"``.
    * ``stem``: ``None`` (the sphere alone) or ``(b, d)`` [m]: a second contact, the stem's tip, a
      sphere of radius ``b`` whose centre ``S = G + d k`` lies on the symmetry axis beyond the
      sphere's centre (``d > h``), protruding past the sphere (``d - h + b > a``) and
      smaller than the sphere (``b < a``): the inverted top ends on it (Leine and Glocker 2003:
      ``(0.005, 0.016)``; docs/physics.md §3, "The stem").
    """

    radius: float = 0.015
    mass: float = 0.006
    offset: float = 0.2
    inertia: tuple[float, float] = (8e-7, 7e-7)
    gravity: float = 9.81
    friction: float = 0.3
    friction_law: str = "coulomb"
    slip_regularization: float = 1e-3
    stem: tuple[float, float] | None = None
    height: float = field(init=False, repr=False)  # h = alpha a [m]

    def __post_init__(self):
        a, m, g, alpha = self._checked_scales()
        big_a, big_c = self._checked_inertia()
        mu, eps = self._checked_friction()
        _require_finite_products(a, m, g, alpha, big_a, big_c)
        stem = None if self.stem is None else self._checked_stem(a, alpha, big_a, big_c)
        set_ = object.__setattr__
        for name, value in (
            ("radius", a),
            ("mass", m),
            ("gravity", g),
            ("offset", alpha),
            ("inertia", (big_a, big_c)),
            ("friction", mu),
            ("slip_regularization", eps),
            ("stem", stem),
            ("height", alpha * a),
        ):
            set_(self, name, value)

    def _checked_scales(self) -> tuple[float, float, float, float]:
        """``(a, m, g, alpha)``: the radius, mass, gravity and offset, checked."""
        a = require_finite_positive("radius", self.radius)
        m = require_finite_positive("mass", self.mass)
        g = require_finite_positive("gravity", self.gravity)
        alpha = require_finite_positive("offset", self.offset)
        if not alpha < 1.0:
            raise ValueError(
                "offset (alpha = h/R, centre-of-mass offset over radius) must lie in (0, 1), got "
                f"{self.offset!r}"
            )
        return a, m, g, alpha

    def _checked_inertia(self) -> tuple[float, float]:
        """``(A, C)``, checked: positive and ``C <= 2 A``."""
        big_a, big_c = require_real_vector(
            "inertia",
            self.inertia,
            2,
            " (A, C): the transverse and axial moments about the centre of mass",
        )
        big_a = require_finite_positive("inertia[0] (A)", big_a)
        big_c = require_finite_positive("inertia[1] (C)", big_c)
        if big_c > 2.0 * big_a:
            raise ValueError(
                "inertia must satisfy C <= 2 A (triangle inequality of a real body), got "
                f"A={big_a!r}, C={big_c!r}"
            )
        return big_a, big_c

    def _checked_friction(self) -> tuple[float, float]:
        """``(mu, eps)``: the friction coefficient and slip regularisation, checked, and the
        law's name checked between them."""
        mu = require_finite_nonnegative("friction", self.friction)
        require_choice("friction_law", self.friction_law, FRICTION_LAWS)
        eps = require_finite_positive("slip_regularization", self.slip_regularization)
        return mu, eps

    def _checked_stem(self, a, alpha, big_a, big_c) -> tuple[float, float]:
        """``(b, d)``: the stem, checked against the sphere (``a``, ``h = alpha a``) and the
        moments (``A``, ``C``)."""
        b, d = require_real_vector(
            "stem",
            self.stem,
            2,
            " (b, d): the stem tip's radius and the distance of its centre from the centre of "
            "mass [m]",
        )
        b = require_finite_positive("stem[0] (b)", b)
        d = require_finite_positive("stem[1] (d)", d)
        h = alpha * a
        if not b < a:
            raise ValueError(
                f"stem radius b must be below the sphere's radius a = {a!r} m, got {b!r}"
            )
        if not d > h:
            raise ValueError(
                f"stem distance d must exceed h = alpha a = {h!r} m (the stem's centre lies "
                f"beyond the sphere's centre), got {d!r}"
            )
        if not d - h + b > a:
            raise ValueError(
                "the stem must protrude past the sphere (d - h + b > a): d - h + b = "
                f"{d - h + b!r} m, a = {a!r} m"
            )
        require_finite_result(
            "stem", (b + d) * (b + d) / min(big_a, big_c), "(b + d)^2 / min(A, C) [1/kg]"
        )
        return b, d

    @property
    def gamma(self) -> float:
        """``A / C``: inversion needs ``1 - alpha < gamma < 1 + alpha`` (docs/physics.md §3)."""
        return self.inertia[0] / self.inertia[1]

    def gravity_rate(self) -> float:
        """``sqrt(m g (a + h) / min(A, C))`` [rad/s]: an upper bound of the rates gravity drives
        through the contact (the weight at the longest arm ``|r| <= a + h`` over the smallest
        moment; the rocking frequency ``sqrt(m g h / (A + m (a - h)^2))`` of a top at rest is
        below it). The guard resolves it as it does the spin (``rbenvs.envs.tippe_top``)."""
        return math.sqrt(self.mass * self.gravity * self.longest_arm() / min(self.inertia))

    def longest_arm(self) -> float:
        """``a + h``, the longest arm ``|r|`` of the sphere's contact; with the stem, the larger
        of it and the stem's ``b + d``."""
        arm = self.radius + self.height
        if self.stem is not None:
            arm = max(arm, self.stem[0] + self.stem[1])
        return arm

    def contact_mobility(self) -> float:
        """An upper bound of ``|M|``, ``M = 1/m + [r x]^T I^-1 [r x]``: the contact point's
        acceleration per unit contact force [1/kg] (``|r| <= a + h``; with the stem ``|r| <=
        max(a + h, b + d)``)."""
        return 1.0 / self.mass + self.longest_arm() ** 2 / min(self.inertia)

    def stem_touch_tilt(self) -> float:
        """The tilt [rad] at which the stem first touches the table while the sphere does:
        ``cos(theta*) = -(a - b)/(d - h)`` (both contacts' heights of ``G`` agree, ``a - h cos =
        b - d cos``); ``nan`` without a stem."""
        if self.stem is None:
            return math.nan
        b, d = self.stem
        return math.acos(-(self.radius - b) / (d - self.height))
