"""The task table: every shipped setting's single env and vector env against their peers."""

from __future__ import annotations

import warnings

import numpy as np

from .timing import (
    ALTERNATIONS,
    Peers,
    _rounds,
    _time_once,
    counting_stepper,
    episode_stepper,
    random_actions,
    stagger_clocks,
    timed,
    timed_budget,
    timed_counting,
)

# ------------------------------------------------------------------------------ task table
TASK_NUM_ENVS = 4096
QUICK_NUM_ENVS = 64
# --quick: a setting whose single step costs more than this runs its vector figures at
# QUICK_SLOW_NUM_ENVS (the tippe top)
QUICK_SLOW_STEP_S = 1e-3
QUICK_SLOW_NUM_ENVS = 8


def env_class(env_id: str) -> type:
    """The single env class registered for ``env_id``."""
    import gymnasium as gym

    cls = gym.spec(env_id).entry_point
    if isinstance(cls, str):
        module, name = cls.split(":")
        cls = getattr(__import__(module, fromlist=[name]), name)
    return cls


def _short(env_id: str) -> str:
    return env_id.split("/", 1)[-1]


def _matches(only, *fields) -> bool:
    return not only or any(only.lower() in str(f).lower() for f in fields if f)


def task_settings(only: str | None = None, scenes: bool = True) -> tuple[list[dict], list[str]]:
    """The task table's settings and notes: every registered id with every task of its env
    class (``tasks``) at the defaults, then every named scene (its id and keyword arguments).
    ``only`` keeps the settings whose label, id, task or scene name contains it (any case).
    Each setting: ``{"setting": label, "id", "task", "scene", "kwargs"}``."""
    import rbenvs

    notes, out = [], []
    for env_id in rbenvs.ENVIRONMENTS:
        for task in env_class(env_id).tasks:
            out.append(
                {
                    "setting": f"{_short(env_id)} {task}",
                    "id": env_id,
                    "task": task,
                    "scene": None,
                    "kwargs": {"task": task},
                }
            )
    if scenes:
        from ...extras import MissingExtra
        from ...scenes import list_scenes, load_scene

        try:
            names = list_scenes()
            loaded = [load_scene(name) for name in names]
        except MissingExtra as exc:
            notes.append(f"named scenes skipped: {exc}")
            loaded = []
        if scenes and not loaded and not notes:
            notes.append("named scenes skipped: none found")
        for s in loaded:
            out.append(
                {
                    "setting": f"scene {s.name}",
                    "id": s.env_id,
                    "task": s.kwargs.get("task"),
                    "scene": s.name,
                    "kwargs": dict(s.kwargs),
                }
            )
    out = [s for s in out if _matches(only, s["setting"], s["id"], s["task"], s["scene"])]
    return out, notes


def no_kernel_reason(env_id: str, kwargs: dict) -> str:
    """Why ``env_id`` with ``kwargs`` has no compiled step: the vector env's own ``ValueError``
    for ``compiled=True``."""
    import gymnasium as gym

    try:
        venv = gym.make_vec(
            env_id,
            num_envs=1,
            vectorization_mode="vector_entry_point",
            **(kwargs | {"compiled": True}),
        )
    except ValueError as exc:
        return str(exc).removeprefix("compiled=True but ")
    venv.close()
    return "compiled=True works, but the default ('auto') does not take it"


