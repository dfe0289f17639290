"""``rbenvs bench fidelity``: what each tippe-top fidelity level costs, measured in one run.

For every level (gliding with Coulomb and with viscous friction, gliding with free flight
(hops modelled: the contact flag carried and the switch tested every internal step; no hop
happens in this scene), frictionless, rolling) on
the default ``TippeTop-v0`` scene (Leine-Glocker top, 150 rad/s, ``dt = 0.01`` s, rk4):

* ``rhs us``: one evaluation of the vector field on a single state (plain floats);
* ``internal steps``: steps per control period from the automatic rule (friction stiffness
  and spin), at the start state;
* ``env step us``: one ``env.step`` with zero action (the whole control period), from a block
  of ``BLOCK`` consecutive steps after a reset, the reset's own time subtracted;
* ``vs gliding``: the env-step cost relative to the gliding (Coulomb) level, the peer.
"""

from __future__ import annotations

import timeit

import numpy as np

__all__ = ["run", "main"]

LEVELS = (
    ("gliding, coulomb", dict(fidelity="gliding", friction_law="coulomb")),
    ("gliding, viscous", dict(fidelity="gliding", friction_law="viscous", friction=3.0)),
    ("gliding + flight", dict(fidelity="gliding", friction_law="coulomb", free_flight=True)),
    ("frictionless", dict(fidelity="frictionless")),
    ("rolling", dict(fidelity="rolling")),
)


# steps timed together after each reset (well inside every level's episode: no end in the block)
BLOCK = 50


def _best(fn, repeat=5, number=None):
    if number is None:  # (calls enough for 0.2 s a timing)
        number, _ = timeit.Timer(fn).autorange()
    return min(timeit.repeat(fn, number=number, repeat=repeat)) / number


def run(levels=LEVELS, repeat=5, progress: bool = False, quick: bool = False) -> list[dict]:
    """A row per level; ``quick``: each figure from one call (noisy: for a check that the
    command runs, not for the figures)."""
    from ..envs import TippeTopEnv
    from ..progress import Progress

    rows = []
    bar = Progress(len(levels), enabled=progress, desc="bench fidelity: levels")
    for label, kwargs in levels:
        env = TippeTopEnv(**kwargs)
        env.reset(seed=0)
        y = env.state_components
        system = env.system
        number = 1 if quick else None
        rhs_s = _best(lambda: system.rhs(y, None), repeat, number)
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        substeps = env.internal_steps(y, (0.0, 0.0, env.params.friction, 0.0, 0.0, 0.0))

        # A block of BLOCK steps from the start, its reset's cost subtracted once: one step less
        # its reset's time would be the difference of two noisy timings of similar size.
        def block():
            env.reset(seed=0)
            for _ in range(BLOCK):
                env.step(action)

        reset_s = _best(lambda: env.reset(seed=0), repeat, number)
        step_s = (_best(block, repeat, number) - reset_s) / BLOCK
        rows.append(
            {
                "level": label,
                "components": system.dim,
                "rhs_us": rhs_s * 1e6,
                "internal_steps": substeps,
                "env_step_us": step_s * 1e6,
            }
        )
        bar.update()
    bar.close()
    peer = rows[0]["env_step_us"]
    for r in rows:
        r["vs_gliding"] = r["env_step_us"] / peer
    return rows


def main(progress: bool = True, quick: bool = False) -> int:
    rows = run(progress=progress, quick=quick)
    print(
        f"{'level':<18} {'components':>10} {'rhs us':>8} {'internal steps':>15} "
        f"{'env step us':>12} "
        f"{'vs gliding':>11}"
    )
    for r in rows:
        print(
            f"{r['level']:<18} {r['components']:>10d} {r['rhs_us']:>8.2f} "
            f"{r['internal_steps']:>15d} {r['env_step_us']:>12.1f} {r['vs_gliding']:>11.3f}"
        )
    return 0
