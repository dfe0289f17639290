"""The tippe top's pure forms (rbenvs.dynamics.tippe_top.pure_forms, the tasks' observation and
reward forms): one implementation for the methods (floats), the numpy batch (arrays) and
compiled code, bit for bit, for every friction law, fidelity and free flight."""

import math

import numpy as np
import pytest
from conftest import HalfViscous

from rbenvs import compiled
from rbenvs.dynamics import contact
from rbenvs.dynamics.contact import (
    FRICTION_LAWS,
    Coulomb,
    Viscous,
    coulomb_coefficient,
    coulomb_stiffness,
    viscous_coefficient,
    viscous_stiffness,
)
from rbenvs.dynamics.tippe_top import TippeTop, TippeTopParams, pure_forms
from rbenvs.integrators import get_integrator
from rbenvs.tasks import HoldTask, InvertTask

needs_numba = pytest.mark.skipif(
    not compiled.available(),
    reason="the compiled path needs the 'fast' extra (numba) and RBENVS_COMPILED unset",
)

# (fidelity, friction law, flight): every combination a TippeTop can be
COMBOS = [
    ("gliding", "coulomb", False),
    ("gliding", "viscous", False),
    ("frictionless", "coulomb", False),
    ("rolling", "coulomb", False),
    ("gliding", "coulomb", True),
    ("gliding", "viscous", True),
    ("frictionless", "coulomb", True),
]
IDS = [f"{f}-{law}" + ("-flight" if fl else "") for f, law, fl in COMBOS]
N = 40  # random states per combination


def make_system(fidelity, law, flight):
    return TippeTop(
        TippeTopParams(friction_law=law, friction=0.4 if law == "coulomb" else 2.0),
        fidelity,
        flight,
    )


def random_states(system, rng, n):
    """``n`` states as ``(floats per state, arrays of the batch)``: random attitudes, fast spins
    (some lift off: ``N < 0``), random slips; with flight, in contact (on the constraint) and in
    flight above the table, with a few hops."""
    q = rng.normal(size=(4, n))
    q /= np.linalg.norm(q, axis=0)
    w = rng.normal(size=(3, n)) * np.array([[40.0], [40.0], [400.0]])
    pos = rng.normal(size=(2, n)) * 0.1
    vel = rng.normal(size=(2, n))
    if system.rolling:
        cols = list(pos) + list(q) + list(w)
    elif system.flight:
        flag = (np.arange(n) % 3 != 0).astype(float)  # a third in flight
        z = system.params.radius + 0.01 * rng.random(n)
        vz = rng.normal(size=n)
        hops = np.floor(4.0 * rng.random(n))
        cols = list(pos) + [z] + list(vel) + [vz] + list(q) + list(w) + [flag, hops]
        cols = list(system.normalize(tuple(cols)))  # in contact: z and v_z on the constraint
    else:
        cols = list(pos) + list(vel) + list(q) + list(w)
    arrays = tuple(np.ascontiguousarray(c, dtype=np.float64) for c in cols)
    floats = [tuple(float(c[i]) for c in arrays) for i in range(n)]
    return floats, arrays


def random_controls(rng, n):
    """``n`` controls ``(a_x, a_y, mu, tau1, tau2, tau3)`` as floats per state and as arrays."""
    u = rng.normal(size=(6, n)) * np.array([[2.0], [2.0], [0.0], [1e-4], [1e-4], [1e-4]])
    u[2] = rng.random(n)
    arrays = tuple(np.ascontiguousarray(c) for c in u)
    return [tuple(float(c[i]) for c in arrays) for i in range(n)], arrays


def bits(x):
    """A value's exact identity: type and bits (NaN by its bits, -0.0 apart from 0.0)."""
    if isinstance(x, tuple):
        return tuple(bits(c) for c in x)
    if isinstance(x, float):
        return ("float", x.hex())
    return (type(x).__name__, x)


def element(x, i):
    """Element ``i`` of a batch's result, as the Python value the single env has."""
    if isinstance(x, tuple):
        return tuple(element(c, i) for c in x)
    a = np.asarray(x)
    v = a if a.ndim == 0 else a[i]
    if a.dtype == np.bool_:
        return bool(v)
    if a.dtype.kind == "i":
        return int(v)
    return float(v)