def kernel_time(venv, action, min_time: float, repeat: int, budget: float | None = None) -> dict:
    """The compiled :class:`rbenvs.compiled.BatchStep` of ``venv`` alone, on the env's current
    states (``Y = np.stack(state_components)``) under the controls of ``action`` (one batch,
    mapped by ``model.actuator.control``; unactuated axes as arrays of 0.0), with the env's
    internal step and substeps, the guard checked per sub-env where the env's periods are not
    plain (as the env calls it: not where the default accuracy's gate holds every state,
    :meth:`rbenvs.core.step.Engine.gated`): ``{"seconds", "ns_per_env_step", "bad", "check",
    "state_unchanged"}``.
    ``state_unchanged``: the env's states (and ``Y``) equal what they were before the calls,
    and the kernel's new states share no memory with them."""
    env = venv.unwrapped
    batch_step = env.batch_step
    if batch_step is None:
        raise ValueError("the env runs on the numpy path: it has no compiled step")
    n = venv.num_envs
    before = tuple(env.state_components)
    saved = [np.array(c, copy=True) for c in before]
    Y = np.stack(before)
    Y_saved = Y.copy()
    columns = tuple(
        np.ascontiguousarray(np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0).T)
    )
    u_norm, u = env.model.actuator.control(columns)

    def full(cs):  # (n,) float64 arrays, as the env hands the kernel
        return tuple(
            np.ascontiguousarray(np.broadcast_to(np.asarray(c, dtype=np.float64), (n,))) for c in cs
        )

    u, u_norm = full(u), full(u_norm)
    h, substeps = env.engine.h, env.engine.substeps
    check = not env.engine.plain  # the guard per sub-env where the env runs one, as the env does
    if (
        check and env.engine.gated(before) is not None
    ):  # (the default accuracy's gate holds every state: the env's periods are plain)
        check = False

    def call():
        return batch_step(Y, u, u_norm, h, substeps, check)

    out = call()  # compiled already by the env's first step; not timed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t = timed_budget(call, min_time, repeat, budget)
    after = tuple(env.state_components)
    unchanged = (
        len(after) == len(saved)
        and all(np.array_equal(a, b) for a, b in zip(after, saved))
        and np.array_equal(Y, Y_saved)
        and not any(np.shares_memory(out[0], c) for c in (Y, *after))
    )
    return {
        "seconds": t,
        "ns_per_env_step": 1e9 * t / n,
        "bad": int(out[1]),
        "check": check,
        "state_unchanged": bool(unchanged),
    }


def measure_setting(
    setting: dict,
    peers: Peers,
    num_envs: int,
    min_time: float,
    repeat: int,
    budget: float,
    stagger: bool = True,
    slow_step_s: float | None = None,
    slow_num_envs: int | None = None,
    seed: int = 0,
    progress=None,
) -> dict:
    """One row of the task table (see the module docstring); ``progress()`` is called four
    times (single env, zero action, random actions, then the kernel and numpy path).
    ``stagger=False`` leaves the headline random-action run's clocks together too."""
    import gymnasium as gym

    env_id, kwargs = setting["id"], dict(setting["kwargs"])
    row = {k: setting[k] for k in ("setting", "id", "task", "scene")}
    row["kwargs"] = kwargs
    tick = progress or (lambda: None)
    single, t_single = _single_figures(row, peers, min_time, repeat, budget, seed)
    row.update(single)
    tick()
    # -- vector env: zero action from a fresh reset, then random actions with ends
    n = num_envs
    if slow_step_s is not None and slow_num_envs is not None and t_single > slow_step_s:
        n = min(n, slow_num_envs)
    row["num_envs"] = n
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
        row.update(_zero_action_figures(venv, min_time, repeat, budget, seed))
        tick()
        actions = random_actions(venv.action_space, seed)
        row.update(
            _random_action_figures(
                venv,
                actions,
                peers,
                row["zero_env_steps_per_s"],
                min_time,
                repeat,
                budget,
                stagger,
                seed,
            )
        )
        tick()
        # -- the kernel alone on the states the random run left, then the numpy path
        row.update(
            _kernel_and_numpy_figures(venv, row, actions, min_time, repeat, budget, stagger, seed)
        )
    tick()
    return row


def _single_figures(row, peers, min_time, repeat, budget, seed) -> tuple[dict, float]:
    """One step of ``gymnasium.make`` for ``row``'s setting (zero action) against Pendulum-v1's,
    interleaved: ``(figures, seconds per step)``; ``task``: the row's, else the env's own."""
    import gymnasium as gym

    env = gym.make(row["id"], **row["kwargs"])
    env.reset(seed=seed)
    task = row["task"] or env.unwrapped.task.name
    ours = episode_stepper(env, np.zeros(env.action_space.shape, dtype=env.action_space.dtype))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ours()  # the first step may generate code: not timed
        t_ours, t_pend = _interleaved(ours, peers.pendulum_step, min_time, repeat, budget)
    env.close()
    return {
        "task": task,
        "single_step_us": t_ours * 1e6,
        "pendulum_step_us": t_pend * 1e6,
        "single_ratio_to_pendulum": t_ours / t_pend,
    }, t_ours


