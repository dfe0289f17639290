"""rbenvs: Gymnasium environments for rotating rigid bodies, checked against analytic oracles.

``import rbenvs`` registers every environment id (in gymnasium's ``namespace/Name-vN`` form):

=============================  ============================  =================
id                             tasks                         max_episode_steps
=============================  ============================  =================
``rbenvs/FreeRigidBody-v0``    spin, detumble, reorient      400
``rbenvs/LagrangeTop-v0``      upright, precess              500
``rbenvs/TippeTop-v0``         invert, hold                  2500
=============================  ============================  =================
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

__version__ = "0.1.0"

# One place for every registration. reward_threshold applies to each id's default scene:
# FreeRigidBody (spin about the intermediate axis): 380 = a mean alignment of 0.95 over 400
# steps; LagrangeTop (upright below the critical spin): 475 = a mean cos(tilt) of 0.95 over 500.
# TippeTop (invert) has none: its return is minus the time to invert, with no natural bar.
ENVIRONMENTS = {
    "rbenvs/FreeRigidBody-v0": dict(
        entry_point="rbenvs.envs.free_body:FreeRigidBodyEnv",
        vector_entry_point="rbenvs.vector:FreeRigidBodyVectorEnv",
        max_episode_steps=400,
        reward_threshold=380.0,
    ),
    "rbenvs/LagrangeTop-v0": dict(
        entry_point="rbenvs.envs.heavy_top:LagrangeTopEnv",
        vector_entry_point="rbenvs.vector:LagrangeTopVectorEnv",
        max_episode_steps=500,
        reward_threshold=475.0,
    ),
    "rbenvs/TippeTop-v0": dict(
        entry_point="rbenvs.envs.tippe_top:TippeTopEnv",
        vector_entry_point="rbenvs.vector:TippeTopVectorEnv",
        max_episode_steps=2500,
    ),
}

for _env_id, _spec in ENVIRONMENTS.items():
    if _env_id not in registry:
        register(id=_env_id, **_spec)

# The subpackages and modules, reachable as attributes after ``import rbenvs`` alone
# (``help(rbenvs.envs.FreeRigidBodyEnv)``) and imported on first access (PEP 562): importing
# rbenvs stays a registration, without the physics, scipy or numba behind it.
_SUBMODULES = (
    "bench",
    "cli",
    "compiled",
    "contracts",
    "controllers",
    "core",
    "docblocks",
    "draws",
    "dynamics",
    "elliptic",
    "envs",
    "extras",
    "integrators",
    "jit",
    "oracles",
    "plotting",
    "progress",
    "render",
    "rotations",
    "scenes",
    "tasks",
    "testing",
    "vector",
    "verify",
)


def __getattr__(name):
    if name in _SUBMODULES:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_SUBMODULES))
