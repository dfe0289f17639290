"""``rbenvs bench throughput``'s task table (rbenvs.bench.throughput): one row per (id, task) at
the defaults and per named scene, single env against Pendulum-v1, the vector env with zero and
with random actions (episode ends and resets inside the timed window) against CartPole-v1, the
numpy path beside a compiled one, and the compiled kernel alone (the gap to the limit).

Tiny sizes and windows: these check the table's structure and invariants, not the figures."""

import json
import math
import time

import numpy as np
import pytest
from conftest import FREE, env_class, make_vec

import rbenvs
from rbenvs.bench import throughput as T
from rbenvs.cli import main as cli_main

COLUMNS = {
    "setting",
    "id",
    "task",
    "scene",
    "kwargs",
    "single_step_us",
    "pendulum_step_us",
    "single_ratio_to_pendulum",
    "num_envs",
    "path",
    "max_episode_steps",
    "zero_env_steps_per_s",
    "zero_ns_per_env_step",
    "random_env_steps_per_s",
    "random_ns_per_env_step",
    "episode_ends",
    "episode_ends_total",
    "random_calls_timed",
    "clocks_staggered",
    "cartpole_env_steps_per_s",
    "cartpole_episode_ends",
    "ratio_to_cartpole",
    "zero_ratio_to_cartpole",
    "numpy_random_env_steps_per_s",
    "numpy_episode_ends",
    "compiled_over_numpy",
    "kernel_ns_per_env_step",
    "gap",
    "gap_zero",
    "kernel_state_unchanged",
    "kernel_bad",
    "kernel_guard_checked",
    "no_kernel_reason",
    "sync_random_env_steps_per_s",
    "sync_episode_ends",
    "sync_random_calls_timed",
    "sync_ratio_to_cartpole",
}
TINY = dict(num_envs=16, min_time=0.02, repeat=1, budget=0.05)


def setting(label):
    (s,) = [s for s in T.task_settings()[0] if s["setting"] == label]
    return s


def positive(x):
    return isinstance(x, float) and math.isfinite(x) and x > 0


def test_settings_cover_every_id_task_and_scene():
    settings, notes = T.task_settings()
    pairs = {(s["id"], s["task"]) for s in settings if s["scene"] is None}
    assert pairs == {(i, t) for i in rbenvs.ENVIRONMENTS for t in env_class(i).tasks}
    from rbenvs.scenes import list_scenes, load_scene

    scenes = {s["scene"]: s for s in settings if s["scene"] is not None}
    assert sorted(scenes) == list_scenes() and not notes
    for name, s in scenes.items():
        scene = load_scene(name)
        assert (
            s["id"] == scene.env_id
            and s["kwargs"] == scene.kwargs
            and s["setting"] == f"scene {name}"
        )
    # --only: a substring of the label, id, task or scene name, any case
    only = T.task_settings("freerigidbody")[0]
    assert only and all(s["id"] == FREE for s in only)
    assert {s["task"] for s in only if s["scene"] is None} == set(env_class(FREE).tasks)
    assert [s["setting"] for s in T.task_settings("FreeRigidBody-v0 spin")[0]] == [
        "FreeRigidBody-v0 spin"
    ]
    assert T.task_settings("no such setting")[0] == []


