"""``tolerance_check=True``: the companion run's estimate of an episode's global error
(:mod:`rbenvs.stepsize.controller`), checked against the free body's exact solution and the tippe
top's DOP853 reference, and the episode it ends."""

import copy
import dataclasses
import math
import pickle
import warnings

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from rbenvs.core.step import NumericalFailureWarning
from rbenvs.envs import FreeRigidBodyEnv, TippeTopEnv, UnstableMotionWarning
from rbenvs.oracles import exact_solution, taylor_solution
from rbenvs.stepsize.controller import companion_ratio, tolerance_blocks
from rbenvs.stepsize.forms import relative_difference

# Tests here set tolerances on motions the systems call unstable (the intermediate axis, a top below
# its critical spin, an inverting tippe top) on purpose: their UnstableMotionWarning is expected,
# and asserted where it is the subject:
# test_the_unstable_motion_warning_names_the_check_and_the_callers_line (pytest.warns sees it
# whatever this filter says). Every other warning fails the run (pyproject.toml: filterwarnings =
# error).
pytestmark = pytest.mark.filterwarnings("ignore::rbenvs.stepsize.controller.UnstableMotionWarning")

INERTIA = (2.0, 1.5, 1.0)
# fb_triaxial's starts (rbenvs bench accuracy --tolerance): near the major axis, 0.002 off the
# separatrix (the one whose error the motion amplifies), and in between
STARTS = ((5.0, 3.0, 0.05), (0.01, 5.0, 0.01), (-2.0, 4.0, 6.0))


def _body(tol, check=True, **kw):
    return FreeRigidBodyEnv(
        inertia=INERTIA,
        axis=0,
        max_torque=0.0,
        integrator="rk4",
        max_angular_velocity=50.0,
        tolerance=tol,
        tolerance_horizon=400,
        tolerance_check=check,
        **kw,
    )


def _relative(y, ref):
    return float(np.linalg.norm(np.subtract(y, ref)) / np.linalg.norm(ref))


def test_the_ratio_and_the_difference_by_hand():
    assert companion_ratio(4) == 15.0 and companion_ratio(1) == 1.0
    blocks = ((0, 2), (2, 3))
    y, yc = (3.0, 4.0, 0.0), (3.0, 4.5, 0.0)
    assert relative_difference(blocks, y, yc) == pytest.approx(
        0.1
    )  # |(0, 0.5)| / 5; the zero block: 0
    assert (
        relative_difference(blocks, y, (3.0, 4.0, 1e-3)) == math.inf
    )  # a block of norm 0 that differs
    batch = tuple(np.array([a, b]) for a, b in zip(y, (1.0, 0.0, 2.0)))
    batch_c = tuple(np.array([a, b]) for a, b in zip(yc, (1.0, 0.0, 1.0)))
    assert np.array_equal(
        relative_difference(blocks, batch, batch_c), [relative_difference(blocks, y, yc), 0.5]
    )


def test_the_measured_blocks_leave_out_the_tippe_tops_position_and_flags():
    env = TippeTopEnv()
    names = [
        n for n, span in env.system.layout.items() if tuple(span) in tolerance_blocks(env.system)
    ]
    assert (
        "position" not in names
        and "contact" not in names
        and "velocity" in names
        and "attitude" in names
    )
    assert tolerance_blocks(FreeRigidBodyEnv().system) == tuple(
        tuple(s) for s in FreeRigidBodyEnv().system.layout.values()
    )


@pytest.mark.parametrize("start", STARTS)
@pytest.mark.parametrize("tol", [1e-3, 1e-6, 1e-9])
def test_the_estimate_bounds_the_free_bodys_error_and_ends_the_episode_where_it_passes(start, tol):
    """Against the exact solution over the free body's 400-period episode: on every period whose
    error is above roundoff the estimate is at least the error and at most 3 times it; the
    episode ends (a numerical failure, with a warning saying so) exactly where the estimate
    passes the tolerance, keeping the last state within it, whose error is within it too."""
    env = _body(tol)
    pi0 = np.array(INERTIA) * np.array(start)
    _, info = env.reset(seed=0, options={"state": {"angular_momentum": pi0}})
    assert info["global_error_estimate"] == 0.0
    a = np.zeros(env.action_space.shape, np.float32)
    ended = None
    for k in range(1, 401):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _, _, terminated, _, info = env.step(a)
        assert (
            round(env.dt / info["internal_step"]) % 2 == 0
        )  # an even count: the companion takes half
        if info["numerical_failure"]:
            assert terminated and info["terminal_reason"] == "numerical_failure"
            assert info["global_error_estimate"] > tol
            assert any(
                issubclass(w.category, NumericalFailureWarning)
                and "global error estimate" in str(w.message)
                for w in caught
            )
            ended = k
            break
        err = _relative(env.state_components, exact_solution(INERTIA, pi0, k * env.dt))
        est = info["global_error_estimate"]
        assert est <= tol
        if err > 1e-11:
            assert err <= est <= 3.0 * err, (k, err, est)
    if ended is not None:  # the state kept: the last one within, after ended - 1 periods
        assert (
            _relative(env.state_components, exact_solution(INERTIA, pi0, (ended - 1) * env.dt))
            <= tol
        )
    if start == (0.01, 5.0, 0.01) and tol == 1e-9:
        assert (
            ended is not None
        )  # the near-separatrix start passes 1e-9 (2.3e-9 without the check: the bench's row)


