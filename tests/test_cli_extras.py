"""Every command line without an extra it needs, or given an unknown scene, says so in one line
on stderr and exits with status 2: no traceback (rbenvs.extras)."""

import pathlib
import subprocess
import sys

import pytest
import tomllib

from rbenvs.cli import main
from rbenvs.extras import EXTRAS, TORCH_EXTRAS, TORCH_PIN, MissingExtra, require

# (prog, entry function, arguments, modules made unimportable, the extra it must name)
CASES = [
    ("rbenvs-train", "rbenvs_agents.cli:train_main", [], ["stable_baselines3"], "agents"),
    (
        "rbenvs-train",
        "rbenvs_agents.cli:train_main",
        ["--scene", "top_upright"],
        ["torch"],
        "agents",
    ),
    ("rbenvs-train", "rbenvs_agents.cli:train_main", [], ["yaml"], "agents"),
    (
        "rbenvs-eval",
        "rbenvs_agents.cli:eval_main",
        ["--agent", "runs/ppo/model.zip"],
        ["stable_baselines3"],
        "agents",
    ),
    (
        "rbenvs-eval",
        "rbenvs_agents.cli:eval_main",
        ["--agent", "analytic", "--agent", "zero"],
        ["yaml"],
        "cli",
    ),
    (
        "rbenvs-results",
        "rbenvs_agents.cli:results_main",
        ["--quick"],
        ["stable_baselines3", "torch"],
        "agents",
    ),
    (
        "rbenvs-results",
        "rbenvs_agents.cli:results_main",
        ["--quick", "--backend", "ray"],
        ["ray"],
        "ray",
    ),  # before the grid runs
    ("rbenvs-sweep", "rbenvs_agents.cli:sweep_main", ["--scene", "top_upright"], ["ray"], "ray"),
    ("rbenvs-sweep", "rbenvs_agents.cli:sweep_main", [], ["optuna"], "ray"),
    ("rbenvs", "rbenvs.cli:main", ["scenes"], ["yaml"], "cli"),
    ("rbenvs", "rbenvs.cli:main", ["run", "--episodes", "1"], ["yaml"], "cli"),
    (
        "rbenvs",
        "rbenvs.cli:main",
        ["bench", "accuracy", "--system", "free_body"],
        ["yaml"],
        "cli",
    ),  # before its long run
    (
        "rbenvs",
        "rbenvs.cli:main",
        ["bench", "accuracy", "--floor"],
        ["mpmath"],
        "reference",
    ),  # its Taylor-series reference
]


@pytest.mark.parametrize(
    "prog, entry, argv, blocked, extra",
    CASES,
    ids=[f"{c[0]}-{'-'.join(c[2][:1]) or 'plain'}-no-{c[3][0]}" for c in CASES],
)
def test_a_missing_extra_is_one_line_naming_it(prog, entry, argv, blocked, extra, tmp_path):
    module, func = entry.split(":")
    code = (
        f"import sys\nfor m in {blocked!r}:\n    sys.modules[m] = None\n"
        f"from {module} import {func}\nsys.exit({func}({argv!r}))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=120
    )
    assert out.returncode == 2, out.stderr
    assert "Traceback" not in out.stderr and out.stdout == ""
    (line,) = out.stderr.splitlines()
    assert line.startswith(f"{prog}: the '{extra}' extra is needed (") and line.endswith(
        f"pip install 'rbenvs[{extra}]'"
    )
    if extra in TORCH_EXTRAS:  # the CPU torch first, pinned (a bare torch resolves to CUDA builds)
        assert line.endswith(
            f": pip install torch=={TORCH_PIN} && pip install 'rbenvs[{extra}]'"
        ), line


def test_the_hints_torch_pin_is_the_packages():
    """The pin the hint gives is pyproject.toml's (the agents extra's torch==)."""
    with open(pathlib.Path(__file__).parents[1] / "pyproject.toml", "rb") as f:
        extras = tomllib.load(f)["project"]["optional-dependencies"]
    assert f"torch=={TORCH_PIN}" in extras["agents"]


def test_require_names_the_missing_distribution(monkeypatch):
    for extra in EXTRAS.keys() - {"ray"}:
        require(extra)  # the dev install has every extra but ray (its own venv: make test-ray)
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    with pytest.raises(
        MissingExtra, match=r"'agents' extra is needed \(stable-baselines3 is not installed\)"
    ) as exc:
        require("agents")
    assert isinstance(exc.value, ImportError) and exc.value.extra == "agents"
    require("cli")


def _one_line(capsys, prog):
    """stderr after ``prog``, checked to be one error line with nothing on stdout."""
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith(f"{prog}: error: ")
    return err[len(prog) :]


def test_an_unknown_scene_is_the_same_error_for_every_command(capsys, tmp_path, monkeypatch):
    pytest.importorskip("stable_baselines3")
    from rbenvs_agents.cli import eval_main, results_main, train_main

    assert main(["run", "--scene", "nope"]) == 2
    expected = _one_line(capsys, "rbenvs")
    assert "scene 'nope' not found" in expected and "known scenes: default," in expected
    assert train_main(["--scene", "nope"]) == 2
    assert _one_line(capsys, "rbenvs-train") == expected
    assert eval_main(["--scene", "nope", "--agent", "zero"]) == 2
    assert _one_line(capsys, "rbenvs-eval") == expected
    # rbenvs-results checks every scene of its grid before the first training run
    import shutil

    from rbenvs.configs import configs_root

    shutil.copytree(
        configs_root(),
        tmp_path,
        dirs_exist_ok=True,
        ignore=shutil.ignore_patterns("*.py", "__pycache__"),
    )
    (tmp_path / "agents" / "results.yml").write_text(
        "runs:\n  - scene: top_sleeping\n    algos: [ppo]\n  - scene: nope\n    algos: [ppo]\n"
    )
    monkeypatch.setenv("RBENVS_CONFIGS", str(tmp_path))
    assert results_main(["--quick", "--no-progress"]) == 2
    err = _one_line(capsys, "rbenvs-results")
    assert err.startswith(": error: scene 'nope' not found") and str(tmp_path) in err