def _interleaved(ours, pendulum_step, min_time, repeat, budget) -> tuple[float, float]:
    """The best time of a call of ``ours`` and of ``pendulum_step``, timed in alternate rounds
    (so that machine load hits both alike); a slow ``ours`` runs fewer rounds than Pendulum."""
    t_ours = _time_once(ours)  # a probe; where one step outlasts a round, the first round
    rounds = max(repeat, 2)
    if t_ours > min_time / rounds:
        rounds = _rounds(t_ours, min_time / rounds, rounds, budget) - 1
    else:
        t_ours = float("inf")
    t_pend = float("inf")
    for k in range(max(rounds, 1)):
        if k < rounds:
            t_ours = min(t_ours, timed(ours, min_time / max(repeat, 2), 1))
        t_pend = min(t_pend, timed(pendulum_step, min_time / max(repeat, 2), 1))
    return t_ours, t_pend


def _zero_action_figures(venv, min_time, repeat, budget, seed) -> dict:
    """The vector env's path and its env-steps/s with zero action from a fresh reset."""
    n = venv.num_envs
    figures = {
        "path": "compiled" if venv.unwrapped.compiled else "numpy",
        "max_episode_steps": venv.unwrapped.max_episode_steps,
    }
    venv.reset(seed=seed)
    zero = np.zeros(venv.action_space.shape, dtype=venv.action_space.dtype)
    venv.step(zero)  # a kernel compiles on its first call: not timed
    t = timed_budget(lambda: venv.step(zero), min_time, repeat, budget)
    figures["zero_env_steps_per_s"] = n / t
    figures["zero_ns_per_env_step"] = 1e9 * t / n
    return figures


def _random_action_figures(
    venv, actions, peers, zero_rate, min_time, repeat, budget, stagger, seed
) -> dict:
    """The vector env under ``actions``, clocks staggered (if asked) and together, against
    CartPole-v1's at the same N; ``zero_rate``: the zero-action env-steps/s, put over it too."""
    n = venv.num_envs
    # ours and the peer in turn, the best of each: on a shared host the speed drifts within
    # seconds, and the best of alternating rounds compares like with like
    sync = random = cart = None
    for _ in range(ALTERNATIONS):
        s_ = _random_rate(venv, actions, min_time, repeat, budget, False, seed)
        r_ = _random_rate(venv, actions, min_time, repeat, budget, stagger, seed)
        c_ = peers.cartpole_rate(n)
        sync = s_ if sync is None or s_["rate"] > sync["rate"] else sync
        random = r_ if random is None or r_["rate"] > random["rate"] else random
        cart = c_ if cart is None or c_["env_steps_per_s"] > cart["env_steps_per_s"] else cart
    rate = cart["env_steps_per_s"]
    return dict(
        random_env_steps_per_s=random["rate"],
        random_ns_per_env_step=1e9 / random["rate"],
        episode_ends=random["ends"],
        episode_ends_total=random["ends_total"],
        random_calls_timed=random["calls"],
        clocks_staggered=random["staggered"],
        cartpole_env_steps_per_s=rate,
        cartpole_episode_ends=cart["episode_ends"],
        ratio_to_cartpole=random["rate"] / rate,
        zero_ratio_to_cartpole=zero_rate / rate,
        sync_random_env_steps_per_s=sync["rate"],
        sync_episode_ends=sync["ends"],
        sync_random_calls_timed=sync["calls"],
        sync_ratio_to_cartpole=sync["rate"] / rate,
    )


# the row's kernel and numpy-path figures, None where the setting has no compiled step
_KERNEL_KEYS = (
    "kernel_ns_per_env_step",
    "gap",
    "gap_zero",
    "kernel_state_unchanged",
    "kernel_bad",
    "kernel_guard_checked",
    "no_kernel_reason",
    "numpy_random_env_steps_per_s",
    "numpy_episode_ends",
    "compiled_over_numpy",
)