def test_reset_restarts_the_companion_and_the_env_copies_and_pickles():
    env = _body(1e-9)
    pi0 = np.array(INERTIA) * np.array(STARTS[1])
    a = np.zeros(env.action_space.shape, np.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalFailureWarning)
        runs = []
        for _ in range(2):
            env.reset(seed=0, options={"state": {"angular_momentum": pi0}})
            estimates = []
            for _ in range(400):
                _, _, terminated, _, info = env.step(a)
                estimates.append(info["global_error_estimate"])
                if terminated:
                    break
            assert info["numerical_failure"]
            runs.append(estimates)
        assert runs[0] == runs[1]  # the same episode again: the companion restarted with the state
        env.reset(seed=0, options={"state": {"angular_momentum": pi0}})
        for _ in range(50):
            env.step(a)
        twin, loaded = copy.deepcopy(env), pickle.loads(pickle.dumps(env))
        for _ in range(50):
            out = [e.step(a)[4]["global_error_estimate"] for e in (env, twin, loaded)]
            assert out[0] == out[1] == out[2]
            assert env.state_components == twin.state_components == loaded.state_components


def test_the_checked_env_passes_gymnasiums_checker():
    check_env(_body(1e-6), skip_render_check=True)


def test_tolerance_check_is_validated():
    # (False or True; the rule names both, and 'refine', removed, says what to use instead)
    for bad in ("auto", "True", 1, "Refine"):
        with pytest.raises(ValueError, match=r"tolerance_check must be False or True \("):
            _body(1e-6, check=bad)
    with pytest.raises(ValueError, match="tolerance_check=True needs tolerance="):
        FreeRigidBodyEnv(tolerance_check=True, tolerance=None)
    with pytest.raises(
        ValueError, match=r"tolerance_check='refine' was removed .*use tolerance_check=True"
    ):
        _body(1e-6, check="refine")
    from rbenvs import compiled

    if (
        compiled.available()
    ):  # the single env's checked period runs compiled (rbenvs.compiled.CheckedRuns)
        assert _body(1e-6, compiled=True).engine.forms.checked_runs is not None
    else:
        with pytest.raises(ValueError, match="compiled=True but numba is not installed"):
            _body(1e-6, compiled=True)
    assert _body(1e-6, compiled=False).engine.forms.checked_runs is None
    from rbenvs.vector import FreeRigidBodyVectorEnv

    with pytest.raises(ValueError, match="compiled=True cannot be had with tolerance_check=True"):
        FreeRigidBodyVectorEnv(
            2, compiled=True, inertia=INERTIA, axis=0, tolerance=1e-6, tolerance_check=True
        )
    assert not FreeRigidBodyVectorEnv(
        2, inertia=INERTIA, axis=0, tolerance=1e-6, tolerance_check=True
    ).compiled  # (numpy)


def _checked_run_inputs(env, periods, every, switches=3):
    """``(y, comp, u, n)`` at the start of every ``every``-th period of an uncontrolled episode
    of ``env`` (a tolerance, no check: the compiled state step), and of the first ``switches``
    periods where the contact flag or the hop count changes (a switch inside it), ``n`` the
    guard's count made even."""
    engine = env.engine
    a = np.zeros(env.action_space.shape, np.float32)
    u = engine.control(tuple(float(v) for v in a))[1]
    flags = [b for name, (b, _) in env.system.layout.items() if name in ("contact", "hops")]
    out = []
    for k in range(periods):
        y, comp = tuple(env.state_components), engine.comp
        n = int(engine.rule.steps(y, u, engine.substeps))
        _, _, term, trunc, _ = env.step(a)
        switched = any(env.state_components[i] != y[i] for i in flags)
        if k % every == 0 or (switched and switches > 0):
            out.append((y, comp, u, n + (n & 1)))
            switches -= switched
        if term or trunc:
            break
    return out