def batch_bits(x, i):
    """Bits of element ``i`` of a batch result, types taken as the single env's."""
    return bits(element(x, i))


def forms_of(system):
    """``name -> (fn, P, arity)`` of every pure form of ``system``: the kernel pairs, the guard's
    rate and the tasks' observation and rewards."""
    out = {}
    for name in (
        "rhs",
        "rhs_normal",
        "normal",
        "normalize",
        "readouts",
        "gap",
        "take_off",
        "touch_down",
        "on_table",
        "airborne",
    ):
        pair = getattr(system, f"kernel_{name}")
        if pair is not None:
            out[name] = pair
    rates = system.guard_rates(get_integrator("rk4").region, math.inf, 0.01)
    if rates.dissipation is not None:
        out["guard_rate"] = rates.dissipation
    invert = InvertTask(150.0, 150.0, 0.1, 0.1, 0.03)
    hold = HoldTask(150.0, 150.0, 0.1, 0.1, 0.05)
    (observe, po), (evaluate_invert, pe_invert) = invert.kernels(system)
    _, (evaluate_hold, pe_hold) = hold.kernels(system)
    out["observe"] = (observe, po)
    out["invert"] = (evaluate_invert, pe_invert)
    out["hold"] = (evaluate_hold, pe_hold)
    return out


# ------------------------------------------------------------------------------------------
# friction laws


def test_each_law_is_its_pure_functions():
    """Coulomb and viscous: the methods are the pure functions (the same bits), which the
    tippe top's pure forms close over; a law with methods only has no pure forms."""
    c, v = FRICTION_LAWS["coulomb"], FRICTION_LAWS["viscous"]
    assert isinstance(c, Coulomb) and isinstance(v, Viscous)
    assert c.kernel_coefficient is coulomb_coefficient and c.kernel_stiffness is coulomb_stiffness
    assert v.kernel_coefficient is viscous_coefficient and v.kernel_stiffness is viscous_stiffness
    assert (
        c.pure_forms() == (coulomb_coefficient, coulomb_stiffness) and c.compilable and v.compilable
    )
    rng = np.random.default_rng(0)
    for law in (c, v):
        for _ in range(50):
            args = tuple(float(x) for x in rng.normal(size=5))
            assert bits(law.coefficient(*args)) == bits(law.kernel_coefficient(*args))
            assert bits(law.stiffness(*args[:4])) == bits(law.kernel_stiffness(*args[:4]))
    # the tippe top's forms are made once per combination, around the law's functions
    a, b = make_system("gliding", "coulomb", True), make_system("gliding", "coulomb", True)
    assert a.forms is b.forms and a.forms is pure_forms(
        coulomb_coefficient, coulomb_stiffness, False, True
    )
    assert make_system("gliding", "viscous", True).forms is not a.forms


def test_a_law_without_pure_functions_runs_on_floats_and_arrays_with_no_kernels(monkeypatch):
    """Its methods serve the float and array paths (viscous at half mu, the same numbers);
    no ``kernel_*`` pair is offered (compiled code could not call it)."""
    monkeypatch.setitem(contact.FRICTION_LAWS, "half_viscous", HalfViscous())
    assert not HalfViscous().compilable
    half = TippeTop(TippeTopParams(friction_law="half_viscous", friction=4.0), "gliding")
    full = TippeTop(TippeTopParams(friction_law="viscous", friction=2.0), "gliding")
    assert half.kernel_rhs is None and half.kernel_readouts is None and half.kernel_normal is None
    floats, arrays = random_states(full, np.random.default_rng(1), 5)
    for y in floats + [arrays]:
        for u in (None, (0.5, -0.5, 4.0, 0.0, 0.0, 0.0)):
            want = full.rhs(y, None if u is None else u[:2] + (2.0,) + u[3:])
            assert np.allclose(np.array(half.rhs(y, u)), np.array(want), rtol=1e-14, atol=0.0)
    fn, p = half.guard_rates(get_integrator("rk4").region, math.inf, 0.01).dissipation
    gn, q = full.guard_rates(get_integrator("rk4").region, math.inf, 0.01).dissipation
    assert fn(p, floats[0], None) == gn(q, floats[0], None)