def check_row(row, compiled):
    assert COLUMNS <= set(row)
    for key in (
        "single_step_us",
        "pendulum_step_us",
        "zero_env_steps_per_s",
        "random_env_steps_per_s",
        "sync_random_env_steps_per_s",
        "cartpole_env_steps_per_s",
    ):
        assert positive(row[key]), key
    assert row["single_ratio_to_pendulum"] == pytest.approx(
        row["single_step_us"] / row["pendulum_step_us"], rel=1e-12
    )
    assert row["ratio_to_cartpole"] == pytest.approx(
        row["random_env_steps_per_s"] / row["cartpole_env_steps_per_s"], rel=1e-12
    )
    assert row["sync_ratio_to_cartpole"] == pytest.approx(
        row["sync_random_env_steps_per_s"] / row["cartpole_env_steps_per_s"], rel=1e-12
    )
    assert row["sync_random_calls_timed"] >= 1 and row["sync_episode_ends"] >= 0
    assert row["random_ns_per_env_step"] * row["random_env_steps_per_s"] == pytest.approx(
        1e9, rel=1e-12
    )
    # random actions with the clocks spread: the timed window crossed episode ends (resets in it)
    assert row["clocks_staggered"] is True and row["random_calls_timed"] >= 1
    assert row["episode_ends"] >= 1 and row["episode_ends_total"] >= row["episode_ends"]
    # the kernel row exactly where the env runs compiled; a reason where it does not
    assert row["path"] == ("compiled" if compiled else "numpy")
    if compiled:
        assert positive(row["kernel_ns_per_env_step"]) and row["no_kernel_reason"] is None
        assert row["kernel_state_unchanged"] is True and row["kernel_bad"] == 0
        assert row["gap"] == pytest.approx(
            row["random_ns_per_env_step"] / row["kernel_ns_per_env_step"], rel=1e-12
        )
        assert positive(row["numpy_random_env_steps_per_s"]) and row["numpy_episode_ends"] >= 1
        assert row["compiled_over_numpy"] == pytest.approx(
            row["random_env_steps_per_s"] / row["numpy_random_env_steps_per_s"], rel=1e-12
        )
    else:
        for key in (
            "kernel_ns_per_env_step",
            "gap",
            "gap_zero",
            "kernel_state_unchanged",
            "numpy_random_env_steps_per_s",
            "compiled_over_numpy",
        ):
            assert row[key] is None, key
        assert isinstance(row["no_kernel_reason"], str) and row["no_kernel_reason"]


def test_task_rows_on_the_path_the_env_takes():
    s = setting("FreeRigidBody-v0 spin")
    (row,), notes = T.run_tasks([s], **TINY)
    assert notes == [] and row["num_envs"] == TINY["num_envs"] and row["task"] == "spin"
    compiled = make_vec(s["id"], TINY["num_envs"], **s["kwargs"]).unwrapped.compiled
    check_row(row, compiled)


def test_a_setting_without_compiled_step_shows_no_kernel_and_says_why(monkeypatch):
    monkeypatch.setenv("RBENVS_COMPILED", "0")  # the documented switch: every env on numpy
    s = setting("FreeRigidBody-v0 detumble")
    (row,), _ = T.run_tasks([s], **TINY)
    assert make_vec(s["id"], 2, **s["kwargs"]).unwrapped.compiled is False
    check_row(row, compiled=False)
    assert "RBENVS_COMPILED" in row["no_kernel_reason"]


def test_the_kernel_call_leaves_the_env_as_it_was():
    n, kwargs = 32, dict(task="spin")
    venv, twin = make_vec(FREE, n, **kwargs), make_vec(FREE, n, **kwargs)
    if venv.unwrapped.batch_step is None:
        venv.reset(seed=0)
        with pytest.raises(ValueError):
            T.kernel_time(venv, np.zeros(venv.action_space.shape), 0.001, 1)
        pytest.skip("the free body's spin runs on numpy here (no numba)")
    actions = T.random_actions(venv.action_space, seed=3, pool=4)
    for env in (venv, twin):
        env.reset(seed=5)
        for a in actions[:3]:
            env.step(a)
    state = venv.unwrapped.get_state()
    k = T.kernel_time(venv, actions[3], min_time=0.005, repeat=1)
    assert k["state_unchanged"] is True and k["bad"] == 0 and k["ns_per_env_step"] > 0
    after = venv.unwrapped.get_state()
    assert all(np.array_equal(state[key], after[key]) for key in state)
    # the env steps on as its twin that never saw the kernel, bit for bit
    for a in actions:
        for x, y in zip(venv.step(a)[:4], twin.step(a)[:4]):
            assert np.array_equal(x, y)


