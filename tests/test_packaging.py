"""Packaging: the built wheel, installed into a fresh venv, ships its scenes and runs.

The wheel is built from a copy of the sources (so the checkout gets no ``build/`` or
``*.egg-info``) without build isolation, and installed with ``--no-deps --no-index`` into a venv
made without pip (the dev venv's pip installs into it, ``pip --python``). Its dependencies
(gymnasium, numpy, scipy, PyYAML, tqdm) come from the dev venv's site-packages, appended by a
``.pth`` file: the ``.pth`` files of an appended folder are not processed, so the editable
install's finder is not, and ``rbenvs`` can only come from the wheel. The commands run from an
empty folder. About 3 s on 2 cores: the build and the install ~2 s, ``rbenvs run`` under 1 s.
"""

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("pyproject.toml", "README.md", "rbenvs", "agents", "configs")


def _run(cmd, cwd, env=None, timeout=300):
    return subprocess.run(
        [str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout
    )


@pytest.fixture(scope="module")
def wheel_venv(tmp_path_factory):
    """(bin folder, site-packages, environment, empty working folder) of a venv with the wheel."""
    tmp = tmp_path_factory.mktemp("packaging")
    src = tmp / "src"
    src.mkdir()
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(
                ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info")
            )
        else:
            shutil.copy2(ROOT / name, src / name)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--no-input"]
    built = _run(
        pip + ["wheel", src, "--no-deps", "--no-build-isolation", "--no-index", "-w", tmp / "dist"],
        cwd=tmp,
    )
    assert built.returncode == 0, built.stdout + built.stderr
    (wheel,) = (tmp / "dist").glob("rbenvs-*.whl")

    venv = tmp / "venv"
    made = _run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=tmp)
    assert made.returncode == 0, made.stderr
    bindir = venv / ("Scripts" if os.name == "nt" else "bin")
    python = bindir / ("python.exe" if os.name == "nt" else "python")
    installed = _run(
        pip + ["--python", python, "install", "--no-deps", "--no-index", wheel], cwd=tmp
    )
    assert installed.returncode == 0, installed.stdout + installed.stderr
    site = Path(
        _run(
            [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=tmp
        ).stdout.strip()
    )
    # the dev venv's packages, appended after the temporary venv's own
    (site / "_rbenvs_test_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")

    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "RBENVS_CONFIGS", "VIRTUAL_ENV")
    }
    work = tmp / "work"
    work.mkdir()
    return bindir, site, env, work


def test_rbenvs_comes_from_the_wheel(wheel_venv):
    bindir, site, env, work = wheel_venv
    code = (
        "import rbenvs, rbenvs.configs, rbenvs_agents\n"
        "from rbenvs.scenes import scenes_dir\n"
        "from rbenvs_agents.config import agent_config\n"
        "print(rbenvs.__file__); print(rbenvs.configs.__file__); print(rbenvs_agents.__file__); "
        "print(scenes_dir())\n"
        "from rbenvs_agents.sweep import load_sweep\n"
        "assert load_sweep('ppo').space\n"  # the sweeps' search spaces shipped too
        # the hyperparameters shipped too
        "print(agent_config('ppo', 'rbenvs/FreeRigidBody-v0', 'default').n_timesteps)\n"
    )
    out = _run([bindir / "python", "-c", code], cwd=work, env=env)
    assert out.returncode == 0, out.stderr
    *paths, n_timesteps = out.stdout.split()
    for path in paths:
        assert Path(path).resolve().is_relative_to(site.resolve()), (path, site)
    assert int(n_timesteps) > 0


def test_every_package_of_the_source_tree_is_in_the_wheel(wheel_venv):
    """A subpackage left out of pyproject's list would import in the checkout and fail here."""
    bindir, site, env, work = wheel_venv
    source = {p.parent.relative_to(ROOT).as_posix() for p in (ROOT / "rbenvs").rglob("__init__.py")}
    installed = {
        p.parent.relative_to(site).as_posix() for p in (site / "rbenvs").rglob("__init__.py")
    }
    assert source <= installed, sorted(source - installed)


def test_every_scene_is_listed(wheel_venv):
    bindir, site, env, work = wheel_venv
    out = _run([bindir / "rbenvs", "scenes"], cwd=work, env=env)
    assert out.returncode == 0, out.stderr
    listed = {line.split()[0] for line in out.stdout.splitlines()[2:] if line.strip()}
    shipped = {p.stem for p in (ROOT / "configs" / "scenes").glob("*.yml")}
    assert shipped and listed == shipped


def test_the_main_job_runs_on_the_default_scene(wheel_venv):
    bindir, site, env, work = wheel_venv
    out = _run(
        [bindir / "rbenvs", "run", "--scene", "default", "--episodes", "1"], cwd=work, env=env
    )
    assert out.returncode == 0, out.stderr
    assert (
        "scene 'default'" in out.stdout
        and "SpinLQR" in out.stdout
        and "ZeroController" in out.stdout
    )


def test_an_empty_configs_folder_is_an_error_saying_where_it_looked(wheel_venv, tmp_path):
    bindir, site, env, work = wheel_venv
    out = _run([bindir / "rbenvs", "scenes"], cwd=work, env=env | {"RBENVS_CONFIGS": str(tmp_path)})
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.splitlines() == [
        f"rbenvs: error: no scenes found in {tmp_path / 'scenes'} "
        "($RBENVS_CONFIGS is set: unset it or point it at a folder with scenes/*.yml)"
    ]


def test_subpackages_are_attributes_after_import_rbenvs_alone(tmp_path):
    """``import rbenvs`` then ``rbenvs.envs.FreeRigidBodyEnv`` (as ``help`` reaches it) works in a
    fresh interpreter, every listed subpackage imports, and an unknown name still raises."""
    code = (
        "import rbenvs, sys\n"
        "assert 'rbenvs.envs' not in sys.modules\n"
        "assert rbenvs.envs.FreeRigidBodyEnv.__doc__\n"
        "assert all(getattr(rbenvs, n).__name__ == 'rbenvs.' + n for n in rbenvs._SUBMODULES)\n"
        "assert 'envs' in dir(rbenvs)\n"
        "try:\n    rbenvs.no_such_thing\nexcept AttributeError as e:\n    print('refused', e)\n"
    )
    out = _run([sys.executable, "-c", code], cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "refused module 'rbenvs' has no attribute 'no_such_thing'" in out.stdout
