"""Tasks on the heavy top: initial states, observation, reward, termination.

As for the free body, a task reads state components (floats for one env, arrays for a batch)
through the system's read-outs and never integrates. ``u`` is the normalised action (one entry
per actuated torque direction, in ``[-1, 1]``).

Both tasks observe ``(Gamma / |Gamma|, Omega)``: the upward vertical seen from the body (3
numbers in [-1, 1]) and the body angular velocity [rad/s]. That is the Markov state of the
top (``Pi = I Omega``); the heading about the vertical does not enter the dynamics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..dynamics.free_body import angular_velocity
from ..dynamics.heavy_top import precession_rate, tilt_sides, top_spin, top_tilt, vertical_norm
from ..jit import jitable
from ..rotations import maximum, select, sqrt
from .common import TwoStageStart, effort

__all__ = ["UprightTask", "PrecessTask", "transverse_basis", "slow_precession_rate"]


def transverse_basis(chi) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Unit vectors ``(t1, t2)`` with ``(t1, t2, chi)`` right-handed and orthonormal.

    For ``chi = +-e_k`` they are the other two body axes (``e_i``, ``+-e_j``, ``(i, j, k)``
    cyclic), so a Lagrange top's transverse torques act on body axes 1 and 2. Made once per
    ``chi`` (every restart of a batch asks).
    """
    return _transverse_basis(tuple(float(c) for c in chi))


@lru_cache(maxsize=64)
def _transverse_basis(chi: tuple):
    x = np.asarray(chi, dtype=float)
    k = int(np.argmax(np.abs(x)))
    e = np.zeros(3)
    e[(k + 1) % 3] = 1.0
    t1 = e - x * np.dot(e, x)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(x, t1)
    return tuple(float(c) for c in t1), tuple(float(c) for c in t2)


@jitable
def clip_unit(x):
    """``x`` clipped to ``[-1, 1]`` (a unit vector's component, against round-off)."""
    if isinstance(x, float):
        return min(1.0, max(-1.0, x))
    return _clip_unit_arrays(x)


@jitable  # (registered so that compiled code can name it; it only ever runs on arrays)
def _clip_unit_arrays(x):
    return np.clip(x, -1.0, 1.0)


@jitable
def vertical_in_cone(p, u_tilt, u_azimuth):
    """Unit vectors at an angle uniform in ``[low, high]`` from ``chi``, azimuth uniform, from two
    uniforms on [0, 1) (floats or rows of a batch); ``(vector, angle)``; ``p = (chi, t1, t2,
    low, high)`` with ``(t1, t2)`` the :func:`transverse_basis` of ``chi``."""
    chi, t1, t2, low, high = p
    theta = low + (high - low) * u_tilt
    phi = 0.0 + 2.0 * np.pi * u_azimuth
    a, b, c = np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)
    return (
        a * t1[0] + b * t2[0] + c * chi[0],
        a * t1[1] + b * t2[1] + c * chi[1],
        a * t1[2] + b * t2[2] + c * chi[2],
    ), theta


def _cone_params(chi, low, high) -> tuple:
    chi = tuple(float(c) for c in chi)
    t1, t2 = transverse_basis(chi)
    return chi, t1, t2, float(low), float(high)


@jitable
def upright_start(p, d):
    """``Gamma`` in the cone of :func:`vertical_in_cone` (``d[0:2]``), spin ``n ~ U(spin_low,
    spin_high)`` (``d[2]``) about ``chi``: ``Pi = n I chi``; ``p = (cone, spin_low, spin_high,
    inertia)``."""
    cone, spin_low, spin_high, inertia = p
    chi = cone[0]
    gamma, _ = vertical_in_cone(cone, d[0], d[1])
    n = spin_low + (spin_high - spin_low) * d[2]
    return (inertia[0] * n * chi[0], inertia[1] * n * chi[1], inertia[2] * n * chi[2]) + gamma


@jitable
def precess_start(p, d):
    """The regular precession's start (:class:`PrecessTask`): ``Gamma`` in the cone about the
    target tilt (``d[0:2]``), spin ``n`` (``d[2]``), ``Omega = r Gamma + (n - r cos(tilt)) chi``
    at the target rate ``r`` (given, or the slow root of [T 3.82] at ``n``); ``p = (cone, spin_low,
    spin_high, fixed, target_rate, root, inertia)``."""
    cone, spin_low, spin_high, fixed, target_rate, root, inertia = p
    chi = cone[0]
    gamma, tilt = vertical_in_cone(cone, d[0], d[1])
    n = spin_low + (spin_high - spin_low) * d[2]
    rate = target_rate if fixed else slow_precession_root(root, n)
    axial = n - rate * np.cos(tilt)
    w1, w2, w3 = (
        rate * gamma[0] + axial * chi[0],
        rate * gamma[1] + axial * chi[1],
        rate * gamma[2] + axial * chi[2],
    )
    return (inertia[0] * w1, inertia[1] * w2, inertia[2] * w3) + gamma