def test_stagger_spreads_the_episode_clocks():
    n = 64
    venv = make_vec(FREE, n)
    venv.reset(seed=0)
    assert T.stagger_clocks(venv, seed=0)
    limit = venv.unwrapped.max_episode_steps
    ends = 0
    for _ in range(limit // 4):
        _, _, terminated, truncated, _ = venv.step(
            np.zeros(venv.action_space.shape, dtype=np.float32)
        )
        ends += int(np.count_nonzero(terminated | truncated))
    # about a quarter of the sub-envs reached the time limit in a quarter of an episode
    assert 0 < ends < n


def test_slow_calls_are_timed_in_few_rounds():
    calls = []

    def slow():
        calls.append(1)
        time.sleep(0.02)

    t = T.timed_budget(slow, min_time=0.005, repeat=5, budget=0.05)
    assert t >= 0.02 and len(calls) == 2  # the probe and one more round fit the budget
    calls.clear()
    T.timed_budget(slow, min_time=0.005, repeat=5, budget=0.001)
    assert len(calls) == 1  # at least one full call


def test_command_line_prints_the_task_table_first_and_writes_json(tmp_path, capsys):
    path = tmp_path / "bench.json"
    argv = [
        "bench",
        "throughput",
        "--quick",
        "--tables",
        "tasks",
        "--only",
        "FreeRigidBody-v0 spin",
        "--num-envs",
        "8",
        "--no-progress",
        "--json",
        str(path),
    ]
    assert cli_main(argv) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].startswith("tasks:")
    header = next(line for line in lines if line.startswith("setting"))
    for column in (
        "single us",
        "/Pend",
        "path",
        "zero/s",
        "random/s",
        "ends",
        "/Cart",
        "sync/s",
        "numpy/s",
        "c/np",
        "kernel ns",
        "gap",
    ):
        assert column in header
    assert any(line.startswith("FreeRigidBody-v0 spin") for line in lines)
    data = json.loads(path.read_text())
    assert set(data) >= {"tasks", "single", "vector", "scaling", "sb3"}
    (row,) = data["tasks"]
    assert (
        COLUMNS <= set(row) and row["num_envs"] == 8 and row["setting"] == "FreeRigidBody-v0 spin"
    )
    assert data["single"] == data["vector"] == data["scaling"] == data["sb3"] == []


def test_command_line_rejects_an_unmatched_filter_and_unknown_tables(capsys):
    assert cli_main(["bench", "throughput", "--only", "no such setting", "--no-progress"]) == 2
    assert "matches no row" in capsys.readouterr().err
    assert cli_main(["bench", "throughput", "--tables", "tasks,nope", "--no-progress"]) == 2
    assert "unknown table 'nope'" in capsys.readouterr().err


def test_the_check_table_times_the_checked_step_against_its_peers(tmp_path, capsys):
    """``--tables check``: per setting, the single env's step without ``tolerance_check``, with
    it (its runs compiled where numba is installed) and on floats, Pendulum-v1 timed after each,
    and the vector env at N = 8 and 256 without the check and with it on both paths beside
    CartPole-v1's; the ratios printed are those of the figures written (no speed is asserted:
    the bench prints it)."""
    path = tmp_path / "check.json"
    argv = [
        "bench",
        "throughput",
        "--tables",
        "check",
        "--only",
        "free body",
        "--no-progress",
        "--quick",
        "--json",
        str(path),
    ]
    assert cli_main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("tolerance_check=True in time") for line in lines)
    data = json.loads(path.read_text())
    (row,) = data["check"]
    assert row["setting"] == "free body"
    for key in ("plain_us", "check_us", "check_floats_us", "pendulum_check_us"):
        assert math.isfinite(row[key]) and row[key] > 0.0, key
    assert [v["num_envs"] for v in row["vector"]] == [8, 256]
    for v in row["vector"]:
        for key in (
            "plain_env_steps_per_s",
            "check_env_steps_per_s",
            "check_numpy_env_steps_per_s",
            "cartpole_plain",
            "cartpole_check",
        ):
            assert math.isfinite(v[key]) and v[key] > 0.0, key
    printed = next(
        line for line in lines if line.startswith("free body") and len(line.split()) == 7
    )
    assert printed.split()[-2:] == [
        f"{row['check_floats_us'] / row['check_us']:.1f}",
        f"{row['check_us'] / row['pendulum_check_us']:.1f}",
    ]
    vector = [
        line.split() for line in lines if line.startswith("free body") and len(line.split()) == 10
    ]
    assert [int(v[2]) for v in vector] == [8, 256]
    for v, fields in zip(row["vector"], vector):
        assert [fields[-4], *fields[-2:]] == [
            f"{v['check_env_steps_per_s'] / v['check_numpy_env_steps_per_s']:.1f}",
            f"{v['cartpole_plain'] / v['plain_env_steps_per_s']:.4g}",
            f"{v['cartpole_check'] / v['check_env_steps_per_s']:.4g}",
        ]
    assert data["tasks"] == data["single"] == []
