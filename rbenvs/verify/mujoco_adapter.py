"""MuJoCo as a :class:`~rbenvs.verify.simulator.Simulator` (the ``mujoco`` extra; ``mujoco`` is
imported here alone, when ``--simulator mujoco`` names it).

The models (docs/verification.md, "Any simulator"; the systems of docs/physics.md §1-§3):

* ``free_body``: one body on a free joint, the given principal moments on the body axes, gravity
  zero. ``Omega = Pi / I`` is the free joint's angular velocity (body frame in MuJoCo, as in
  rbenvs); a body torque goes to the joint's rotational generalised forces, which are body-frame
  torques, held over the step as rbenvs holds its control.
* ``heavy_top``: a body on a ball joint at the pivot, its centre of mass at ``l chi``, its
  inertia about the centre of mass ``I - M l^2 (1 - chi chi^T)``, gravity ``-g e_z``. The
  attitude given to MuJoCo is the one taking ``Gamma`` to ``e_z`` by the shortest turn (the
  heading is free: nothing in the heavy top depends on it); ``Gamma`` is read back as
  ``R^T e_z``, ``Pi = I Omega`` from the joint's body-frame angular velocity. Pivot friction:
  not modelled.
* ``tippe_top``: a body on a free joint, its frame at the centre of mass ``G``, a sphere geom of
  radius ``R`` centred ``h = alpha R`` along the body axis ``e3``, on a plane ``z = 0`` under
  gravity, friction ``mu`` (the geoms' ``friction``, Coulomb in MuJoCo's soft, convex contact
  model: ``condim=3``; frictionless: ``condim=1``). Started touching (``z_G = R - h k_z``, ``v_z``
  from the constraint); read back as ``(x, y, vx, vy, q, Omega)`` of ``G``: MuJoCo's penetration
  and any flight are in its own state, not in rbenvs'. Viscous friction, pure rolling and a
  moving table are not modelled (their rows read n/a).

Options (``--simulator mujoco:key=value,...``): ``integrator`` (``Euler``, ``RK4``,
``implicit``, ``implicitfast``, several joined by ``+``; default ``RK4+implicitfast``), ``dt``
(default 1e-3 s), and for the tippe top's contact ``cone`` (``elliptic`` (default) or
``pyramidal``), ``timeconst`` (default ``2 dt``, the stiffest MuJoCo allows at that step) and
``dampratio`` (1) of its ``solref``, ``impratio`` (1), ``noslip`` (noslip iterations, 0).
"""

from __future__ import annotations

import math

import numpy as np

from ..rotations import quat_from_two_vectors
from .protocol import Problem

__all__ = ["MUJOCO_INTEGRATORS", "MujocoSimulator", "mujoco_simulators"]

# MuJoCo's integrators with their orders (the declared order scales the tolerances): Euler is
# semi-implicit Euler, the implicit pair first order in the step as well
MUJOCO_INTEGRATORS = {"Euler": 1, "RK4": 4, "implicit": 1, "implicitfast": 1}
DEFAULT_INTEGRATORS = ("RK4", "implicitfast")


def _f(x) -> str:
    return repr(float(x))


class MujocoSimulator:
    """One MuJoCo integrator at a fixed ``dt`` with the contact settings of the module docstring."""

    batched = False

    def __init__(
        self,
        integrator="RK4",
        dt=1e-3,
        cone="elliptic",
        timeconst=None,
        dampratio=1.0,
        impratio=1.0,
        noslip=0,
    ):
        import mujoco  # noqa: F401  (fails here, with the extra's name, when it is missing)

        if integrator not in MUJOCO_INTEGRATORS:
            raise ValueError(
                f"mujoco integrator must be one of {list(MUJOCO_INTEGRATORS)}, got {integrator!r}"
            )
        if cone not in ("elliptic", "pyramidal"):
            raise ValueError(f"mujoco cone must be 'elliptic' or 'pyramidal', got {cone!r}")
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        self.integrator, self.dt, self.order = integrator, float(dt), MUJOCO_INTEGRATORS[integrator]
        self.cone, self.dampratio, self.impratio, self.noslip = (
            cone,
            float(dampratio),
            float(impratio),
            int(noslip),
        )
        self.timeconst = 2.0 * self.dt if timeconst is None else float(timeconst)
        self.name = f"mujoco {integrator} dt={dt:g}"
        self._models: dict = {}

    def start(self, problem: Problem, y0):
        import mujoco

        key = (problem.system, problem.params, problem.fidelity)
        if key not in self._models:
            self._models[key] = mujoco.MjModel.from_xml_string(self._xml(problem))
        model = self._models[key]
        run = _Run(model, problem, self.dt)
        run.set_state(tuple(float(c) for c in y0))
        return run

    def _xml(self, problem: Problem) -> str:
        p = problem.params
        option = f'integrator="{self.integrator}" timestep="{_f(self.dt)}"'
        if problem.system == "free_body":
            i1, i2, i3 = p.inertia
            return (
                f'<mujoco><option {option} gravity="0 0 0"/><worldbody><body><freejoint/>'
                f'<inertial pos="0 0 0" mass="1" diaginertia="{_f(i1)} {_f(i2)} '
                f'{_f(i3)}"/></body></worldbody></mujoco>'
            )
        if problem.system == "heavy_top":
            if p.spin_friction != 0.0:
                raise NotImplementedError("the pivot's spin friction is not modelled")
            chi = np.array(p.com_direction)
            inertia_g = np.diag(p.inertia) - p.mass * p.length**2 * (np.eye(3) - np.outer(chi, chi))
            full = " ".join(
                _f(v)
                for v in (
                    inertia_g[0, 0],
                    inertia_g[1, 1],
                    inertia_g[2, 2],
                    inertia_g[0, 1],
                    inertia_g[0, 2],
                    inertia_g[1, 2],
                )
            )
            pos = " ".join(_f(v) for v in p.length * chi)
            return (
                f'<mujoco><option {option} gravity="0 0 {_f(-p.gravity)}"/><worldbody><body><joint '
                'type="ball"/>'
                f'<inertial pos="{pos}" mass="{_f(p.mass)}" '
                f'fullinertia="{full}"/></body></worldbody></mujoco>'
            )
        if problem.system == "tippe_top":
            if problem.fidelity == "rolling":
                raise NotImplementedError(
                    "pure rolling: MuJoCo's soft friction cone lets the contact slip"
                )
            frictionless = problem.fidelity == "frictionless"
            if not frictionless and p.friction_law != "coulomb":
                raise NotImplementedError(
                    f"{p.friction_law} friction: MuJoCo's contacts have Coulomb friction only"
                )
            big_a, big_c = p.inertia
            mu = 0.0 if frictionless else p.friction
            contact = (
                f'condim="{1 if frictionless else 3}" friction="{_f(mu)} 0 0" '
                f'solref="{_f(self.timeconst)} {_f(self.dampratio)}"'
            )
            return (
                f'<mujoco><option {option} gravity="0 0 {_f(-p.gravity)}" cone="{self.cone}" '
                f'impratio="{_f(self.impratio)}" '
                f'noslip_iterations="{self.noslip}"/><worldbody><geom type="plane" size="0 0 1" '
                f"{contact}/>"
                f'<body><freejoint/><inertial pos="0 0 0" mass="{_f(p.mass)}" '
                f'diaginertia="{_f(big_a)} {_f(big_a)} {_f(big_c)}"/>'
                f'<geom type="sphere" size="{_f(p.radius)}" pos="0 0 {_f(p.height)}" '
                f"{contact}/></body></worldbody></mujoco>"
            )
        raise NotImplementedError(f"no MuJoCo model of {problem.system!r}")