# ------------------------------------------------------------------------------------------
# the methods are the pure forms


@pytest.mark.parametrize("fidelity,law,flight", COMBOS, ids=IDS)
def test_kernel_pairs_are_what_the_methods_compute(fidelity, law, flight):
    """Each ``kernel_*`` pair gives the method's value, bit for bit and type for type: the
    vector field (``u = None``: the table at rest, the parameter's friction, no torque), the
    vector field with the normal force from one solve, the projection, the read-outs (``u``
    ``None`` after a reset), the lift-off switch and the flight switches."""
    system = make_system(fidelity, law, flight)
    rng = np.random.default_rng(2)
    floats, _ = random_states(system, rng, N)
    controls, _ = random_controls(rng, N)
    mu = system.params.friction
    f = {name: pair for name, pair in forms_of(system).items()}
    call = lambda name, *a: f[name][0](f[name][1], *a)  # noqa: E731
    lift_offs = 0
    for i, y in enumerate(floats):
        for u in (None, controls[i]):
            system._memo = None
            dy = system.rhs(y, u)
            assert bits(call("rhs", y, u)) == bits(dy) and len(dy) == system.dim
            n = system.constraint_normal_force(y, u)
            assert bits(call("rhs_normal", y, u)) == bits((dy, n)) and bits(
                call("normal", y, u)
            ) == bits(n)
            assert bits(system.contact_forces(y, u)[0]) == bits(n)
            fired = i % 2 == 0
            reads = system.readouts(y, u, fired)
            assert bits(call("readouts", y, u, fired)) == bits(reads)
            assert [type(r) for r in reads] == [float] * 5 + [bool, bool, int, float, float]
            if not flight:
                assert system.lifts_off(y, u) == (n < 0.0) and reads[5] is fired
                lift_offs += n < 0.0
            if "guard_rate" in f:
                mu_u = mu if u is None else u[2]
                assert bits(call("guard_rate", y, u)) == bits(system.friction_stiffness(mu_u, n))
        assert bits(system.rhs(y, None)) == bits(call("rhs", y, (0.0, 0.0, mu, 0.0, 0.0, 0.0)))
        assert bits(call("normalize", y)) == bits(system.normalize(y))
        if flight:
            assert bits(call("gap", y)) == bits(system.gap(y))
            assert call("on_table", y) == system.on_table(y) == (y[13] == 1.0)
            assert call("airborne", y) == system.airborne(y) == (y[13] != 1.0)
            assert bits(call("take_off", y)) == bits(system.take_off(y)) and system.take_off(y)[
                13:
            ] == (0.0, y[14] + 1.0)
            assert (
                bits(call("touch_down", y))
                == bits(system.touch_down(y))
                == bits(system.impact(y)[0])
            )
            if y[13] == 0.0:
                assert call("normal", y, None) == 0.0  # no contact force in flight
    if not flight and fidelity != "rolling":
        assert 0 < lift_offs < 2 * N  # both sides of the lift-off switch were seen


@pytest.mark.parametrize("fidelity,law,flight", COMBOS, ids=IDS)
def test_tasks_observe_and_evaluate_are_their_pure_forms(fidelity, law, flight):
    system = make_system(fidelity, law, flight)
    rng = np.random.default_rng(3)
    floats, _ = random_states(system, rng, N)
    f = forms_of(system)
    for task, key in (
        (InvertTask(150.0, 150.0, 0.1, 0.1, 0.03), "invert"),
        (HoldTask(150.0, 150.0, 0.1, 0.1, 0.05), "hold"),
    ):
        fn, pe = f[key]
        for i, y in enumerate(floats):
            assert bits(f["observe"][0](f["observe"][1], y)) == bits(tuple(task.observe(system, y)))
            u = tuple(
                float(c) for c in rng.uniform(-1.0, 1.0, 2 + i % 5)
            )  # the action's size varies with the options
            reward, terminated, metrics = task.evaluate(system, y, u)
            assert bits(fn(pe, y, u)) == bits((reward, terminated, metrics["is_success"]))
            assert type(reward) is float and type(terminated) is bool
            tilt = system.tilt(y)
            if key == "invert":
                assert terminated == (tilt > task.goal_tilt) == metrics["is_success"]
            else:
                assert terminated == (tilt > task.fall_tilt) and metrics["is_success"] == (
                    tilt < task.success_tilt
                )


