"""rbenvs: Gymnasium environments for rotating rigid bodies, checked against analytic oracles.

``import rbenvs`` registers every environment id (in gymnasium's ``namespace/Name-vN`` form):

=============================  ============================  =================
id                             tasks                         max_episode_steps
=============================  ============================  =================
``rbenvs/FreeRigidBody-v0``    spin, detumble, reorient      400
=============================  ============================  =================
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

__version__ = "0.1.0"

# One place for every registration. reward_threshold applies to the default scene
# (spin about the intermediate axis): 380 = a mean alignment of 0.95 over 400 steps.
ENVIRONMENTS = {
    "rbenvs/FreeRigidBody-v0": dict(
        entry_point="rbenvs.envs.free_body:FreeRigidBodyEnv",
        max_episode_steps=400,
        reward_threshold=380.0,
    ),
}

for _env_id, _spec in ENVIRONMENTS.items():
    if _env_id not in registry:
        register(id=_env_id, **_spec)