def _matrix(q):
    """The rotation matrix of the unit quaternion ``q = (w, x, y, z)``, body -> space."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


class _Run:
    """One MjData, converted from and to rbenvs' layout at the start and at each read."""

    def __init__(self, model, problem, dt):
        import mujoco

        self.mujoco, self.model, self.data, self.problem, self.dt = (
            mujoco,
            model,
            mujoco.MjData(model),
            problem,
            dt,
        )

    def set_state(self, y):
        d, p, system = self.data, self.problem.params, self.problem.system
        if system == "free_body":
            d.qvel[3:6] = np.array(y) / np.array(p.inertia)
        elif system == "heavy_top":
            gamma = np.array(y[3:6]) / np.linalg.norm(y[3:6])
            d.qpos[0:4] = quat_from_two_vectors(tuple(gamma), (0.0, 0.0, 1.0))  # R Gamma = e_z
            d.qvel[0:3] = np.array(y[0:3]) / np.array(p.inertia)
        else:
            x, yy, vx, vy = y[0:4]
            q, w = np.array(y[4:8]), np.array(y[8:11])
            rm = _matrix(q)
            k, w_space = rm[:, 2], rm @ w
            d.qpos[0:3] = (
                x,
                yy,
                p.radius - p.height * k[2],
            )  # the sphere's centre O = G + h k at z = R
            d.qpos[3:7] = q
            d.qvel[0:3] = (vx, vy, -p.height * np.cross(w_space, k)[2])
            d.qvel[3:6] = w
        self.mujoco.mj_forward(self.model, d)

    def state(self):
        d, p, system = self.data, self.problem.params, self.problem.system
        if system == "free_body":
            return tuple(float(v) for v in d.qvel[3:6] * np.array(p.inertia))
        if system == "heavy_top":
            gamma = _matrix(d.qpos[0:4])[2]  # R^T e_z: the last row
            return tuple(float(v) for v in d.qvel[0:3] * np.array(p.inertia)) + tuple(
                float(v) for v in gamma
            )
        return tuple(float(v) for v in (*d.qpos[0:2], *d.qvel[0:2], *d.qpos[3:7], *d.qvel[3:6]))

    def _control(self, u, h):
        if abs(h - self.dt) > 1e-12 * self.dt:
            raise ValueError(f"this MuJoCo model steps {self.dt:g} s, asked for {h:g}")
        d = self.data
        if u is None:
            d.qfrc_applied[:] = 0.0
        elif self.problem.system == "free_body":
            d.qfrc_applied[3:6] = u  # the free joint's rotational forces: body-frame torques
        else:
            raise NotImplementedError(
                f"a control on the {self.problem.system} (a moving table) is not modelled"
            )

    def step(self, u, h):
        self._control(u, h)
        self.mujoco.mj_step(self.model, self.data)
        return self.state()

    def advance(self, n, u, h):
        self._control(u, h)
        self.mujoco.mj_step(self.model, self.data, nstep=n)
        return self.state()


def mujoco_simulators(options: dict) -> list[MujocoSimulator]:
    """The simulators of ``--simulator mujoco:...`` options (module docstring), one per
    integrator."""
    from .protocol import no_more_options, take_option

    names = take_option(options, "integrator", str, "+".join(DEFAULT_INTEGRATORS)).split("+")
    settings = dict(
        dt=take_option(options, "dt", float, 1e-3),
        cone=take_option(options, "cone", str, "elliptic"),
        timeconst=take_option(options, "timeconst", float, None),
        dampratio=take_option(options, "dampratio", float, 1.0),
        impratio=take_option(options, "impratio", float, 1.0),
        noslip=take_option(options, "noslip", int, 0),
    )
    no_more_options(options, "mujoco")
    return [MujocoSimulator(name, **settings) for name in names]
