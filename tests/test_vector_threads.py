"""``num_threads=``: the compiled vector step split over threads gives the bits of one call, on
every path a step can take (restarts in both autoreset modes, a tolerance's estimates and
compensations, noise and delay, a refusal, a sub-env going non-finite, a bad action), after a
pickle, and in a forked child; the argument validated."""

import os
import pickle
import warnings

import numpy as np
import pytest
from conftest import FREE, LAGRANGE, TIPPE, make_vec, same
from gymnasium.vector import AutoresetMode

from rbenvs import compiled as _compiled

pytestmark = pytest.mark.skipif(
    not _compiled.available(),
    reason="num_threads splits the compiled step: numba (the 'fast' extra)",
)

N = 200  # chunks at multiples of 64: [0, 128), [128, 200) for 2 threads; three chunks for 3
THREADS = (1, 2, 3)


def trajectory(env, steps: int, seed: int = 5, scale: float = 1.5) -> list:
    """Every output of ``steps`` steps under random actions (some beyond [-1, 1]: clipped)."""
    rng = np.random.default_rng(seed)
    out = [env.reset(seed=11)]
    for _ in range(steps):
        out.append(
            env.step(
                rng.uniform(-scale, scale, env.action_space.shape).astype(env.action_space.dtype)
            )
        )
    return out


def identical(a: list, b: list) -> bool:
    return len(a) == len(b) and all(
        len(x) == len(y) and all(same(p, q) for p, q in zip(x, y)) for x, y in zip(a, b)
    )


CASES = [
    (FREE, {}, 60),
    (FREE, {"task": "reorient", "autoreset_mode": AutoresetMode.SAME_STEP}, 60),
    (FREE, {"task": "detumble", "integrator": "rk4", "tolerance": 1e-6}, 40),
    (FREE, {"observation_noise": 0.01, "action_delay": 2}, 40),
    (LAGRANGE, {}, 60),
    (
        LAGRANGE,
        {
            "integrator": "euler",
            "tolerance": None,
            "axial_torque": True,
            "spin": (5.0, 15.0),
            "attitude": True,
        },
        40,
    ),  # (counts per sub-env: the per-env period)
    (
        LAGRANGE,
        {"task": "upright", "spin": (5.0, 30.0), "autoreset_mode": AutoresetMode.SAME_STEP},
        60,
    ),
    (TIPPE, {}, 25),
]


@pytest.mark.parametrize(
    "env_id, kwargs, steps",
    CASES,
    ids=[f"{e.split('/')[1]}-{'-'.join(map(str, k)) or 'default'}" for e, k, _ in CASES],
)
def test_threads_give_the_bits_of_one_call(env_id, kwargs, steps):
    """Short episodes (max_episode_steps=15): every sub-env ends and restarts a few times, its
    start drawn from its own generator inside whichever chunk holds it."""
    runs = []
    for threads in THREADS:
        env = make_vec(env_id, N, max_episode_steps=15, num_threads=threads, **kwargs)
        assert env.num_threads == threads and env.compiled_path.whole is not None
        runs.append(trajectory(env, steps))
    assert identical(runs[0], runs[1]) and identical(runs[0], runs[2])


def _fast_sub_env(env, i: int, momentum) -> None:
    """Sub-env ``i`` restarted with angular momentum ``momentum``, the others kept."""
    state = env.get_state()
    state["angular_momentum"][i] = momentum
    mask = np.zeros(env.num_envs, dtype=bool)
    mask[i] = True
    env.reset(options={"state": state, "reset_mask": mask})


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(integrator="euler", tolerance=None),
        dict(task="detumble", integrator="rk4", tolerance=1e-6),
    ],
    ids=["euler", "rk4-tolerance"],
)
def test_a_refusal_in_one_chunk_raises_and_changes_nothing(kwargs):
    """guard='refuse' with one fast sub-env in the last chunk: the same error for every thread
    count, every state (and a tolerance's compensations, carried in place) as before the step,
    and the next steps the same bits."""
    runs = []
    for threads in THREADS:
        env = make_vec(
            FREE, N, guard="refuse", max_angular_velocity=1e4, num_threads=threads, **kwargs
        )
        out = trajectory(env, 3)
        _fast_sub_env(env, 170, (3e3, 2e3, 1e3))
        before = env.get_state()
        cc = None if env.run.cc is None else env.run.cc.copy()
        with pytest.raises(
            ValueError,
            match=r"guard='refuse' and the state of sub-envs \[170\] needs .* internal steps",
        ):
            env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        assert same(env.get_state(), before)
        assert cc is None or np.array_equal(env.run.cc, cc)
        _fast_sub_env(env, 170, (0.1, 0.2, 0.3))
        for _ in range(5):
            out.append(env.step(np.full(env.action_space.shape, 0.3, dtype=np.float32)))
        runs.append(out)
    assert identical(runs[0], runs[1]) and identical(runs[0], runs[2])