@pytest.mark.parametrize(
    "scene",
    [None, "top_precess", "tippe", "hops", "tippe_leine_glocker"],
    ids=["free_body", "heavy_top", "tippe_from_rest", "tippe_flight_hops", "tippe_stem_switches"],
)
def test_the_checked_periods_compiled_runs_are_the_float_paths_bits(scene):
    """The checked period's runs compiled (:class:`rbenvs.compiled.CheckedRuns`, the single env's
    with numba) against the float path's :meth:`rbenvs.core.period.Period._run_one`, bit for bit:
    the main run's count and step, the companion's half as many of twice the size, from
    states along an episode (with free flight: every period with a take-off or touchdown inside
    it, a top hopping many times a period; with the stem: every period that lands on it or
    leaves it), compensations carried; and the period's plan (:class:`rbenvs.compiled.PeriodPlan`:
    the guard's ratio, the rates and the decaying mode's rate and share its estimate reads)
    against :meth:`StepRule.plan` at the same states, under no control and a random one."""
    from rbenvs import compiled
    from rbenvs.scenes import load_scene

    if not compiled.available():
        pytest.skip("numba is not installed (the 'fast' extra): the checked period runs on floats")

    def make(**kw):
        with (
            warnings.catch_warnings()
        ):  # (the tippe tops invert: the warning is not what is tested here)
            warnings.simplefilter("ignore", UnstableMotionWarning)
            if scene is None:
                return _body(1e-6, **kw)
            if scene == "tippe":
                return TippeTopEnv(integrator="rk4", tolerance=1e-6, **kw)
            if (
                scene == "hops"
            ):  # (tests/test_tippe_top_flight.py's top that hops many times a period)
                return TippeTopEnv(
                    integrator="rk4",
                    tolerance=1e-3,
                    spin=1000.0,
                    friction=1.0,
                    tilt=0.01,
                    free_flight=True,
                    max_speed=20.0,
                    start="rolling",
                    friction_bound="stability",
                    **kw,
                )
            return load_scene(scene).make(integrator="rk4", tolerance=1e-6, **kw).unwrapped

    source = make(check=False) if scene is None else make(tolerance_check=False)
    source.reset(seed=0)
    inputs = _checked_run_inputs(
        source, *{None: (200, 40), "hops": (110, 20)}.get(scene, (400, 40))
    )
    fast = (make(check=True) if scene is None else make(tolerance_check=True)).engine
    slow = (
        make(check=True, compiled=False)
        if scene is None
        else make(tolerance_check=True, compiled=False)
    ).engine
    assert fast.forms.checked_runs is not None and slow.forms.checked_runs is None
    assert fast.forms.planner is not None and slow.forms.planner is None
    rng = np.random.default_rng(5)
    switched = 0
    for y, comp, u, n in inputs:
        for v in (
            u,
            fast.control(tuple(float(c) for c in rng.uniform(-1.0, 1.0, fast.actuator.size)))[1],
        ):
            plan = fast.forms.plan_one(y, v)
            assert plan == slow.forms.plan_one(y, v) == slow.rule.plan(y, v), plan
        count = fast.rule.count(fast.forms.plan_one(y, u)[0], fast.substeps)
        assert count + (count & 1) == n  # (the inputs' count, the guard's made even, is the plan's)
        for c, h in ((n, fast.dt / n), (n // 2, 2.0 * fast.dt / n)):
            assert fast.period._run_one(y, u, c, h, comp) == slow.period._run_one(
                y, u, c, h, comp
            ), c
        flag = slow.system.layout.get("hops", slow.system.layout.get("contact", (0, 0)))[
            0
        ]  # (flight: the hops it counts)
        switched += (
            scene in ("hops", "tippe_leine_glocker")
            and slow.period._run_one(y, u, n, fast.dt / n, comp)[0][flag] != y[flag]
        )
    assert len(inputs) >= 5
    if scene in ("hops", "tippe_leine_glocker"):
        assert switched >= 1  # (a period with a switch inside it was among them)


@pytest.mark.parametrize(
    "scene",
    [None, "top_precess", "tippe", "hops", "tippe_leine_glocker"],
    ids=["free_body", "heavy_top", "tippe_from_rest", "tippe_flight_hops", "tippe_stem_switches"],
)
def test_the_batchs_compiled_rates_are_numpys_bits(scene):
    """The vector env's error estimate reads a batch's rates
    (:meth:`CompiledForms.rates_batch`) and its checked period counts the guard's steps
    (:meth:`CompiledForms.counts`): compiled in one loop
    (:meth:`rbenvs.compiled.PeriodPlan.batch`, ``ratios``) they are numpy's bits and each
    element's are the single state's plan's (:meth:`StepRule.plan`, :meth:`StepRule.count`),
    over states along an episode (flight, the stem's landings) under random controls."""
    from rbenvs import compiled
    from rbenvs.scenes import load_scene

    if not compiled.available():
        pytest.skip("numba is not installed (the 'fast' extra): the rates run on numpy")

    def make(**kw):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnstableMotionWarning)
            if scene is None:
                return _body(1e-6, check=False, **kw)
            if scene == "tippe":
                return TippeTopEnv(integrator="rk4", tolerance=1e-6, **kw)
            if scene == "hops":
                return TippeTopEnv(
                    integrator="rk4",
                    tolerance=1e-3,
                    spin=1000.0,
                    friction=1.0,
                    tilt=0.01,
                    free_flight=True,
                    max_speed=20.0,
                    start="rolling",
                    friction_bound="stability",
                    **kw,
                )
            return load_scene(scene).make(integrator="rk4", tolerance=1e-6, **kw).unwrapped

    source = make()
    source.reset(seed=0)
    states = [
        y
        for y, _, _, _ in _checked_run_inputs(
            source, *{None: (200, 10), "hops": (110, 5)}.get(scene, (400, 10))
        )
    ]
    fast, slow = make().engine, make(compiled=False).engine
    rng = np.random.default_rng(7)
    actions = rng.uniform(-1.0, 1.0, (len(states), fast.actuator.size))
    y = tuple(np.array(c) for c in zip(*states))
    u = fast.actuator.control(tuple(actions[:, j] for j in range(actions.shape[1])))[1]
    motion, n = fast.rule.motion, len(states)

    def columns(out):  # (lam's one or three, lam_d, a: each an (n,) array)
        lam, lam_d, a = out
        return [
            np.broadcast_to(np.asarray(v, dtype=np.float64), (n,))
            for v in (*(lam if motion else (lam,)), lam_d, a)
        ]

    got, want = columns(fast.forms.rates_batch(y, u)), columns(slow.forms.rates_batch(y, u))
    assert fast.forms.planner is not None and slow.forms.planner is None
    for g, w in zip(got, want):
        assert np.array_equal(g, w)
    # (the vector env's checked period's count: the ratios compiled)
    counts = fast.forms.counts(y, u)
    assert np.array_equal(counts, slow.forms.counts(y, u)) and np.array_equal(
        fast.forms.planner.ratios(*fast.forms.plan_inputs(fast.forms.planner, y, u)),
        np.broadcast_to(slow.rule.ratio(y, u), (n,)),
    )
    for i, state in enumerate(states):  # (each element: the single state's plan)
        x, r, rate, share = slow.rule.plan(
            state, tuple(float(np.broadcast_to(c, (n,))[i]) for c in u)
        )
        assert tuple(float(g[i]) for g in got) == (*(r if motion else (r,)), rate, share)
        assert counts[i] == slow.rule.count(x, slow.substeps)
    assert len(states) >= 5


def test_the_unstable_motion_warning_names_the_check_and_the_callers_line():
    from rbenvs.vector import TippeTopVectorEnv

    with pytest.warns(UnstableMotionWarning, match="tolerance_check=True estimates it") as caught:
        TippeTopEnv(tolerance=1e-6)
    with pytest.warns(UnstableMotionWarning, match="tolerance_check=True: a companion run"):
        TippeTopEnv(tolerance=1e-6, tolerance_check=True)
    with pytest.warns(UnstableMotionWarning) as caught_vector:
        TippeTopVectorEnv(2, tolerance=1e-6)
    # the line that built the env, not a line of the package (the vector env builds a single env)
    assert {
        w.filename for w in [*caught, *caught_vector] if w.category is UnstableMotionWarning
    } == {__file__}


@pytest.fixture(scope="module")
def hop_reference():
    """The hopping tippe top (scene tippe_hop, seed 0) through DOP853 at rtol 1e-13, the env's
    switching layer included: the state after each of its first 300 periods (of 400; the
    checked episode below ends at period 250)."""

    from rbenvs.bench.tolerance import _env, _references, scene_cases

    case = scene_cases(["tippe_hop"])[0]
    return case, _references(dataclasses.replace(case, periods=300), _env(case), (0,))[0]


def test_the_hopping_tippe_top_is_ended_within_the_tolerance(hop_reference):
    """The tippe top that hops while it inverts (scene tippe_hop, 180 rad/s, free flight; 1e-6
    over 4 s, outside without the check: rbenvs bench accuracy --tolerance) against DOP853 at
    rtol 1e-13 through the env's switching layer: the estimate is at least the error on every
    period above roundoff, and the episode ends where it passes 1e-6, the state kept within it."""
    from rbenvs.bench.tolerance import _env

    case, reference = hop_reference
    env = _env(case, tolerance=1e-6, tolerance_horizon=case.periods, tolerance_check=True)
    env.reset(seed=0)
    a = np.zeros(env.action_space.shape, np.float32)

    def error(y, r):
        return max(
            float(np.linalg.norm(np.subtract(y[lo:hi], r[lo:hi])) / np.linalg.norm(r[lo:hi]))
            for lo, hi in tolerance_blocks(env.system)
        )

    ended, previous = None, None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(1, case.periods + 1):
            _, _, terminated, _, info = env.step(a)
            if info["numerical_failure"]:
                ended = k
                assert (
                    error(env.state_components, previous) <= 1e-6
                )  # the state kept: the last period's
                break
            previous = reference[k - 1]  # (DOP853's state after period k: the fixture's)
            err = error(env.state_components, previous)
            if err > 1e-11:
                assert err <= info["global_error_estimate"] <= 3.0 * err, (
                    k,
                    err,
                    info["global_error_estimate"],
                )
            assert not terminated
    assert ended is not None and ended < len(reference)


@pytest.mark.parametrize("compiled", ["auto", False], ids=["runs_compiled", "numpy"])
@pytest.mark.parametrize("mode", ["next", "same"])
def test_the_vector_env_checks_each_sub_env_as_its_single_env(mode, compiled):
    """The vector env's companions (one per sub-env; their runs on numpy with ``compiled=False``,
    else sub-env by sub-env through the compiled runs) give each sub-env its single env's
    global error estimates, bit for bit, and end the same episodes at the same period (the
    near-separatrix start at 1e-9), restarting their companions with the sub-envs."""
    from gymnasium.vector import AutoresetMode

    from rbenvs.vector import FreeRigidBodyVectorEnv

    kw = dict(
        inertia=INERTIA,
        axis=0,
        max_torque=0.0,
        integrator="rk4",
        max_angular_velocity=50.0,
        tolerance=1e-9,
        tolerance_horizon=400,
        tolerance_check=True,
    )
    autoreset = AutoresetMode.NEXT_STEP if mode == "next" else AutoresetMode.SAME_STEP
    vec = FreeRigidBodyVectorEnv(
        len(STARTS), max_episode_steps=400, autoreset_mode=autoreset, compiled=compiled, **kw
    )
    singles = [FreeRigidBodyEnv(**kw) for _ in STARTS]
    pis = np.array([np.array(INERTIA) * np.array(w) for w in STARTS])
    _, vinfo = vec.reset(seed=0, options={"state": {"angular_momentum": pis}})
    assert np.array_equal(vinfo["global_error_estimate"], np.zeros(len(STARTS)))
    for env, pi0 in zip(singles, pis):
        env.reset(seed=0, options={"state": {"angular_momentum": pi0}})
    a = np.zeros(vec.action_space.shape, np.float32)
    ended, at = [], None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalFailureWarning)
        for k in range(300):
            obs, reward, terminated, _, info = vec.step(a)
            if (
                ended
            ):  # after the end: NEXT_STEP restarts the sub-env on the next step; the others go on
                rows = [j for j in range(len(STARTS)) if j != ended[0]]
                since = k - at
                if mode == "next" and since == 1:  # the restart: no period ran
                    assert info["global_error_estimate"][ended[0]] == 0.0
                elif (
                    since >= 1
                    # the restarted companion measures the new episode alone (a start drawn from the
                    # seed)
                ):
                    assert 0.0 < info["global_error_estimate"][ended[0]] < 1e-9
            else:
                rows = range(len(STARTS))
            final = info.get("final_info")
            for i in rows:
                o, r, t, _, single = singles[i].step(a[i])
                source = final if final is not None and info["_final_info"][i] else info
                assert source["global_error_estimate"][i] == single["global_error_estimate"], (k, i)
                assert bool(terminated[i]) == t and reward[i] == r
                if final is None or not info["_final_info"][i]:
                    assert np.array_equal(obs[i], o)
                if t:
                    assert single["numerical_failure"] and source["numerical_failure"][i]
                    ended.append(i)
                    at = k
                    if mode == "same":  # restarted in this step: its new episode's estimate is 0
                        assert info["global_error_estimate"][i] == 0.0
            if len(ended) and k > 240:
                break
    assert ended == [1]  # the near-separatrix start, alone