# The tasks' arithmetic as pure functions of (parameters, state, action): the methods below call
# them on floats or arrays, the compiled batch kernel (rbenvs.compiled) on floats.
@jitable
def top_observe(inv, y):
    """``(Gamma / |Gamma|, Omega)``: a unit vector (clipped against round-off) and [rad/s]."""
    n = vertical_norm(y)
    return (clip_unit(y[3] / n), clip_unit(y[4] / n), clip_unit(y[5] / n)) + angular_velocity(
        inv, y
    )


@jitable
def upright_evaluate(p, y, u):
    """``(reward, terminated, is_success)``; ``p = (chi, control_cost, limit, success)`` with
    ``limit = (cos L, sin L, L < pi)`` of the tilt limit ``L`` and ``success = (cos S, sin S)``
    of the success tilt ``S``.

    ``tilt > L`` is decided without the angle: with ``s = |Gamma x chi| >= 0`` and ``c = Gamma .
    chi`` (:func:`tilt_sides`), ``s cos L - c sin L`` has the sign of ``sin(tilt - L)``, and
    ``tilt - L`` lies in ``(-pi, pi)``, so ``tilt > L`` iff it is positive (likewise ``tilt <
    S``); ``L = pi`` ends nothing, as ``tilt <= pi``. The same decisions as comparing
    :func:`top_tilt` except within rounding of the boundary, without its ``atan2`` (a noticeable
    part of a large batch's vector step)."""
    chi, control_cost, limit, success = p
    s, c = tilt_sides(chi, y)
    cos_tilt = c / vertical_norm(y)  # (c is Gamma . chi, summed in the same order)
    terminated = limit[2] & (s * limit[0] - c * limit[1] > 0.0)
    return cos_tilt - control_cost * effort(u), terminated, s * success[0] - c * success[1] < 0.0


@jitable
def slow_precession_root(p, spin):
    """Slow root of [T 3.82] ``A cos(a) p^2 - C n p + M g l = 0`` at spin ``n``; ``p = (C, M g l,
    4 A M g l cos(a))``. Without cancellation: ``q = (C n + sgn(C n) sqrt(D)) / 2``,
    ``p = M g l / q``, the discriminant ``D`` clamped at 0 (a spin too slow for a real root,
    reached only if friction has slowed the top, gives the double root's rate) and ``|q|``
    kept off 0."""
    c, mgl, four_a_mgl_cos = p
    k = c * spin
    disc = k * k - four_a_mgl_cos
    root = sqrt(maximum(disc, 0.0))
    q = 0.5 * (k + select(k < 0.0, -root, root))
    q = select(abs(q) > 1e-300, q, 1e-300)
    return mgl / q


@jitable
def precess_evaluate(p, y, u):
    """``(reward, terminated, precession_rate, target_precession_rate, tilt_error, is_success)``;
    ``p = (inverse, chi, target_tilt, fixed, target_rate, root, tilt_limit, success_tilt,
    control_cost)`` (``fixed``: a given ``target_rate``; else the slow root's parameters
    ``root`` at the current spin)."""
    inv, chi, target_tilt, fixed, target_rate, root, tilt_limit, success_tilt, control_cost = p
    target = target_rate if fixed else slow_precession_root(root, top_spin(inv, chi, y))
    rate = precession_rate((inv, chi), y)
    tilt_err = abs(top_tilt(chi, y) - target_tilt)
    rate_err = abs(rate - target) / abs(target)
    # capped at 1 (the axis exactly upright has rate 0: error 1); NaN counts as 1
    rate_err = select(rate_err <= 1.0, rate_err, 1.0)
    reward = 1.0 - tilt_err / tilt_limit - rate_err - control_cost * effort(u)
    return (
        reward,
        tilt_err > tilt_limit,
        rate,
        target,
        tilt_err,
        (tilt_err < success_tilt) & (rate_err < 0.1),
    )


def _root_params(system, tilt):
    prm = system.params
    return (prm.axial_inertia, prm.mgl, 4.0 * prm.transverse_inertia * prm.mgl * math.cos(tilt))


