"""The configuration files that ship with rbenvs, installed as the package ``rbenvs.configs``.

This is the repository's ``configs/`` folder; ``pyproject.toml`` maps it into the package
(``package-dir``) and installs its YAML files as package data:

* ``scenes/<name>.yml``: named scenes, an env id plus keyword arguments (:mod:`rbenvs.scenes`);
* ``agents/<algo>.yml``: SB3 hyperparameters per algorithm, and ``agents/results.yml``, the
  grid of ``rbenvs-results`` (:mod:`rbenvs_agents.config`).

:func:`configs_root` is the one place both are looked up. It holds no code but that.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

__all__ = ["configs_root"]


def configs_root():
    """The folder holding ``scenes/`` and ``agents/``.

    ``$RBENVS_CONFIGS`` if that environment variable is set (a folder laid out the same way,
    which replaces the shipped files wholesale: a scene or algorithm not in it is not found),
    else this package's files through :mod:`importlib.resources` (in a wheel install
    ``site-packages/rbenvs/configs``, in an editable install the checkout's ``configs/``). The
    result is a :class:`pathlib.Path` for the override, else a ``Traversable`` (a ``Path`` for
    any install on the file system).
    """
    override = os.environ.get("RBENVS_CONFIGS")
    return Path(override) if override else resources.files(__name__)