@pytest.mark.parametrize("compiled", ["auto", False], ids=["runs_compiled", "numpy"])
def test_the_vector_tippe_top_checks_as_its_single_envs(compiled):
    """The hybrid system (the contact's switches and the lift-off event in the companion's
    steps too): two sub-envs' estimates equal their single envs' over 60 periods."""
    from rbenvs.vector import TippeTopVectorEnv

    kw = dict(tolerance=1e-6, tolerance_horizon=400, tolerance_check=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableMotionWarning)
        vec = TippeTopVectorEnv(2, compiled=compiled, **kw)
        singles = [TippeTopEnv(**kw) for _ in range(2)]
    vec.reset(seed=3)
    for i, env in enumerate(singles):
        env.reset(seed=3 + i)
    a = np.zeros(vec.action_space.shape, np.float32)
    for _ in range(60):
        _, _, _, _, info = vec.step(a)
        for i, env in enumerate(singles):
            single = env.step(a[i])[4]
            assert info["global_error_estimate"][i] == single["global_error_estimate"] > 0.0
            assert info["internal_step"][i] == single["internal_step"]


def test_the_benchs_checked_rows_are_within_or_ended_with_the_message():
    """``rbenvs bench accuracy --tolerance``'s ``fb_triaxial_episode+check`` rows (its unchecked
    rows end 1.3 and 2.3 times outside 1e-6 and 1e-9): at every tolerance within it, up to the
    end of each episode or up to the state kept where the global error estimate ended one; the
    companion's steps counted."""
    from rbenvs.bench.tolerance import CHECK_SUFFIX, all_cases, run_tolerance

    key = "fb_triaxial_episode" + CHECK_SUFFIX
    assert [c.key for c in all_cases([key])] == [key] and all_cases([key])[0].check
    rows = [r for r in run_tolerance(keys=[key], fixed=False)["rows"] if r["tolerance"] is not None]
    assert len(rows) == 3
    for r in rows:
        assert r["error"] <= r["tolerance"], r
        assert r["failure"] is None or r["failure"].startswith(
            "ended: the global error estimate passed the tolerance"
        ), r
    plain = [
        r
        for r in run_tolerance(keys=["fb_triaxial_episode"], fixed=False)["rows"]
        if r["tolerance"] is not None
    ]
    assert all(
        c["steps"] > p["steps"] for c, p in zip(rows, plain)
    )  # the companion's steps and the even counts