def slow_precession_rate(system, spin, tilt):
    """Slow root of [T 3.82] ``A cos(a) p^2 - C n p + M g l = 0`` for arrays/floats of ``spin``
    (:func:`slow_precession_root`)."""
    p = slow_precession_root(
        _root_params(system, tilt),
        float(spin) if np.ndim(spin) == 0 else np.asarray(spin, dtype=np.float64),
    )
    return float(p) if np.ndim(p) == 0 else p


def _require_real_precession(params, low, high, alpha):
    """The torque-free regular precession [T 3.82] exists at tilt ``alpha`` for every spin drawn."""
    a, c, mgl = params.transverse_inertia, params.axial_inertia, params.mgl
    need = 4.0 * a * mgl * math.cos(alpha)
    n_min = math.sqrt(max(need, 0.0)) / c
    if need > 0.0 and (low * high <= 0.0 or min(abs(low), abs(high)) <= n_min):
        raise ValueError(
            "spin must satisfy (I3 spin)^2 > 4 I1 M g l cos(target_tilt) for a torque-free regular "
            "precession "
            f"(|spin| > {n_min:.6g} rad/s at target_tilt={alpha!r}, one sign); got the range "
            f"({low!r}, {high!r}). "
            "Raise the spin or give target_rate"
        )