# ------------------------------------------------------------------------------------------
# floats and arrays


@pytest.mark.parametrize("fidelity,law,flight", COMBOS, ids=IDS)
def test_pure_forms_on_arrays_equal_the_floats_element_by_element(fidelity, law, flight):
    """The numpy batch runs the same functions on arrays: every element is the single state's
    result, bit for bit (controls as arrays, as scalars shared by the batch, and ``None``)."""
    system = make_system(fidelity, law, flight)
    rng = np.random.default_rng(4)
    floats, arrays = random_states(system, rng, N)
    controls, u_arrays = random_controls(rng, N)
    shared = (u_arrays[0], u_arrays[1], 0.3, 0.0, 0.0, 0.0)  # the actuator's: mu and torque fixed
    f = forms_of(system)
    fired = np.arange(N) % 2 == 0
    u_norm = tuple(np.ascontiguousarray(c) for c in rng.uniform(-1.0, 1.0, (4, N)))
    for ua, uf in (
        (u_arrays, controls),
        (
            shared,
            [(float(shared[0][i]), float(shared[1][i]), 0.3, 0.0, 0.0, 0.0) for i in range(N)],
        ),
        (None, [None] * N),
    ):
        batch = {
            name: f[name][0](f[name][1], arrays, ua)
            for name in ("rhs", "rhs_normal", "normal", "guard_rate")
            if name in f
        }
        batch["readouts"] = f["readouts"][0](f["readouts"][1], arrays, ua, fired)
        for i, y in enumerate(floats):
            for name, got in batch.items():
                args = (y, uf[i], bool(fired[i])) if name == "readouts" else (y, uf[i])
                assert batch_bits(got, i) == bits(f[name][0](f[name][1], *args)), (name, i)
    batch = {name: f[name][0](f[name][1], arrays) for name in ("normalize", "observe", "gap")}
    batch["invert"] = f["invert"][0](f["invert"][1], arrays, u_norm)
    batch["hold"] = f["hold"][0](f["hold"][1], arrays, u_norm)
    for i, y in enumerate(floats):
        un = tuple(float(c[i]) for c in u_norm)
        for name, got in batch.items():
            args = (y, un) if name in ("invert", "hold") else (y,)
            assert batch_bits(got, i) == bits(f[name][0](f[name][1], *args)), (name, i)


# ------------------------------------------------------------------------------------------
# compiled


def _compiled(fn, arity):
    """``fn`` called from a function numba compiles (as a batch kernel calls it), registered as
    a kernel build registers its parts: every jitable function imported by now, and ``fn`` (a
    form made per system or task is not one of them). Without it the test passed only after
    another test in the same process had built such a kernel."""
    import numba

    from rbenvs.jit import register, register_all

    register_all()
    register(fn)

    if arity == 2:
        return numba.njit(error_model="numpy")(lambda p, a: fn(p, a))
    if arity == 3:
        return numba.njit(error_model="numpy")(lambda p, a, b: fn(p, a, b))
    return numba.njit(error_model="numpy")(lambda p, a, b, c: fn(p, a, b, c))


ARITY = {
    "normalize": 2,
    "gap": 2,
    "take_off": 2,
    "touch_down": 2,
    "on_table": 2,
    "airborne": 2,
    "observe": 2,
    "readouts": 4,
}