@pytest.mark.parametrize("mode", ["next", "same"])
def test_the_vector_env_with_param_ranges_checks_each_sub_env_on_its_drawn_model(mode):
    """With param_ranges each sub-env steps its episode's own model and is checked by its own
    companion (the single env's GlobalErrorCheck.step_one): each sub-env's estimates are its
    single env's, bit for bit (with its drawn parameters), up to the period before the
    near-separatrix start's estimate passes 1e-9 (228); a partial reset (reset_mask) leaves the
    other sub-envs' runs, compensation included, going on."""
    from gymnasium.vector import AutoresetMode

    from rbenvs.vector import FreeRigidBodyVectorEnv

    # (the drawn torque bound leaves the motion under zero action unchanged, while each sub-env
    # runs a model, engine and check of its own)
    kw = dict(
        inertia=INERTIA,
        axis=0,
        max_torque=0.0,
        integrator="rk4",
        max_angular_velocity=50.0,
        tolerance=1e-9,
        tolerance_horizon=400,
        tolerance_check=True,
        param_ranges={"max_torque": (0.0, 0.5)},
    )
    autoreset = AutoresetMode.NEXT_STEP if mode == "next" else AutoresetMode.SAME_STEP
    vec = FreeRigidBodyVectorEnv(len(STARTS), max_episode_steps=400, autoreset_mode=autoreset, **kw)
    singles = [FreeRigidBodyEnv(**kw) for _ in STARTS]
    pis = np.array([np.array(INERTIA) * np.array(w) for w in STARTS])
    _, info = vec.reset(seed=0, options={"state": {"angular_momentum": pis}})
    for i, (env, pi0) in enumerate(zip(singles, pis)):
        single = env.reset(seed=i, options={"state": {"angular_momentum": pi0}})[1]
        assert info["params"]["max_torque"][i] == single["params"]["max_torque"]
    assert len(set(info["params"]["max_torque"].tolist())) == len(STARTS)
    a = np.zeros(vec.action_space.shape, np.float32)
    for k in range(220):
        if k == 100:  # sub-env 2 starts again; 0 and 1 go on
            mask = np.array([False, False, True])
            vec.reset(
                seed=[None, None, 9],
                options={"reset_mask": mask, "state": {"angular_momentum": pis}},
            )
            singles[2].reset(seed=9, options={"state": {"angular_momentum": pis[2]}})
        obs, reward, terminated, truncated, info = vec.step(a)
        final = info.get("final_info")
        for i, env in enumerate(singles):
            o, r, t, tr, single = env.step(a[i])
            source = final if final is not None and info["_final_info"][i] else info
            for key in ("error_estimate", "global_error_estimate", "internal_step"):
                assert source[key][i] == single[key], (k, i, key)
            assert bool(terminated[i]) == t and reward[i] == r
            if source is info:
                assert np.array_equal(obs[i], o)
    assert not terminated.any()
    assert (
        1e-10 < info["global_error_estimate"][1] <= 1e-9
    )  # (the near-separatrix start's, close to its end)