def test_a_sub_env_going_non_finite_in_one_chunk():
    """A sub-env of the second chunk overflows (guard off, bounds at float32's limit): its episode
    ends as a numerical failure, the others step on, with the same bits for every thread count."""
    from rbenvs.envs import NumericalFailureWarning

    runs = []
    for threads in THREADS:
        env = make_vec(FREE, N, guard="off", max_angular_velocity=3e38, num_threads=threads)
        out = trajectory(env, 2)
        _fast_sub_env(env, 150, (2e38, 1.5e38, 1e38))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(3):
                out.append(env.step(np.zeros(env.action_space.shape, dtype=np.float32)))
        assert any(issubclass(w.category, NumericalFailureWarning) for w in caught)
        assert out[3][4]["numerical_failure"][150] and out[3][4]["numerical_failure"].sum() == 1
        runs.append(out)
    assert identical(runs[0], runs[1]) and identical(runs[0], runs[2])


def test_a_non_finite_action_is_refused_with_nothing_written():
    env = make_vec(LAGRANGE, N, num_threads=2)
    env.reset(seed=0)
    before = env.get_state()
    a = np.zeros(env.action_space.shape, dtype=np.float32)
    a[190, 1] = np.nan
    with pytest.raises(ValueError, match="190"):
        env.step(a)
    assert same(env.get_state(), before)


def test_a_pickled_threaded_env_and_a_forked_child_go_on_bit_for_bit():
    """The compiled parts are made again on loading; a child forked after the parent ran numba's
    threads goes on with the same bits (on one thread, with one warning, where the layer is GNU
    OpenMP, whose threads cannot start in a forked child)."""
    import numba

    env = make_vec(FREE, N, max_episode_steps=15, num_threads=2)
    trajectory(env, 20)
    copy = pickle.loads(pickle.dumps(env))
    assert copy.num_threads == 2
    a = np.full(env.action_space.shape, 0.5, dtype=np.float32)
    for _ in range(20):
        assert all(same(x, y) for x, y in zip(env.step(a)[:4], copy.step(a)[:4]))
    if not hasattr(os, "fork"):
        return
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: one step, whether it warned, and its observation sent back
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                obs = env.step(a)[0]
                env.step(a)
            warned = [
                w
                for w in caught
                if "forked from one that ran numba's GNU OpenMP threads" in str(w.message)
            ]
            os.write(write, bytes([len(warned)]) + obs.tobytes())
        finally:
            os._exit(0)
    os.close(write)
    chunks = []
    while data := os.read(read, 1 << 16):
        chunks.append(data)
    os.waitpid(pid, 0)
    sent = b"".join(chunks)
    assert sent[1:] == env.step(a)[0].tobytes()
    assert sent[0] == (1 if numba.threading_layer() == "omp" else 0)  # (once, not per step)


def test_num_threads_argument():
    """An integer >= 1 or 'auto' (every core the process may use); more than one thread where
    the step is not compiled is refused, saying why; 'auto' is then one."""
    from rbenvs.vector.threads import usable_cores

    assert make_vec(FREE, 4, num_threads="auto").num_threads == usable_cores()
    for bad in (0, -1, 2.5, "many", None):
        with pytest.raises((ValueError, TypeError), match="num_threads must be an integer >= 1"):
            make_vec(FREE, 4, num_threads=bad)
    with pytest.raises(ValueError, match="num_threads=2 splits the compiled vector step"):
        make_vec(FREE, 4, num_threads=2, compiled=False)
    assert make_vec(FREE, 4, num_threads="auto", compiled=False).num_threads == 1


def test_a_split_step_leaves_the_callers_numba_thread_count():
    """The split kernel runs on as many of numba's threads as chunks and puts the calling
    thread's count back (a user's own parallel code keeps its setting)."""
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        env = make_vec(FREE, N, num_threads=2)
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        assert numba.get_num_threads() == 1
    finally:
        numba.set_num_threads(before)
