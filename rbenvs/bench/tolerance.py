"""``rbenvs bench accuracy --tolerance``: what ``tolerance=`` achieves and what it costs.

For each extreme of issue 19 (fast spins to 1e4 rad/s, the separatrix, nearly equal moments,
heavy tops above and below the critical spin, euler where its error grows without bound (refused
with a tolerance), the tippe top from several starts) and each requested tolerance (1e-3, 1e-6,
1e-9), the env is built with ``tolerance=tol`` and ``tolerance_horizon`` = the case's periods, run
without control from the case's starts until the episode ends (the horizon, or the task's
termination: a fallen top, an inverted tippe top; the tolerance is per episode), and compared period
by period with the reference (the free
body: the exact elliptic solution; the others: DOP853 at ``rtol = 1e-13``, as
:mod:`rbenvs.bench.accuracy`). Printed per row:

* ``error``: the worst over the periods, the starts and the named blocks of the state of
  ``|y_b - ref_b| / |ref_b|`` (the tippe top's horizontal position left out, as in the accuracy
  bench); ``<= tol`` is what the tolerance promises;
* ``estimate``: the largest over the starts of the episode's summed ``info["error_estimate"]``;
* ``steps``: the internal steps the env took (all starts), the cost (one scheme: steps are rhs
  evaluations over a constant);
* ``fixed``: the fewest equal ``substeps`` (the same env without a tolerance, its stability
  guard still on) whose error meets ``tol`` on every start, found by bisection, and its steps;
  ``cost x``: ``steps / fixed steps`` (issue 19 asks for at most 1.5). Where the case's
  integrator is named (``rk4``, ``euler``) ``tolerance=`` chooses the steps only, and the fixed
  setting is of the same integrator; where it is ``"auto"`` ``tolerance=`` chooses the scheme
  too, and the fixed setting is the cheapest of every scheme with an error constant (each one's
  fewest substeps), compared in rhs evaluations (``steps x`` the scheme's evaluations a step:
  the ``fixed`` column names the scheme);
* a construction refusal (``refused``: the tolerance cannot be met within ``MAX_INTERNAL_STEPS``,
  or the scheme's leading error is in the amplitude: euler, whose rows show it) or an episode
  ended as a numerical failure is printed as such; an episode ended where the global error
  estimate passed the tolerance (``tolerance_check=True``: the ``<key>+check`` rows of
  :data:`CHECKED`) shows the error up to the state it kept, the period where it ended, the
  companion's steps counted in ``steps`` and no fixed search (it ran fewer periods).

The error constants are measured here too (:func:`rbenvs.integrators.error.measure_error_constant`)
against each scheme's declared one.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "TOLERANCES",
    "TOLERANCE_CASES",
    "ToleranceCase",
    "scene_cases",
    "all_cases",
    "run_tolerance",
    "print_tolerance",
]

TOLERANCES = (1e-3, 1e-6, 1e-9)
MAX_FIXED = 2**20  # the bisection's largest substeps


@dataclass(frozen=True)
class ToleranceCase:
    key: str
    label: str
    env: str  # "free_body", "heavy_top", "tippe_top"
    kwargs: dict
    starts: tuple  # named states for reset(options={"state": ...}), or seeds (ints)
    periods: int
    tolerances: tuple = TOLERANCES
    skip_fixed: tuple = field(default_factory=tuple)  # tolerances whose fixed search is too costly
    # with integrator="auto": the schemes the fixed setting is chosen from (cost in rhs evaluations)
    fixed_integrators: tuple = ()
    # tolerance_check= with each tolerance (True: the companion run's global error estimate)
    check: bool = False


def _top(spin, tilt, side=0.0):
    inertia = np.array([0.45, 0.45, 0.3])
    return {
        "angular_momentum": np.array([side, 0.0, spin]) * inertia,
        "vertical": np.array([math.sin(tilt), 0.0, math.cos(tilt)]),
    }


def _body(inertia, omega):
    return {"angular_momentum": np.array(inertia) * np.array(omega)}


TOLERANCE_CASES = (
    ToleranceCase(
        "fb_fast",
        "free body, rk4, |Omega| 5e3-1e4 rad/s (random)",
        "free_body",
        dict(
            task="detumble",
            spin_rate=1e4,
            max_angular_velocity=2e4,
            max_torque=0.0,
            integrator="rk4",
        ),
        (0, 1, 2),
        4,
    ),
    ToleranceCase(
        "fb_separatrix",
        "free body, rk4, 1e-6 off the separatrix, 1 rad/s",
        "free_body",
        dict(max_torque=0.0, integrator="rk4"),
        (_body((2.0, 1.5, 1.0), (1e-6, 1.0, 1e-6)), _body((2.0, 1.5, 1.0), (0.05, 1.0, 0.0))),
        400,
    ),
    ToleranceCase(
        "fb_equal",
        "free body, rk4, moments equal to 1e-9, 10 rad/s",
        "free_body",
        dict(
            inertia=(1.5, 1.5 * (1 + 1e-9), 1.0),
            axis=0,
            max_torque=0.0,
            integrator="rk4",
            max_angular_velocity=20.0,
        ),
        (_body((1.5, 1.5 * (1 + 1e-9), 1.0), (6.0, 6.0, 5.0)),),
        400,
    ),
    # beside the bench's: a nearly symmetric body and the default body at 5 rad/s, from near a
    # stable axis, 0.002-0.004 off the separatrix and in between (error_rate's sigma term)
    ToleranceCase(
        "fb_near_symmetric",
        "free body, rk4, moments (1.5, 1.45, 1), 5 rad/s, 3 starts",
        "free_body",
        dict(
            inertia=(1.5, 1.45, 1.0),
            axis=0,
            max_torque=0.0,
            integrator="rk4",
            max_angular_velocity=50.0,
        ),
        tuple(
            _body((1.5, 1.45, 1.0), w)
            for w in ((5.0, 1.0, 0.5), (0.01, 5.0, 0.01), (3.0, 3.0, 3.0))
        ),
        200,
    ),
    ToleranceCase(
        "fb_triaxial",
        "free body, rk4, moments (2, 1.5, 1), 5 rad/s, 3 starts (one 0.002 off the separatrix)",
        "free_body",
        dict(
            inertia=(2.0, 1.5, 1.0),
            axis=0,
            max_torque=0.0,
            integrator="rk4",
            max_angular_velocity=50.0,
        ),
        tuple(
            _body((2.0, 1.5, 1.0), w)
            for w in ((5.0, 3.0, 0.05), (0.01, 5.0, 0.01), (-2.0, 4.0, 6.0))
        ),
        200,
    ),
    # the same starts over the free body's own episode (400 periods, 20 s): the start 0.002 off the
    # separatrix amplifies its error beyond a local estimate (docs/accuracy.md, "Unstable motions")
    ToleranceCase(
        "fb_triaxial_episode",
        "free body, rk4, moments (2, 1.5, 1), 5 rad/s, fb_triaxial's starts over 400 periods",
        "free_body",
        dict(
            inertia=(2.0, 1.5, 1.0),
            axis=0,
            max_torque=0.0,
            integrator="rk4",
            max_angular_velocity=50.0,
        ),
        tuple(
            _body((2.0, 1.5, 1.0), w)
            for w in ((5.0, 3.0, 0.05), (0.01, 5.0, 0.01), (-2.0, 4.0, 6.0))
        ),
        400,
    ),
    ToleranceCase(
        "fb_euler",
        "free body, euler, 1 rad/s",
        "free_body",
        dict(max_torque=0.0, integrator="euler"),
        (0, 1),
        400,
        skip_fixed=(1e-6, 1e-9),
    ),
    ToleranceCase(
        "fb_auto",
        "free body, integrator='auto', 1 rad/s (fb_euler's starts)",
        "free_body",
        dict(max_torque=0.0, integrator="auto"),
        (0, 1),
        400,
        fixed_integrators=("euler", "rk4"),
    ),
    ToleranceCase(
        "top_100",
        "Lagrange top, rk4, 100 rad/s, tilt 0.1",
        "heavy_top",
        dict(integrator="rk4", max_torque=0.0, max_angular_velocity=300.0),
        (_top(100.0, 0.1), _top(100.0, 0.1, 3.0)),
        50,
    ),
    ToleranceCase(
        "top_1e4",
        "Lagrange top, rk4, 1e4 rad/s, tilt 0.1",
        "heavy_top",
        dict(integrator="rk4", max_torque=0.0, max_angular_velocity=2.1e4),
        (_top(1e4, 0.1),),
        2,
    ),
    ToleranceCase(
        "top_below",
        "Lagrange top, rk4, 5 rad/s (below the critical 9.9), tilt 0.05",
        "heavy_top",
        dict(integrator="rk4", max_torque=0.0),
        (_top(5.0, 0.05),),
        50,
    ),
    ToleranceCase(
        "top_euler",
        "Lagrange top, euler, 20 rad/s (twice the critical), tilt 0.1",
        "heavy_top",
        dict(integrator="euler", max_torque=0.0),
        (_top(20.0, 0.1),),
        50,
        skip_fixed=(1e-6, 1e-9),
    ),
    ToleranceCase(
        "top_auto",
        "Lagrange top, integrator='auto', 20 rad/s, tilt 0.1 (top_euler's start)",
        "heavy_top",
        dict(integrator="auto", max_torque=0.0),
        (_top(20.0, 0.1),),
        50,
        fixed_integrators=("euler", "rk4"),
    ),
    # the tippe top: each seed its own spin and tilt (the scene's 150 rad/s at tilt 0.1 is inside);
    # from rest (sliding into rolling within the horizon) and rolling
    ToleranceCase(
        "tippe",
        "tippe top, rk4, Coulomb friction, from rest, 100-200 rad/s, tilt 0.05-0.6, seeds 0-2",
        "tippe_top",
        dict(integrator="rk4", max_torque=0.0, spin=(100.0, 200.0), tilt=(0.05, 0.6)),
        (0, 1, 2),
        10,
    ),
    ToleranceCase(
        "tippe_rolling",
        "tippe top, rk4, Coulomb friction, rolling start, 100-200 rad/s, tilt 0.05-0.6, seeds 0-1",
        "tippe_top",
        dict(
            integrator="rk4", max_torque=0.0, spin=(100.0, 200.0), tilt=(0.05, 0.6), start="rolling"
        ),
        (0, 1),
        10,
    ),
    ToleranceCase(
        "tippe_viscous",
        "tippe top, rk4, viscous friction 3 s/m, from rest, 100-200 rad/s, tilt 0.05-0.6, seeds "
        "0-2",
        "tippe_top",
        dict(
            integrator="rk4",
            max_torque=0.0,
            friction_law="viscous",
            friction=3.0,
            spin=(100.0, 200.0),
            tilt=(0.05, 0.6),
        ),
        (0, 1, 2),
        10,
    ),
)


# the scenes' rows: each shipped scene (configs/scenes) uncontrolled from seeds 0-2 (the tippe top:
# seed 0) over its own episode (the tippe top: SCENE_TIPPE_HORIZON s, through the inversion of the
# inverting scenes: `rbenvs bench accuracy --tippe` prints its t90); the scene's scheme where a
# tolerance takes it, rk4 where not (the tops' default splitting), its substeps left to the rule
SCENE_TIPPE_HORIZON = 4.0
SCENE_PREFIX = "scene:"
_SCENE_ENVS = {
    "rbenvs/FreeRigidBody-v0": "free_body",
    "rbenvs/LagrangeTop-v0": "heavy_top",
    "rbenvs/TippeTop-v0": "tippe_top",
}


def scene_cases(names=None) -> tuple:
    """:class:`ToleranceCase` rows for the shipped scenes (``names``: a subset), keyed
    ``scene:<name>`` (needs PyYAML, the ``cli`` extra, as every scene does)."""
    from ..scenes import list_scenes, load_scene

    cases = []
    for name in names or list_scenes():
        scene = load_scene(name)
        env = _SCENE_ENVS[scene.env_id]
        kwargs = {k: v for k, v in scene.kwargs.items() if k not in ("substeps", "integrator")}
        kwargs["integrator"] = "rk4"
        if env != "tippe_top":
            kwargs["max_torque"] = 0.0
        probe = scene.make(**kwargs, tolerance=None)
        episode = probe.spec.max_episode_steps
        dt = probe.unwrapped.dt
        probe.close()
        periods = (
            min(episode, int(round(SCENE_TIPPE_HORIZON / dt))) if env == "tippe_top" else episode
        )
        starts = (0,) if env == "tippe_top" else (0, 1, 2)
        seeds = f"seeds {starts[0]}-{starts[-1]}" if len(starts) > 1 else f"seed {starts[0]}"
        label = (
            f"scene {name}, rk4, uncontrolled, {periods} periods "
            f"({periods * dt:g} s{', its episode' if periods == episode else ''}), {seeds}"
        )
        cases.append(ToleranceCase(SCENE_PREFIX + name, label, env, kwargs, starts, periods))
    return tuple(cases)


# the rows whose motion amplifies errors beyond the tolerance (docs/accuracy.md, "Unstable
# motions") run again with tolerance_check=True, keyed "<key>+check": within the tolerance, or ended
# as a numerical failure where the global error estimate passes it
CHECKED = ("fb_triaxial_episode", "scene:tippe_hop")
CHECK_SUFFIX = "+check"


def _checked(case):
    return dataclasses.replace(
        case, key=case.key + CHECK_SUFFIX, label=case.label + ", tolerance_check=True", check=True
    )


def _plain_key(key):
    return key[: -len(CHECK_SUFFIX)] if key.endswith(CHECK_SUFFIX) else key


def all_cases(keys=None) -> tuple:
    """:data:`TOLERANCE_CASES` and, where ``keys`` asks for them (or is ``None``: all), the scenes'
    rows (:func:`scene_cases`), then the :data:`CHECKED` rows with ``tolerance_check=True``
    (``<key>+check``)."""
    plain = None if keys is None else {_plain_key(k) for k in keys}
    cases = tuple(c for c in TOLERANCE_CASES if plain is None or c.key in plain)
    scenes = (
        None
        if plain is None
        else [k[len(SCENE_PREFIX) :] for k in plain if k.startswith(SCENE_PREFIX)]
    )
    if scenes is None or scenes:
        cases += scene_cases(scenes)
    checked = tuple(
        _checked(c)
        for c in cases
        if c.key in CHECKED and (keys is None or c.key + CHECK_SUFFIX in keys)
    )
    return tuple(c for c in cases if keys is None or c.key in keys) + checked


def _env(case, **kw):
    from ..envs import FreeRigidBodyEnv, LagrangeTopEnv, TippeTopEnv, UnstableMotionWarning

    cls = {"free_body": FreeRigidBodyEnv, "heavy_top": LagrangeTopEnv, "tippe_top": TippeTopEnv}[
        case.env
    ]
    kw = {
        "tolerance": None,
        **case.kwargs,
        **kw,
    }  # (the rows without a tolerance and the fixed settings: unchecked)
    with (
        warnings.catch_warnings()
    ):  # (the bench measures what the warning says: the table shows it)
        warnings.simplefilter("ignore", UnstableMotionWarning)
        return cls(**kw)


def _reset(env, start):
    if isinstance(start, int):
        env.reset(seed=start)
    else:
        env.reset(seed=0, options={"state": start})
    return env.state_components


def _references(case, env, starts):
    """Per start, the reference state after each period."""
    from ..integrators.reference import REFERENCE
    from ..oracles import exact_solution

    refs = []
    for start in starts:
        y0 = _reset(env, start)
        if case.env == "free_body" and not env.system.attitude:
            pi0 = np.array(y0)
            refs.append(
                [
                    tuple(exact_solution(env.system.params.inertia, pi0, k * env.dt))
                    for k in range(1, case.periods + 1)
                ]
            )
            continue
        if env.system.hybrid:
            # through the env's own switching layer (lift-off, touchdown, the stem's contact), as
            # every run compared with it: REFERENCE.step alone would integrate across a switch
            ref_env = _env(
                dataclasses.replace(case, kwargs=dict(case.kwargs, integrator=REFERENCE))
            )
            _reset(ref_env, start)
            a = np.zeros(ref_env.action_space.shape, np.float32)
            out = []
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                for _ in range(case.periods):
                    ref_env.step(a)
                    out.append(ref_env.state_components)
            refs.append(out)
            continue
        y, out = y0, []
        for _ in range(case.periods):
            y = REFERENCE.step(env.system, y, None, env.dt)
            out.append(y)
        refs.append(out)
    return refs


def _episode(case, env, starts, refs):
    """``(error, summed estimate, internal steps, failure)`` over the starts; ``error`` up to the
    end of each episode (where a numerical failure ends one: up to the state it keeps, the last
    one within; ``failure`` then says where), the companions' steps (``tolerance_check``) counted
    in ``steps``."""
    err = est_max = 0.0
    steps = 0
    failure = None
    a = np.zeros(env.action_space.shape, np.float32)
    from ..stepsize.controller import companion_steps, tolerance_blocks
    from ..stepsize.forms import relative_difference

    checked = bool(env.engine.check)  # (tolerance_check: a companion run beside the state)
    # the measured blocks: the tippe top's horizontal position (it drifts) and its contact flags
    # (counts, not quantities) left out
    blocks = tolerance_blocks(env.system)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i, (start, ref) in enumerate(zip(starts, refs)):
            _reset(env, start)
            est = 0.0
            for k, r in enumerate(ref):
                _, _, term, _, info = env.step(a)
                n = int(round(env.dt / info["internal_step"]))
                steps += n + (
                    companion_steps(n) if checked else 0
                )  # (the companion: n / 2 steps of 2 h)
                est += info.get("error_estimate") or 0.0  # (None: not estimated)
                if info["numerical_failure"]:
                    if failure is None:
                        by = (
                            "the global error estimate passed the tolerance"
                            if "global_error_estimate" in info
                            else "a numerical failure"
                        )
                        failure = f"ended: {by} at period {k + 1} of start {i}"
                    if "global_error_estimate" not in info:
                        err = math.inf
                    break
                # per block |y_b - ref_b| / |ref_b|, as the companion measures (a block the
                # reference keeps at zero, a top at rest: 0 where the state does too)
                err = max(err, relative_difference(blocks, r, env.state_components))
                # the episode ends here: the tolerance is per episode (a task's end is no failure)
                if term:
                    if info.get("terminal_reason") not in (None, "task") and failure is None:
                        failure = info["terminal_reason"]
                    break
            est_max = max(est_max, est)
    return err, est_max, steps, failure


def _cheapest_fixed(case, tol, starts, refs, hint, limit=None):
    """The fewest ``substeps`` (no tolerance) whose error meets ``tol`` on every start, and its
    steps (bisection between 1 and a count that meets it; ``None`` past MAX_FIXED, or past
    ``limit`` substeps where given: a search that cannot beat a cheaper scheme stops there)."""
    from ..stepsize.controller import MAX_INTERNAL_STEPS

    def run(n):
        env = _env(case, substeps=n)
        err, _, steps, failure = _episode(case, env, starts, refs)
        return (err <= tol and failure is None), steps

    top = (
        min(MAX_FIXED, MAX_INTERNAL_STEPS)
        if limit is None
        else min(MAX_FIXED, MAX_INTERNAL_STEPS, max(1, int(limit)))
    )
    hi = min(max(1, hint), top)
    ok, steps_hi = run(hi)
    while not ok:
        if hi >= top:
            return None
        hi = min(2 * hi, top)
        ok, steps_hi = run(hi)
    lo = 0  # fails (or none)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        ok, steps_mid = run(mid)
        if ok:
            hi, steps_hi = mid, steps_mid
        else:
            lo = mid
    return hi, steps_hi


def run_tolerance(keys=None, progress=None, fixed=True) -> dict:
    """Every case of :data:`TOLERANCE_CASES` and every scene (:func:`scene_cases`; ``keys``: a
    subset) at each of its tolerances; ``fixed=False`` skips the search for the cheapest fixed
    substeps (the tests' run)."""
    constants = _error_constants()
    rows = []
    for case in all_cases(keys):
        row, refs = _base_row(case)
        rows.append(row)
        for tol in case.tolerances:
            row = _tolerance_row(case, tol, refs, fixed)
            rows.append(row)
            # (a refused tolerance ran nothing: no progress)
            if "refused" not in row and progress:
                progress()
    return {"constants": constants, "rows": rows}


def _error_constants() -> dict:
    """Per scheme with an error constant: the declared one and the measured one."""
    from ..integrators import INTEGRATORS
    from ..integrators.error import measure_error_constant

    return {
        name: {"declared": cls.error_constant, "measured": measure_error_constant(name)}
        for name, cls in INTEGRATORS.items()
        if cls.error_constant is not None
    }


def _row_head(case, tol) -> dict:
    """The keys every row starts with."""
    return {"case": case.key, "label": case.label, "periods": case.periods, "tolerance": tol}


def _base_row(case):
    """``(row, refs)``: the case without a tolerance (its row, ``tolerance`` ``None``) and the
    reference states every row of the case is compared with."""
    # (integrator="auto" needs a tolerance: the row without one runs the last of the fixed
    # schemes, rk4)
    base = _env(
        case
        if not case.fixed_integrators
        else dataclasses.replace(
            case, kwargs=dict(case.kwargs, integrator=case.fixed_integrators[-1])
        )
    )
    refs = _references(case, base, case.starts)
    base_err, _, base_steps, base_fail = _episode(case, base, case.starts, refs)
    row = {**_row_head(case, None), "error": base_err, "steps": base_steps, "failure": base_fail}
    return row, refs


def _tolerance_row(case, tol, refs, fixed) -> dict:
    """The case at tolerance ``tol``: refused at construction, or its error, estimate, steps and
    (``fixed``) the cheapest fixed setting that meets it."""
    t0 = time.perf_counter()
    try:
        env = _env(
            case,
            tolerance=tol,
            tolerance_horizon=case.periods,
            **({"tolerance_check": case.check} if case.check else {}),
        )
    except ValueError as e:
        return {**_row_head(case, tol), "refused": str(e)}
    err, est, steps, failure = _episode(case, env, case.starts, refs)
    row = {
        **_row_head(case, tol),
        "error": err,
        "estimate": est,
        "steps": steps,
        "failure": failure,
        "seconds": time.perf_counter() - t0,
        "integrator": env.integrator.name,
    }
    # (an episode ended by a numerical failure ran fewer periods: no cost to compare)
    if fixed and tol not in case.skip_fixed and not (failure or "").startswith("ended"):
        _add_fixed(row, case, tol, refs)
    return row


def _add_fixed(row, case, tol, refs) -> None:
    """Add to ``row`` the cheapest fixed setting that meets ``tol`` (``fixed_substeps``,
    ``fixed_steps``, ``cost_ratio``; with ``integrator="auto"`` also ``fixed_integrator``, the
    cost in rhs evaluations); nothing where none does."""
    from ..integrators import get_integrator

    steps = row["steps"]
    per_period = max(1, steps // (case.periods * len(case.starts)))
    if not case.fixed_integrators:
        found = _cheapest_fixed(case, tol, case.starts, refs, max(1, per_period // 4))
        if found is not None:
            row["fixed_substeps"], row["fixed_steps"] = found
            row["cost_ratio"] = steps / found[1]
        return
    chosen = get_integrator(row["integrator"]).evaluations
    best = _cheapest_scheme(case, tol, refs, row["integrator"], per_period)
    if best is not None:
        row["fixed_integrator"] = best[0]
        row["fixed_substeps"], row["fixed_steps"] = best[1]
        row["cost_ratio"] = steps * chosen / best[2]


def _cheapest_scheme(case, tol, refs, chosen, per_period):
    """With ``integrator="auto"``: ``(scheme, (substeps, steps), rhs evaluations)`` of the
    cheapest of ``case.fixed_integrators`` whose fewest fixed substeps meet ``tol`` (the scheme
    ``tolerance=`` chose searched first), or ``None``."""
    from ..integrators import get_integrator

    best = None
    for name in sorted(case.fixed_integrators, key=lambda n: n != chosen):
        evaluations = get_integrator(name).evaluations
        sub = dataclasses.replace(case, kwargs=dict(case.kwargs, integrator=name))
        # a scheme is searched only up to the substeps whose rhs evaluations would cost what the
        # best so far costs
        limit = None if best is None else best[2] / (evaluations * case.periods * len(case.starts))
        found = _cheapest_fixed(sub, tol, case.starts, refs, max(1, per_period // 4), limit)
        if found is not None and (best is None or found[1] * evaluations < best[2]):
            best = (name, found, found[1] * evaluations)
    return best


def _g(x, fmt=".1e"):
    return "-" if x is None else format(x, fmt)


def print_tolerance(result, file=None):
    file = sys.stdout if file is None else file
    head = "error constants C (global error C lambda T (lambda h)^p on a rotation)"
    print(f"{head}, measured against declared:", file=file)
    for name, c in result["constants"].items():
        print(f"  {name:<6} measured {c['measured']:.6g}  declared {c['declared']:g}", file=file)
    print(
        "\ntolerance=: worst relative error of the state over the horizon against the reference, "
        "summed estimate, internal steps;",
        file=file,
    )
    print(
        "fixed: the fewest equal substeps (no tolerance) that meet the same tolerance on every "
        "start; cost x = steps / fixed steps",
        file=file,
    )
    w = max([14] + [len(r["case"]) for r in result["rows"]])
    print(
        f"{'case':<{w}} {'periods':>7} {'tolerance':>9} {'error':>8} {'estimate':>8} {'steps':>10} "
        f"{'fixed':>7} {'fixed steps':>11} {'cost x':>6}  note",
        file=file,
    )
    for r in result["rows"]:
        tol = "none" if r["tolerance"] is None else f"{r['tolerance']:.0e}"
        if "refused" in r:
            reason = r["refused"]
            if "cannot be met" in reason:
                short = reason.split(" internal steps")[0].replace(
                    f"tolerance={r['tolerance']!r} cannot be met: at the start the integrator ", ""
                )
                short += " internal steps a period"
            else:  # a scheme tolerance= does not take (its error in the amplitude)
                short = reason.split("(or integrator='auto'): ")[-1].split(", which")[0]
            print(
                f"{r['case']:<{w}} {r['periods']:>7} {tol:>9} {'refused':>8} {'':>8} {'':>10} "
                f"{'':>7} {'':>11} {'':>6}  {short}",
                file=file,
            )
            continue
        note = r.get("failure") or ""
        if r["tolerance"] is not None and (not note or note.startswith("ended")):
            note = ("within" if r["error"] <= r["tolerance"] else "OUTSIDE the tolerance") + (
                f" until {note}" if note else ""
            )
        if r.get("fixed_integrator"):  # integrator="auto": both schemes, cost in evaluations
            note += (
                f" (auto: {r['integrator']}; fixed: {r['fixed_integrator']}; "
                "cost x in rhs evaluations)"
            )
        fixed = r.get("fixed_substeps")
        print(
            f"{r['case']:<{w}} {r['periods']:>7} {tol:>9} {_g(r['error']):>8} "
            f"{_g(r.get('estimate')):>8} {r['steps']:>10} {_g(fixed, 'd'):>7} "
            f"{_g(r.get('fixed_steps'), 'd'):>11} {_g(r.get('cost_ratio'), '.2f'):>6}  {note}",
            file=file,
        )
    shown = {r["case"]: r["label"] for r in result["rows"]}
    print("\ncases: " + "; ".join(f"{k}: {label}" for k, label in shown.items()), file=file)