@dataclass(frozen=True)
class UprightTask(TwoStageStart):
    """Keep the top upright: the centre-of-mass axis on the upward vertical.

    * Start: spin ``n ~ U(spin_low, spin_high)`` about ``chi`` (``Omega = n chi``), the vertical
      tilted from ``chi`` by an angle uniform in ``[0, perturbation]`` (azimuth uniform).
    * Reward: ``cos(tilt) - control_cost * mean(u^2)``, in [-1, 1] (1 = upright, no effort).
    * Terminates when ``tilt > tilt_limit``. Success: ``tilt < success_tilt``.
    """

    spin_low: float
    spin_high: float
    perturbation: float
    tilt_limit: float
    control_cost: float
    success_tilt: float = 0.05

    name = "upright"
    observation_size = 6
    observation_names = ("Gamma1", "Gamma2", "Gamma3", "Omega1", "Omega2", "Omega3")
    observation_units = ("1",) * 3 + ("rad/s",) * 3
    metric_names = ("is_success",)
    final_measure = "tilt"
    controller = "UprightLQR"

    draw_kinds = "uuu"  # tilt, azimuth, spin

    # the env's defaults for this task: tilt_limit, and spin=None's share of the critical spin
    # (below it: the top falls without control)
    default_tilt_limit = math.pi / 4
    default_spin = (0.5, "half")
    needs_lagrange = False

    @classmethod
    def build(cls, system, low, high, perturbation, tilts, control_cost):
        """``(task, the fastest start's angular speed, what sets it besides the spin)`` from the
        env's checked keywords (``tilts``: the tilt limit, the target tilt checked and as given,
        the target rate; the upright task reads the limit alone)."""
        task = cls(low, high, perturbation, tilts[0], control_cost)
        return task, max(abs(low), abs(high)), ""

    def kernel_start(self, system):
        """``(upright_start, P)``: the pure form of :meth:`initial_from_draws`."""
        prm = system.params
        cone = _cone_params(prm.com_direction, 0.0, self.perturbation)
        return upright_start, (
            cone,
            float(self.spin_low),
            float(self.spin_high),
            tuple(float(c) for c in prm.inertia),
        )

    def observe(self, system, y):
        return top_observe(system.params.inverse, tuple(y))

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the tilt computed once."""
        reward, terminated, success = upright_evaluate(self._params(system), tuple(y), u)
        return reward, terminated, {"is_success": success}

    def kernels(self, system):
        """``((observe, P), (evaluate, P))`` for :mod:`rbenvs.compiled`."""
        return (top_observe, system.params.inverse), (upright_evaluate, self._params(system))

    def reward_floor(self, system, observation_high) -> float:
        """The least reward of a step: the tilt at its limit (upside down when the limit is pi),
        at full effort."""
        return math.cos(min(float(self.tilt_limit), math.pi)) - float(self.control_cost)

    def _params(self, system):
        limit, success = float(self.tilt_limit), float(self.success_tilt)
        return (
            system.params.com_direction,
            float(self.control_cost),
            (math.cos(limit), math.sin(limit), limit < math.pi),
            (math.cos(success), math.sin(success)),
        )


@dataclass(frozen=True)
class PrecessTask(TwoStageStart):
    """Hold a regular precession at tilt ``target_tilt`` (Lagrange tops only).

    The target rate is ``target_rate`` [rad/s] if given (a forced precession: it needs torque
    unless it solves [T 3.82]), else the slow root of [T 3.82] at the current spin, the torque-free
    steady precession ([T 3.82-3.83]).

    * Start: spin ``n ~ U(spin_low, spin_high)``, tilt ``target_tilt + U(-perturbation,
      perturbation)`` at a uniform azimuth, and the angular velocity of the regular precession
      at the target rate: ``Omega = p Gamma + (n - p cos(tilt)) chi`` (so ``Omega.chi = n``).
      Off the target tilt this is not steady: the top nutates.
    * Reward: ``1 - |tilt - target_tilt| / tilt_limit - min(|p - p*| / |p*|, 1) -
      control_cost * mean(u^2)`` with ``p`` the precession rate of the axis about the vertical.
    * Terminates when ``|tilt - target_tilt| > tilt_limit``. Success: tilt within
      ``success_tilt`` and rate within 10% of the target.
    """

    spin_low: float
    spin_high: float
    target_tilt: float
    target_rate: float | None
    perturbation: float
    tilt_limit: float
    control_cost: float
    success_tilt: float = 0.02

    name = "precess"
    observation_size = 6
    observation_names = ("Gamma1", "Gamma2", "Gamma3", "Omega1", "Omega2", "Omega3")
    observation_units = ("1",) * 3 + ("rad/s",) * 3
    metric_names = ("precession_rate", "target_precession_rate", "tilt_error", "is_success")
    final_measure = "tilt_error"
    controller = "PrecessionTracking"

    draw_kinds = "uuu"  # tilt, azimuth, spin

    # the env's defaults for this task (:class:`UprightTask`'s); [T 3.82] needs a Lagrange top
    default_tilt_limit = 0.3
    default_spin = (2.0, "twice")
    needs_lagrange = True

    @classmethod
    def build(cls, system, low, high, perturbation, tilts, control_cost):
        """:meth:`UprightTask.build`: the target tilt within the tilt limit of both poles, a
        torque-free precession for every spin drawn unless a ``target_rate`` forces one, and the
        fastest start spinning at its spin plus twice its precession rate."""
        limit, alpha, target_tilt, target_rate = tilts
        if not (limit < alpha < math.pi - limit):
            raise ValueError(
                f"target_tilt must lie in (tilt_limit, pi - tilt_limit) = ({limit!r}, "
                f"{math.pi - limit!r}) rad, got {target_tilt!r}"
            )
        if target_rate is None:
            _require_real_precession(system.params, low, high, alpha)
        task = cls(low, high, alpha, target_rate, perturbation, limit, control_cost)
        rates = [
            abs(target_rate if target_rate is not None else slow_precession_rate(system, n, alpha))
            for n in (low, high)
        ]
        peak = max(2.0 * r + abs(n) for r, n in zip(rates, (low, high)))
        more = " and the precession rate (target_rate, or the torque-free rate of [T 3.82])"
        return task, peak, more

    def kernel_start(self, system):
        """``(precess_start, P)``: the pure form of :meth:`initial_from_draws`."""
        prm = system.params
        cone = _cone_params(
            prm.com_direction,
            self.target_tilt - self.perturbation,
            self.target_tilt + self.perturbation,
        )
        fixed = self.target_rate is not None
        rate = float(self.target_rate) if fixed else 0.0
        return precess_start, (
            cone,
            float(self.spin_low),
            float(self.spin_high),
            fixed,
            rate,
            _root_params(system, self.target_tilt),
            tuple(float(c) for c in prm.inertia),
        )

    def observe(self, system, y):
        return top_observe(system.params.inverse, tuple(y))

    def evaluate(self, system, y, u):
        """``(reward, terminated, metrics)`` with the errors computed once."""
        reward, terminated, rate, target, tilt_err, success = precess_evaluate(
            self._params(system), tuple(y), u
        )
        metrics = {
            "precession_rate": rate,
            "target_precession_rate": target,
            "tilt_error": tilt_err,
            "is_success": success,
        }
        return reward, terminated, metrics

    def kernels(self, system):
        """``((observe, P), (evaluate, P))`` for :mod:`rbenvs.compiled`."""
        return (top_observe, system.params.inverse), (precess_evaluate, self._params(system))

    def reward_floor(self, system, observation_high) -> float:
        """The least reward of a step: the tilt error at its limit and the rate error at its cap
        of 1, at full effort."""
        return -1.0 - float(self.control_cost)

    def _params(self, system):
        prm = system.params
        fixed = self.target_rate is not None
        rate = float(self.target_rate) if fixed else 0.0
        return (
            prm.inverse,
            prm.com_direction,
            float(self.target_tilt),
            fixed,
            rate,
            _root_params(system, self.target_tilt),
            float(self.tilt_limit),
            float(self.success_tilt),
            float(self.control_cost),
        )
