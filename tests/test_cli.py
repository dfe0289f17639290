import re
import subprocess
import sys

import pytest

from rbenvs.cli import main
from rbenvs.scenes import list_scenes, load_scene


def test_list(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "rbenvs/FreeRigidBody-v0" in out and "spin, detumble, reorient" in out and "400" in out
    assert "rbenvs/LagrangeTop-v0" in out and "upright, precess" in out and "500" in out
    assert "rbenvs/TippeTop-v0" in out and "invert, hold" in out and "2500" in out


def test_every_scene_loads_and_makes_an_env():
    names = list_scenes()
    assert "default" in names
    for name in names:
        env = load_scene(name).make()
        env.reset(seed=0)


def test_main_job_runs_and_summarises(capsys):
    assert main(["run", "--episodes", "1"]) == 0
    out = capsys.readouterr().out
    assert "SpinLQR" in out and "ZeroController" in out and "final alignment" in out
    # the heavy top's headline scene runs in the same job
    assert "UprightLQR" in out and "final tilt" in out and "pi_dot_gamma" in out
    assert "SlipCancelling" in out and "jellett" in out


def test_run_selected_scenes(capsys):
    assert main(["run", "--episodes", "1", "--scene", "top_precess", "--scene", "detumble"]) == 0
    out = capsys.readouterr().out
    assert "PrecessionTracking" in out and "DetumbleDamping" in out and "SpinLQR" not in out


def test_run_takes_several_scenes_after_one_flag(capsys):
    """``--scene a b`` (the synopsis' form) and ``--scene a --scene b`` select the same scenes."""
    assert main(["run", "--episodes", "1", "--scene", "top_precess", "detumble"]) == 0
    out = capsys.readouterr().out
    assert "PrecessionTracking" in out and "DetumbleDamping" in out and "SpinLQR" not in out


def test_unknown_scene_is_a_clear_error(capsys):
    assert main(["run", "--scene", "nope"]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and "did you mean" not in err  # (nothing close: no guess)
    assert main(["run", "--scene", "tippe_invrt"]) == 2
    err = capsys.readouterr().err
    assert "scene 'tippe_invrt' not found" in err and "did you mean 'tippe_invert'?" in err


def test_a_misspelled_command_or_choice_is_answered_with_the_closest_one(capsys):
    for argv, said in (
        (["verfy"], "invalid choice: 'verfy' (choose from 'list', "),
        (["verify", "--system", "heavy"], "invalid choice: 'heavy'"),
        (["warmup", "--system", "tipe_top"], "invalid choice: 'tipe_top'"),
    ):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and said in err, err
    assert "did you mean 'warmup'" not in err and "did you mean 'tippe_top'?" in err
    with pytest.raises(SystemExit):
        main(["zzzzzz"])
    assert "did you mean" not in capsys.readouterr().err  # (nothing close: no guess)
    # the benches' own parsers and the agents' commands suggest too
    from rbenvs_agents.cli import train_main

    for argv, said in (
        (["bench", "startup", "--system", "heavy_tp"], "did you mean 'heavy_top'?"),
        (["bench", "render", "--help"], None),
    ):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        err = capsys.readouterr().err
        assert said is None or (exit_.value.code == 2 and said in err), err
    with pytest.raises(SystemExit) as exit_:
        train_main(["--algo", "ppx"])
    assert exit_.value.code == 2 and "did you mean 'ppo'?" in capsys.readouterr().err


def test_python_dash_m():
    out = subprocess.run(
        [sys.executable, "-m", "rbenvs", "list"], capture_output=True, text=True, check=True
    ).stdout
    assert "FreeRigidBody-v0" in out


def test_core_runs_without_torch_sb3_yaml():
    # The core package must import and run with gymnasium, numpy and scipy alone.
    code = (
        "import sys\n"
        "for m in ('torch', 'stable_baselines3', 'yaml', 'tqdm', 'matplotlib'):\n"
        "    sys.modules[m] = None\n"
        "import gymnasium as gym, rbenvs\n"
        "env = gym.make('rbenvs/FreeRigidBody-v0')\n"
        "env.reset(seed=0)\n"
        "env.step(env.action_space.sample())\n"
        "print('ok')\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "ok"


def test_verify_shows_progress_on_the_core_install_without_tqdm():
    """Without tqdm (the core install) a long command still shows its progress on stderr, as
    lines of text (at the start, then every few seconds, and at the end), its output intact."""
    code = (
        "import sys\n"
        "sys.modules['tqdm'] = None\n"
        "from rbenvs.cli import main\n"
        "sys.exit(main(['verify', '--quick', '--system', 'free_body', '--integrator', 'rk4']))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = out.stderr.splitlines()
    assert lines[0].startswith("verify: 0/") and re.fullmatch(
        r"verify: (\d+)/\1 \(100%\) \d+ s", lines[-1]
    ), lines
    assert "passed, 0 failed" in out.stdout


def test_bench_fidelity_measures_every_level_against_gliding():
    from rbenvs.bench.fidelity import run

    rows = run(repeat=1, quick=True)  # (no speed is asserted: the bench prints it)
    assert [r["level"] for r in rows][0] == "gliding, coulomb"
    assert rows[0]["vs_gliding"] == 1.0
    by = {r["level"]: r for r in rows}
    # rolling carries no velocity of G: 9 components against 11
    assert by["rolling"]["components"] == 9 and by["frictionless"]["components"] == 11
    # only regularised Coulomb friction is stiff: it needs the most internal steps
    assert by["gliding, coulomb"]["internal_steps"] > by["frictionless"]["internal_steps"]
    assert all(r["env_step_us"] > 0 and r["rhs_us"] > 0 for r in rows)


def test_progress_bar_counts_and_is_silent_when_off(capsys):
    from rbenvs.progress import Progress

    bar = Progress(5, enabled=True, desc="t")
    for _ in range(3):
        bar.update()
    bar.update(2)
    assert bar.bar is not None and bar.bar.n == 5  # tqdm is in the cli extra
    bar.close()
    capsys.readouterr()
    off = Progress(5, enabled=False)
    off.update()
    off.close()
    assert off.bar is None
    assert capsys.readouterr().err == ""


def test_progress_without_tqdm_is_text_on_stderr(capsys, monkeypatch):
    """The fallback: the start, then a line per interval (0 s here: each update), the end."""
    from rbenvs import progress

    monkeypatch.setitem(sys.modules, "tqdm", None)
    monkeypatch.setattr(progress, "LOG_INTERVAL", 0.0)
    bar = progress.Progress(4, desc="work")
    bar.update()
    bar.update(3)
    bar.close()
    lines = capsys.readouterr().err.splitlines()
    assert [line.rsplit(" ", 2)[0] for line in lines] == [
        "work: 0/4 (0%)",
        "work: 1/4 (25%)",
        "work: 4/4 (100%)",
        "work: 4/4 (100%)",
    ], lines


def test_long_commands_show_progress_unless_asked_not_to(capsys):
    """`rbenvs run` and `bench fidelity` take tens of seconds: each shows a bar
    (on stderr, its total the work it will do) and `--no-progress` silences it."""
    assert main(["run", "--episodes", "1", "--scene", "detumble"]) == 0
    err = capsys.readouterr().err
    assert "rbenvs run: episodes" in err and "0/2" in err  # (two controllers, one episode each)
    assert main(["run", "--episodes", "1", "--scene", "detumble", "--no-progress"]) == 0
    assert capsys.readouterr().err == ""
    from rbenvs.bench.fidelity import run as fidelity

    fidelity(levels=(("gliding, coulomb", {}),), repeat=1, progress=True)
    assert "bench fidelity: levels" in capsys.readouterr().err
    from rbenvs.cli import build_parser

    for argv in (["bench", "fidelity", "--no-progress"],):
        assert build_parser().parse_args(argv).no_progress


def test_plot_writes_into_docs_only_when_asked():
    from rbenvs.cli import build_parser

    assert build_parser().parse_args(["plot"]).out == "plots"
    assert build_parser().parse_args(["plot", "--out", "docs"]).out == "docs"


def test_headline_outside_the_repository_reads_the_checkout_or_says_where_the_records_are(tmp_path):
    """`rbenvs headline` in a folder without docs/: the checkout rbenvs runs from (editable here);
    with --root on a folder without the records: exit 2, naming the record and where it lives."""
    import subprocess

    exe = [sys.executable, "-m", "rbenvs", "headline"]
    out = subprocess.run(exe, cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.startswith("- **Verification**"), out.stderr
    out = subprocess.run(
        [*exe, "--root", str(tmp_path)], cwd=tmp_path, capture_output=True, text=True
    )
    assert (
        out.returncode == 2
        and "docs/verify.json is missing" in out.stderr
        and "--root" in out.stderr
    )


def test_bench_costs_sizes_folders_and_reads_pytests_summary(tmp_path, capsys):
    from rbenvs.bench.costs import _minutes, _summary, folder_bytes, main

    assert (_minutes(42.4), _minutes(119.6), _minutes(1167.2)) == (
        "42 s",
        "2 min 00 s",
        "19 min 27 s",
    )

    (tmp_path / "a").write_bytes(b"x" * 1000)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b").write_bytes(b"y" * 234)
    assert folder_bytes(tmp_path) == 1234
    assert (
        _summary("....\n==== 4829 passed, 1 skipped, 330 warnings in 1465.27s (0:24:25) ====\n")
        == "4829 passed, 1 skipped, 330 warnings"
    )
    with pytest.raises(SystemExit) as exc:  # the suite needs the repository's tests/
        main(["--root", str(tmp_path)])
    assert exc.value.code == 2 and "no tests/ folder" in capsys.readouterr().err


def test_bench_render_prints_a_row_per_system_beside_the_peer(capsys):
    import rbenvs

    assert main(["bench", "render", "--frames", "2", "--no-progress"]) == 0
    rows = [
        line.split("|")[1:-1]
        for line in capsys.readouterr().out.splitlines()
        if line.startswith("| `")
    ]
    assert [r[0].strip(" `") for r in rows[:3]] == list(rbenvs.ENVIRONMENTS)
    for r in rows:
        assert r[1].strip() in ("480x480", "500x500") and float(r[2]) > 0.0 and float(r[3]) > 0.0


def test_bench_startups_processes_read_bytecode_whatever_the_callers_setting(monkeypatch):
    """A wheel has its bytecode: the bench's processes must not be told to skip writing it (in an
    editable checkout each would compile rbenvs' sources again)."""
    from rbenvs.bench import startup

    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    monkeypatch.setenv("RBENVS_SOMETHING", "kept")
    env = startup._environment()
    assert "PYTHONDONTWRITEBYTECODE" not in env and env["RBENVS_SOMETHING"] == "kept"