def _fixed_run(w, substeps, tolerance=None):
    """The default-like body from ``w`` over 400 periods at ``substeps`` a period (with a
    ``tolerance`` of 1e-3 the guard's count never passes them): the states and ``dt``."""
    env = FreeRigidBodyEnv(
        inertia=INERTIA,
        axis=0,
        max_torque=0.0,
        integrator="rk4",
        max_angular_velocity=50.0,
        substeps=substeps,
        tolerance=tolerance,
    )
    env.reset(seed=0, options={"state": {"angular_momentum": np.array(INERTIA) * np.array(w)}})
    a = np.zeros(env.action_space.shape, np.float32)
    out = []
    for _ in range(400):
        _, _, _, _, info = env.step(a)
        assert info["internal_step"] == env.dt / substeps
        out.append(env.state_components)
    return np.array(out), env.dt


def _apart(w, tolerance=None):
    """How far the runs at 200 and 400 substeps a period end apart (relative, worst period)."""
    (a, _), (b, _) = _fixed_run(w, 200, tolerance), _fixed_run(w, 400, tolerance)
    return float(np.max(np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)))


def test_float64_carries_no_better_than_about_1e_9_near_the_separatrix():
    """Fixed substeps sum plainly (docs/accuracy.md, "Roundoff"): near the intermediate axis
    roundoff is amplified, so two rk4 runs whose steps' error is far below 1e-12 (200 and 400
    substeps a period, 20 s) differ by the roundoff alone: above 1e-10 from 0.01 rad/s off the
    axis (measured 1.1e-9), below 1e-11 from 0.5 off (1.1e-12); and the near-separatrix start's
    run at 400 substeps ends some 1e-9 from the exact solution, no nearer than 1e-10 (measured
    8.5e-10)."""
    assert _apart((0.01, 5.0, 0.007)) > 1e-10
    assert _apart((0.5, 5.0, 0.35)) < 1e-11
    states, dt = _fixed_run(STARTS[1], 400)
    pi0 = np.array(INERTIA) * np.array(STARTS[1])
    worst = max(
        _relative(y, exact_solution(INERTIA, pi0, (k + 1) * dt)) for k, y in enumerate(states)
    )
    assert 1e-10 < worst < 1e-8


