"""Named scenes: an env id plus keyword arguments, stored as YAML under ``configs/scenes``.

YAML is read with PyYAML (the ``cli`` extra), imported only here and only when a scene is
loaded, so the core package runs without it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["Scene", "scenes_dir", "list_scenes", "load_scene"]


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


def scenes_dir() -> Path:
    """``$RBENVS_CONFIGS/scenes`` if set, else ``configs/scenes`` of the source checkout."""
    root = os.environ.get("RBENVS_CONFIGS")
    base = Path(root) if root else Path(__file__).resolve().parents[1] / "configs"
    return base / "scenes"


def list_scenes() -> list[str]:
    d = scenes_dir()
    return sorted(p.stem for p in d.glob("*.yml")) if d.is_dir() else []


def load_scene(name_or_path: str) -> Scene:
    """A scene by name (``configs/scenes/<name>.yml``) or by path to a YAML file."""
    try:
        import yaml
    except ImportError:
        raise ImportError("reading scenes needs PyYAML: pip install 'rbenvs[cli]'") from None
    path = Path(name_or_path)
    if path.suffix not in (".yml", ".yaml"):
        path = scenes_dir() / f"{name_or_path}.yml"
    if not path.is_file():
        raise ValueError(f"scene {name_or_path!r} not found (looked for {path}); known scenes: {list_scenes()}")
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
    return Scene(name=path.stem, env_id=data["id"], kwargs=kwargs, description=data.get("description", ""))
