"""Optional extras and how the command lines report what is missing.

The core package needs gymnasium, numpy and scipy alone; the rest comes with extras
(``pyproject.toml``). :func:`require` is called where a command first needs an extra (before any
long work): a missing module raises :class:`MissingExtra`, an ``ImportError`` whose message names
the extra and its ``pip install`` line. :func:`run_command` runs a command line's body and turns
that, and a ``ValueError`` of bad input (an unknown scene, a bad value), into one line on stderr
and exit status 2, no traceback. ``rbenvs`` (:mod:`rbenvs.cli`) and ``rbenvs-train``,
``rbenvs-eval``, ``rbenvs-results``, ``rbenvs-sweep`` (:mod:`rbenvs_agents.cli`) all go through it.
"""

from __future__ import annotations

import argparse
import sys
from importlib.util import find_spec

__all__ = ["EXTRAS", "MissingExtra", "require", "run_command"]

# extra -> (module, distribution) pairs that a command needing the extra cannot do without.
EXTRAS = {
    # Scenes and agent hyperparameters are YAML files. The extra's tqdm is not required:
    # rbenvs.progress writes lines of text without it.
    "cli": (("yaml", "PyYAML"),),
    # The agents: stable-baselines3 on torch; their scenes and hyperparameters are YAML too.
    "agents": (("stable_baselines3", "stable-baselines3"), ("torch", "torch"), ("yaml", "PyYAML")),
    # rbenvs-train --tensorboard: SB3 writes its logs through tensorboard's SummaryWriter.
    "tensorboard": (("tensorboard", "tensorboard"),),
    # gymnasium's RecordVideo writes its files through moviepy.
    "video": (("moviepy", "moviepy"),),
    # `rbenvs bench accuracy --floor`: mpmath's Taylor series as the reference
    # (rbenvs.oracles.taylor_solution)
    "reference": (("mpmath", "mpmath"),),
    # `rbenvs verify --simulator mujoco`: MuJoCo's models beside ours (rbenvs.verify.mujoco_adapter)
    "mujoco": (("mujoco", "mujoco"),),
    # rbenvs-results --backend ray, rbenvs-sweep (Ray Tune with Optuna) and RLlib on the vector
    # envs. Not part of `dev`: RLlib pins an older gymnasium (see .ci/run's Ray job).
    "ray": (("ray", "ray[tune,rllib]"), ("optuna", "optuna")),
}


# the extras that pull torch, and its pin (pyproject.toml's agents extra: the CPU build)
TORCH_EXTRAS, TORCH_PIN = ("agents", "zoo", "ray"), "2.13.0"


class MissingExtra(ImportError):
    """A module of an extra is not installed; the message says which extra to install."""

    def __init__(self, extra: str, distribution: str):
        self.extra = extra
        self.distribution = distribution
        # (extras on torch: its CPU build first, pinned, or pip resolves a bare torch with CUDA)
        line = (
            f"pip install torch=={TORCH_PIN} && pip install 'rbenvs[{extra}]'"
            if extra in TORCH_EXTRAS
            else f"pip install 'rbenvs[{extra}]'"
        )
        super().__init__(f"the {extra!r} extra is needed ({distribution} is not installed): {line}")


def require(extra: str) -> None:
    """Raise :class:`MissingExtra` unless every module of ``extra`` can be imported.

    The modules are located, not imported (no cost for torch); a module blocked in
    ``sys.modules`` (set to ``None``) counts as missing.
    """
    for module, distribution in EXTRAS[extra]:
        try:
            found = find_spec(module) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            raise MissingExtra(extra, distribution)


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser whose "invalid choice" error also suggests the closest choice (a
    misspelled command, system or table: "did you mean 'verify'?"); its subparsers are of this
    class too."""

    def _check_value(self, action, value):
        if action.choices is not None and value not in action.choices:
            from .dynamics.validation import did_you_mean

            choices = ", ".join(map(repr, action.choices))
            raise argparse.ArgumentError(
                action,
                f"invalid choice: {value!r} (choose from "
                f"{choices}){did_you_mean(value, action.choices)}",
            )


def run_command(prog: str, body, argv) -> int:
    """``body(argv)``, its exit status; a missing extra or a ``ValueError`` or ``ImportError``
    becomes one line on stderr (``prog: ...``) and exit status 2. ``--docs PAGE`` in ``argv``
    writes the command's output into PAGE (:mod:`rbenvs.docblocks`)."""
    from .docblocks import run_with_docs

    try:
        return run_with_docs(prog, body, argv)
    except MissingExtra as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
    except (ValueError, ImportError) as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
    return 2