def test_a_tolerance_sums_the_steps_with_compensation_from_period_to_period():
    """With a tolerance the steps sum with compensation, carried from period to period (Kahan
    1965; docs/accuracy.md, "Roundoff"), and the floor above falls by two to four orders. The
    roundoff is chaotic (a start one ulp away changes it eightfold), so the bounds sit above the
    worst of eight starts near each, measured: the same two runs differ by less than 1e-11 from
    0.01 rad/s off the axis (1.3e-13 to 1.2e-12; summed plainly 8.8e-10 to 7.9e-9) and by less
    than 1e-9 from 0.001 off (7.1e-12 to 6.8e-11; plainly 2.1e-8 to 1.7e-7), and the
    near-separatrix start at 400 substeps ends within 1e-11 of the exact solution (2.4e-13 to
    6.2e-13 near it; plainly 3.6e-10 to 4.6e-9). The compensation goes on with the state: a
    copy and a pickle taken mid-episode step on as the env does, bit for bit."""
    assert _apart((0.01, 5.0, 0.007), 1e-3) < 1e-11
    assert _apart((0.001, 5.0, 0.0007), 1e-3) < 1e-9
    states, dt = _fixed_run(STARTS[1], 400, 1e-3)
    pi0 = np.array(INERTIA) * np.array(STARTS[1])
    assert (
        max(_relative(y, exact_solution(INERTIA, pi0, (k + 1) * dt)) for k, y in enumerate(states))
        < 1e-11
    )
    env = _body(1e-9)
    env.reset(
        seed=0, options={"state": {"angular_momentum": np.array(INERTIA) * np.array(STARTS[1])}}
    )
    a = np.zeros(env.action_space.shape, np.float32)
    for _ in range(50):
        env.step(a)
    twins = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    for _ in range(50):
        env.step(a)
        for twin in twins:
            twin.step(a)
            assert twin.unwrapped.state_components == env.unwrapped.state_components