def _kernel_and_numpy_figures(venv, row, actions, min_time, repeat, budget, stagger, seed) -> dict:
    """For a compiled ``venv`` (closed here): its kernel alone on its current states, then the
    same setting with ``compiled=False`` under ``actions``; otherwise the env's reason why not.
    ``row``: the figures so far (its id, kwargs, path, num_envs and random-action rate)."""
    import gymnasium as gym

    figures = dict.fromkeys(_KERNEL_KEYS)
    env_id, kwargs = row["id"], row["kwargs"]
    if row["path"] != "compiled":
        venv.close()
        figures["no_kernel_reason"] = no_kernel_reason(env_id, kwargs)
        return figures
    k = kernel_time(venv, actions[0], min_time, repeat, budget)
    figures.update(
        kernel_ns_per_env_step=k["ns_per_env_step"],
        gap=row["random_ns_per_env_step"] / k["ns_per_env_step"],
        gap_zero=row["zero_ns_per_env_step"] / k["ns_per_env_step"],
        kernel_state_unchanged=k["state_unchanged"],
        kernel_bad=k["bad"],
        kernel_guard_checked=k["check"],
    )
    venv.close()
    numpy_env = gym.make_vec(
        env_id,
        num_envs=row["num_envs"],
        vectorization_mode="vector_entry_point",
        **(kwargs | {"compiled": False}),
    )
    numpy_random = _random_rate(numpy_env, actions, min_time, repeat, budget, stagger, seed)
    numpy_env.close()
    figures.update(
        numpy_random_env_steps_per_s=numpy_random["rate"],
        numpy_episode_ends=numpy_random["ends"],
        compiled_over_numpy=row["random_env_steps_per_s"] / numpy_random["rate"],
    )
    return figures


def _random_rate(venv, actions, min_time, repeat, budget, stagger, seed) -> dict:
    """Env-steps per second of ``venv`` under ``actions`` (cycled) from ``reset(seed)``, clocks
    staggered if asked, with the episode ends of the timed window."""
    n = venv.num_envs
    if stagger:
        staggered = stagger_clocks(venv, seed)
    else:
        venv.reset(seed=seed)
        staggered = False
    step, count = counting_stepper(venv, actions)
    step()  # a kernel compiles on its first call: not timed
    best = timed_counting(step, count, min_time, repeat, budget)
    return {
        "rate": n / best["seconds"],
        "ends": best["ends"],
        "ends_total": best["ends_total"],
        "calls": best["calls"],
        "staggered": staggered,
    }


def run_tasks(
    settings=None,
    num_envs: int = TASK_NUM_ENVS,
    min_time: float = 0.2,
    repeat: int = 3,
    budget: float = 1.0,
    only: str | None = None,
    stagger: bool = True,
    slow_step_s: float | None = None,
    slow_num_envs: int | None = None,
    seed: int = 0,
    progress=None,
) -> tuple[list[dict], list[str]]:
    """The task table: ``(rows, notes)``, one row per setting (default: :func:`task_settings`
    with ``only``), each measured by :func:`measure_setting` against the same peers."""
    import rbenvs  # noqa: F401  (registers the ids)

    notes = []
    if settings is None:
        settings, notes = task_settings(only)
    peers = Peers(min_time, repeat, seed)
    rows = [
        measure_setting(
            s,
            peers,
            num_envs,
            min_time,
            repeat,
            budget,
            stagger,
            slow_step_s,
            slow_num_envs,
            seed,
            progress,
        )
        for s in settings
    ]
    peers.close()
    return rows, notes


def _g(x, fmt=".3g"):
    return "-" if x is None else format(x, fmt)


def print_tasks(rows, notes) -> None:
    """The task table, its footnotes (why a setting has no kernel) and the scenes' arguments."""
    _print_task_legend(rows)
    reasons = _print_task_rows(rows)
    _print_task_footnotes(rows, notes, reasons)
    _print_scene_arguments(rows)


def _print_task_legend(rows) -> None:
    """The lines above the task table: what each column measures, at which N."""
    ns = sorted({r["num_envs"] for r in rows})
    clocks = (
        "episode clocks spread over max_episode_steps"
        if all(r["clocks_staggered"] for r in rows)
        else "episode clocks NOT spread: see the note below"
    )
    print("tasks: every (id, task) at its defaults and every named scene")
    print(
        "  single: one step of gymnasium.make against Pendulum-v1 (zero action; us, interleaved, "
        "same run)"
    )
    print(
        f"  vector: make_vec at N = {', '.join(map(str, ns)) or '-'}; env-steps/s with zero "
        "action, "
        "and with seeded random actions in [-1, 1]"
    )
    print(f"          ({clocks}; 'ends': episode ends in the timed window, resets included),")
    print(
        "          that rate over CartPole-v1's native vector env (random actions) at the same N, "
        "same run;"
    )
    print(
        "          sync/s: the same actions from reset, every episode clock together (restarts all "
        "at once, at the limit);"
    )
    print(
        "          numpy/s and c/np: the same env with compiled=False; kernel: the compiled "
        "BatchStep alone"
    )
    print("          (ns per env-step), gap = env time per env-step (random actions) / kernel time")


