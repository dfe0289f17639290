"""Named scenes: an env id plus keyword arguments, stored as YAML under ``configs/scenes``.

The scenes ship with the package (``rbenvs.configs``, see :func:`rbenvs.configs.configs_root`;
``$RBENVS_CONFIGS`` replaces them with a folder of your own). YAML is read with PyYAML (the
``cli`` extra), imported only here and only when a scene is loaded, so the core package runs
without it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from .configs import configs_root
from .dynamics.validation import did_you_mean
from .extras import require

__all__ = ["Scene", "scenes_dir", "list_scenes", "no_scenes_found", "load_scene"]


@dataclass(frozen=True)
class Scene:
    name: str
    env_id: str
    kwargs: dict = field(default_factory=dict)
    description: str = ""

    def make(self, **overrides):
        import gymnasium as gym

        import rbenvs  # noqa: F401  (registers the ids)

        return gym.make(self.env_id, **(self.kwargs | overrides))


def scenes_dir():
    """The folder of the named scenes: ``scenes/`` of :func:`rbenvs.configs.configs_root`."""
    return configs_root() / "scenes"


def list_scenes() -> list[str]:
    """The names of the scenes in :func:`scenes_dir`, sorted (empty if it holds none)."""
    d = scenes_dir()
    return (
        sorted(p.name[: -len(".yml")] for p in d.iterdir() if p.name.endswith(".yml"))
        if d.is_dir()
        else []
    )


def no_scenes_found() -> str:
    """What to say when :func:`list_scenes` is empty: where it looked and what to do."""
    if os.environ.get("RBENVS_CONFIGS"):
        why = "$RBENVS_CONFIGS is set: unset it or point it at a folder with scenes/*.yml"
    else:
        why = "the installed package lacks its data files: reinstall rbenvs"
    return f"no scenes found in {scenes_dir()} ({why})"


def load_scene(name_or_path: str) -> Scene:
    """A scene by name (``configs/scenes/<name>.yml``) or by path to a YAML file."""
    require("cli")
    import yaml

    path = Path(name_or_path)
    if path.suffix not in (".yml", ".yaml"):
        path = scenes_dir() / f"{name_or_path}.yml"
    if not path.is_file():
        known = list_scenes()
        hint = f"known scenes: {', '.join(known)}" if known else no_scenes_found()
        raise ValueError(
            f"scene {name_or_path!r} not found (looked for "
            f"{path}){did_you_mean(name_or_path, known)} ({hint})"
        )
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, dict) or "id" not in data:
        raise ValueError(f"scene file {path} must be a mapping with an 'id' key")
    unknown = set(data) - {"id", "kwargs", "description"}
    if unknown:
        raise ValueError(f"scene file {path} has unknown keys {sorted(unknown)}")
    kwargs = data.get("kwargs") or {}
    if not isinstance(kwargs, dict):
        raise ValueError(f"scene file {path}: 'kwargs' must be a mapping")
    # YAML lists become tuples: the env arguments are fixed-size vectors.
    kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in kwargs.items()}
    return Scene(
        name=path.name.rsplit(".", 1)[0],
        env_id=data["id"],
        kwargs=kwargs,
        description=data.get("description", ""),
    )