def _within_until_ended(env, tol, reference):
    """Steps ``env`` (reset) uncontrolled over 400 periods, each period it returns within ``tol``
    of ``reference(k)`` (the state after ``k + 1`` periods): ``(ended, info, said)``, the period
    its episode ended at (``None``: ran its horizon), the last step's info and its warnings."""
    a = np.zeros(env.action_space.shape, np.float32)
    for k in range(400):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _, _, terminated, _, info = env.step(a)
        said = " ".join(str(m.message) for m in caught)
        if terminated:
            return k + 1, info, said
        assert _relative(env.state_components, reference(k)) <= tol, k
    return None, info, said


def _taylor_reference(w, periods, dt):
    """The body from the float64 ``Pi = I w`` over ``periods`` periods by mpmath's Taylor series
    (:func:`rbenvs.oracles.taylor_solution`; mpmath is a dev dependency: missing it must fail,
    not skip): float64's exact solution loses digits this near the separatrix."""
    return taylor_solution(
        INERTIA, np.array(INERTIA) * np.array(w), [(k + 1) * dt for k in range(periods)]
    )


@pytest.mark.parametrize(
    "w, tol",
    [
        ((1e-4, 5.0, 7e-5), 1e-9),
        ((3e-4, 5.0, 2.1e-4), 1e-10),
        ((1.5e-4, 5.0, 1.05e-4), 1e-10),
        ((3e-4, 5.0, 2.1e-4), 1e-11),
        ((1e-3, 5.0, 7e-4), 1e-12),
    ],
)
def test_the_check_near_the_separatrix_ends_before_roundoff_passes_the_tolerance(w, tol):
    """0.0001 to 0.001 rad/s off the intermediate axis the motion amplifies the roundoff of every
    passage by the saddle past the steps' error, and the companion counts roundoff at a fifteenth
    (rk4: ``1 / (2^4 - 1)``). The check still ends each episode where the steps' error passes the
    tolerance, before the roundoff does: every period returned is within the tolerance of mpmath's
    Taylor solution, and the episode ends as a numerical failure (the starts and tolerances where
    the removed ``"refine"`` had run outside, without the rounding twins or with one)."""
    env = _body(tol)
    env.reset(seed=0, options={"state": {"angular_momentum": np.array(INERTIA) * np.array(w)}})
    reference = _taylor_reference(w, 400, env.dt)
    ended, info, said = _within_until_ended(env, tol, lambda k: reference[k])
    assert ended is not None and info["numerical_failure"] and "the global error estimate" in said


def test_a_period_that_goes_non_finite_reports_the_check_it_could_not_make():
    """A checked period whose state goes non-finite (a torque far beyond what the period resolves)
    ends as a numerical failure with ``global_error_estimate`` inf on every path: the single env,
    the vector env's batch (its companion's difference with a NaN state) and the vector env with
    ``param_ranges`` (each episode's check: the key was missing and the batch raised KeyError)."""
    import gymnasium as gym

    kw = dict(tolerance=1e-6, tolerance_check=True, max_angular_velocity=1e37, max_torque=1e9)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalFailureWarning)
        warnings.simplefilter("ignore", UnstableMotionWarning)
        single = FreeRigidBodyEnv(**kw)
        single.reset(seed=0)
        _, _, terminated, _, info = single.step(np.ones(single.action_space.shape, np.float32))
        assert terminated and info["numerical_failure"]
        assert info["global_error_estimate"] == math.inf
        for extra in ({}, {"param_ranges": {"inertia": 0.1}}):
            vec = gym.make_vec(
                "rbenvs/FreeRigidBody-v0",
                num_envs=2,
                vectorization_mode="vector_entry_point",
                **kw,
                **extra,
            )
            vec.reset(seed=0)
            _, _, terminated, _, info = vec.step(np.ones(vec.action_space.shape, np.float32))
            assert terminated.all() and info["numerical_failure"].all(), extra
            assert np.array_equal(info["global_error_estimate"], [math.inf, math.inf]), extra