def _print_task_rows(rows) -> dict:
    """The table's header and rows; returns the footnote mark of each reason for no kernel."""
    w = max([25] + [len(r["setting"]) + 1 for r in rows])
    print(
        f"{'setting':<{w}} {'single us':>9} {'/Pend':>6} {'N':>5} {'path':<8} {'zero/s':>9} "
        f"{'random/s':>9} {'ends':>6} {'/Cart':>6} {'sync/s':>9} {'/Cart':>6} {'numpy/s':>9} "
        f"{'c/np':>5} {'kernel ns':>9} {'gap':>6}"
    )
    reasons = {}
    for r in rows:
        kernel, gap = _g(r["kernel_ns_per_env_step"], ".2f"), _g(r["gap"], ".2f")
        if r["no_kernel_reason"] is not None:
            mark = reasons.setdefault(r["no_kernel_reason"], len(reasons) + 1)
            kernel = f"-[{mark}]"
        if r["kernel_state_unchanged"] is False:
            kernel += "!"
        print(
            f"{r['setting']:<{w}} {r['single_step_us']:>9.2f} "
            f"{r['single_ratio_to_pendulum']:>6.3f} "
            f"{r['num_envs']:>5d} {r['path']:<8} "
            f"{r['zero_env_steps_per_s']:>9.3g} {r['random_env_steps_per_s']:>9.3g} "
            f"{r['episode_ends']:>6d} {r['ratio_to_cartpole']:>6.3f} "
            f"{r['sync_random_env_steps_per_s']:>9.3g} {r['sync_ratio_to_cartpole']:>6.3f} "
            f"{_g(r['numpy_random_env_steps_per_s']):>9} {_g(r['compiled_over_numpy'], '.2f'):>5} "
            f"{kernel:>9} {gap:>6}"
        )
    return reasons


def _print_task_footnotes(rows, notes, reasons) -> None:
    """The lines below the task table: the peers' figures, then every mark and exception."""
    if rows:
        pend = min(r["pendulum_step_us"] for r in rows)
        carts = {}
        for r in rows:
            carts.setdefault(r["num_envs"], []).append(r["cartpole_env_steps_per_s"])
        print(
            f"peers: Pendulum-v1 step {pend:.2f} us (best of the run); CartPole-v1 vector env "
            "(measured beside each row) "
            + ", ".join(f"{min(c):.3g}-{max(c):.3g}/s at N = {n}" for n, c in sorted(carts.items()))
        )
    for reason, mark in reasons.items():
        which = ", ".join(r["setting"] for r in rows if r["no_kernel_reason"] == reason)
        print(f"[{mark}] no compiled step ({which}): {reason}")
    if any(r["kernel_state_unchanged"] is False for r in rows):
        print("! the kernel call changed the env's state (it must write new arrays only)")
    if any(r["kernel_bad"] for r in rows if r["kernel_bad"] is not None):
        print(
            "kernel: non-finite new states in "
            + ", ".join(r["setting"] for r in rows if r["kernel_bad"])
        )
    ns = sorted({r["num_envs"] for r in rows})
    small = [r["setting"] for r in rows if r["num_envs"] < max(ns)]
    if small:
        print(f"at N = {min(ns)} (a slow single step, --quick): " + ", ".join(small))
    unspread = [r["setting"] for r in rows if not r["clocks_staggered"]]
    if unspread:
        print(
            "episode clocks not spread (not asked, or the env keeps no per-sub-env step count or "
            "has no time limit): " + ", ".join(unspread)
        )
    for note in notes:
        print(note)


def _print_scene_arguments(rows) -> None:
    scenes = [r for r in rows if r["scene"]]
    if scenes:
        print("scenes:")
        for r in scenes:
            print(
                f"  {r['scene']}: {r['id']} "
                + ", ".join(f"{k}={v}" for k, v in r["kwargs"].items())
            )