@needs_numba
@pytest.mark.parametrize("fidelity,law,flight", COMBOS, ids=IDS)
def test_compiled_pure_forms_equal_the_floats_bit_for_bit(fidelity, law, flight):
    """Every pure form compiles with numba and gives the single env's bits and types: vector
    field, ``(dy, N)``, normal force, projection, read-outs (``u`` a tuple or ``None``), the
    guard's friction rate, the flight switches and the tasks' observation and reward (actions
    of 2 to 6 entries)."""
    from rbenvs.jit import register_all

    register_all()
    system = make_system(fidelity, law, flight)
    rng = np.random.default_rng(5)
    floats, _ = random_states(system, rng, N)
    controls, _ = random_controls(rng, N)
    for name, (fn, p) in forms_of(system).items():
        kernel = _compiled(fn, ARITY.get(name, 3))
        for i, y in enumerate(floats):
            if name in ("take_off", "touch_down") and y[13] == 1.0:
                continue  # (switches of a state in flight; a touchdown's impact is a float branch)
            if name == "readouts":
                for u in (controls[i], None):
                    assert bits(kernel(p, y, u, i % 2 == 0)) == bits(fn(p, y, u, i % 2 == 0)), (
                        name,
                        i,
                        u,
                    )
            elif name in ("invert", "hold"):
                u = tuple(float(c) for c in rng.uniform(-1.0, 1.0, 2 + i % 5))
                assert bits(kernel(p, y, u)) == bits(fn(p, y, u)), (name, i)
            elif ARITY.get(name, 3) == 2:
                assert bits(kernel(p, y)) == bits(fn(p, y)), (name, i)
            else:
                assert bits(kernel(p, y, controls[i])) == bits(fn(p, y, controls[i])), (name, i)


@needs_numba
@pytest.mark.parametrize(
    "fidelity,law,flight", [COMBOS[0], COMBOS[3], COMBOS[4]], ids=[IDS[0], IDS[3], IDS[4]]
)
def test_the_compiled_integrator_step_is_the_single_env_step(fidelity, law, flight):
    """rk4's pure step (``kernel_step``: the generated step around ``kernel_rhs`` and
    ``kernel_normalize``), compiled, takes the single env's bound step bit for bit."""
    import numba

    from rbenvs.jit import register, register_all

    system = make_system(fidelity, law, flight)
    rk4 = get_integrator("rk4")
    step, ps = rk4.kernel_step(system)
    # the system's pure forms are made with it: registered after, as a kernel build does (before,
    # the test passed only where an earlier test in the process had registered them)
    register_all()
    register(step)  # (generated per scheme and layout, as rbenvs.compiled registers it)
    bound = rk4.bind(system, system.dim)
    kernel = numba.njit(error_model="numpy")(lambda ps, y, u, h: step(ps, y, u, h))
    rng = np.random.default_rng(6)
    floats, _ = random_states(system, rng, 10)
    controls, _ = random_controls(rng, 10)
    for y, u in zip(floats, controls):
        for _ in range(3):
            want = bound(y, u, 2e-5)
            assert bits(kernel(ps, y, u, 2e-5)) == bits(want) == bits(rk4.step(system, y, u, 2e-5))
            y = want
    assert math.isfinite(sum(y))


# ------------------------------------------------------------------------------------------
# pickling


def test_systems_and_envs_pickle_into_a_new_process(tmp_path):
    """The pure forms are made per combination (closures, which pickle cannot carry): a system
    pickles as its parameters and makes its forms again on loading, and a model its guard's rule
    (which holds the friction rate), also in a process that has not made them yet; the clone
    computes the same values."""
    import pickle
    import subprocess
    import sys

    import gymnasium as gym

    system = make_system("gliding", "viscous", True)
    clone = pickle.loads(pickle.dumps(system))
    assert clone.forms is system.forms and clone.form_params == system.form_params
    assert clone.kernel_rhs == system.kernel_rhs and clone.kernel_take_off == system.kernel_take_off
    env = gym.make("rbenvs/TippeTop-v0", friction_law="viscous", compiled=False)
    env.reset(seed=0)
    y = random_states(system, np.random.default_rng(7), 1)[0][0]
    path = tmp_path / "forms.pkl"
    path.write_bytes(pickle.dumps((system, y, env)))
    script = (
        "import pickle\n"
        "import numpy as np\n"
        f"system, y, env = pickle.loads(open({str(path)!r}, 'rb').read())\n"
        "fn, p = env.unwrapped.model.step_rule.dissipation\n"
        "print(repr(system.rhs(y, None)), repr(fn(p, env.unwrapped.state_components, None)), "
        "env.step(np.zeros(2, np.float32))[1])\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout
    fn, p = env.unwrapped.model.step_rule.dissipation
    want = (
        f"{system.rhs(y, None)!r} {fn(p, env.unwrapped.state_components, None)!r} "
        f"{env.step(np.zeros(2, np.float32))[1]}"
    )
    assert out.strip() == want
