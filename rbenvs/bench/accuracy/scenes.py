"""A recommended integrator and step count per scene: the cheapest that meets the target."""

from __future__ import annotations

import math
import warnings

import numpy as np

from ...integrators.reference import REFERENCE
from ...progress import Progress
from ...render.common import plot_unavailable
from ..throughput import episode_stepper, timed
from .convergence import MAX_SUBSTEPS, SAVING, SCENE_SEEDS, TARGET, TIPPE_HORIZON
from .report import _write_json


# ------------------------------------------------------------------------------------ scenes
def _scene_run(scene, integrator, substeps, seed, actions, horizon_steps):
    """States (per block) along ``horizon_steps`` env steps under ``actions``, from ``seed``."""
    env = scene.make(
        integrator=integrator, substeps=substeps, tolerance=None
    ).unwrapped  # (fixed steps: unchecked)
    env.reset(seed=seed)
    names = [
        k
        for k in env.get_state()
        if not (scene.env_id.startswith("rbenvs/TippeTop") and k == "position")
    ]
    out = {k: [env.get_state()[k]] for k in names}
    failed = False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for a in actions[:horizon_steps]:
            _, _, _, _, info = env.step(a)
            if info.get("numerical_failure") or info.get("terminal_reason") == "lift_off":
                failed = True
                break
            st = env.get_state()
            for k in names:
                out[k].append(st[k])
    env.close()
    return {k: np.array(v) for k, v in out.items()}, failed


def _scene_error(run, ref):
    err = 0.0
    for k, r in ref.items():
        x = run[k]
        n = min(len(x), len(r))
        scale = float(np.max(np.linalg.norm(r, axis=1)))
        err = max(err, float(np.max(np.linalg.norm(x[:n] - r[:n], axis=1))) / scale)
    return err


def _scene_cost(scene, integrator, substeps, min_time):
    """Seconds per env step (the unwrapped env, zero action, reset when an episode ends)."""
    env = scene.make(integrator=integrator, substeps=substeps, tolerance=None)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t = timed(
            episode_stepper(env, np.zeros(env.action_space.shape, dtype=np.float32)), min_time, 3
        )
    env.close()
    return t


def run_scenes(
    names=None, target=TARGET, seeds=SCENE_SEEDS, min_time=0.1, progress=None
) -> list[dict]:
    """Per scene: each integrator's error over an episode at ``substeps = 1, 2, 4, ...`` until
    it meets ``target`` (at most :data:`MAX_SUBSTEPS`), its cost per env step, and the cheapest
    integrator and substeps that meet it."""
    from ...scenes import list_scenes

    return [_scene_row(name, target, seeds, min_time, progress) for name in names or list_scenes()]


def _scene_row(name, target, seeds, min_time, progress) -> dict:
    """One scene's row of :func:`run_scenes`: the candidates measured against ``seeds``
    reference runs under one sequence of random actions, and the recommendation."""
    from ...scenes import load_scene

    scene = load_scene(name)
    probe = scene.make().unwrapped
    dt, current = probe.dt, (probe.integrator.name, probe.substeps)
    episode = scene.make().spec.max_episode_steps
    tippe = scene.env_id.startswith("rbenvs/TippeTop")
    steps = min(episode, int(round(TIPPE_HORIZON / dt))) if tippe else episode
    rng = np.random.default_rng(0)
    space = probe.action_space
    actions = [rng.uniform(space.low, space.high).astype(np.float32) for _ in range(steps)]
    refs = [_scene_run(scene, REFERENCE, 1, seed, actions, steps)[0] for seed in range(seeds)]
    ladder = _substeps_ladder(probe, tippe)
    candidates = []
    for integ in (i for i in probe.integrators if i != "dop853"):
        _integrator_candidates(scene, integ, ladder, actions, refs, target, min_time, candidates)
        if progress:
            progress()
    best, cur = _recommended(candidates, current)
    return {
        "scene": name,
        "id": scene.env_id,
        "dt": dt,
        "steps": steps,
        "episode_steps": episode,
        "current": {"integrator": current[0], "substeps": current[1]},
        "current_error": None if cur is None else cur["error"],
        "candidates": candidates,
        "recommended": None
        if best is None
        else {"integrator": best["integrator"], "substeps": best["substeps"]},
        "target": target,
    }


def _substeps_ladder(probe, tippe) -> list[int]:
    """The substeps tried per integrator: ``1, 2, 4, ...`` up to :data:`MAX_SUBSTEPS`; the
    tippe top takes ``max(substeps, its own rule's count)``, so only 1 and the counts of at least
    twice the rule's at the start (to 256) matter there."""
    ladder = [2**k for k in range(int(math.log2(MAX_SUBSTEPS)) + 1)]
    if tippe:
        probe.reset(seed=0)
        n0 = probe.internal_steps(
            probe.state_components, (0.0, 0.0, probe.params.friction, 0.0, 0.0, 0.0)
        )
        ladder = [1] + [k for k in (2**j for j in range(1, 9)) if k >= 2 * n0]
    return ladder


def _integrator_candidates(scene, integ, ladder, actions, refs, target, min_time, candidates):
    """Append ``integ``'s candidates to ``candidates``, one per rung of ``ladder``: its worst
    error over the seeds (``inf`` where a run failed) and its cost per env step."""
    steps = len(actions)
    for substeps in ladder:
        errs = []
        for seed, ref in enumerate(refs):
            run_, failed = _scene_run(scene, integ, substeps, seed, actions, steps)
            errs.append(math.inf if failed else _scene_error(run_, ref))
        err = max(errs)
        cost = _scene_cost(scene, integ, substeps, min_time)
        candidates.append(
            {
                "integrator": integ,
                "substeps": substeps,
                "error": err,
                "step_us": cost * 1e6,
                "meets": err <= target,
            }
        )
        cheapest = min((c["step_us"] for c in candidates if c["meets"]), default=math.inf)
        # more substeps only cost more: stop once the target is met or this costs more than a
        # pair that meets it
        if err <= target or cost * 1e6 > cheapest:
            break


def _recommended(candidates, current):
    """``(best, cur)``: the cheapest candidate that meets the target (``None`` if none does)
    and the scene's current setting's candidate (``None`` if it was not tried)."""
    meeting = [c for c in candidates if c["meets"]]
    best = min(meeting, key=lambda c: c["step_us"]) if meeting else None
    cur = next((c for c in candidates if (c["integrator"], c["substeps"]) == current), None)
    if cur is not None and cur["meets"] and best["step_us"] > SAVING * cur["step_us"]:
        best = cur  # a saving within the timing noise is no reason to change a scene
    return best, cur


def _tippe_main(args) -> int:
    """``--tippe``: :mod:`rbenvs.bench.tippe_accuracy` (``--quick``, ``--json``, ``--plot`` and
    ``--mujoco`` as for the other cases)."""
    from .. import tippe_accuracy

    if args.plot and plot_unavailable("rbenvs bench accuracy"):
        return 2
    bar = Progress(
        tippe_accuracy.progress_total(args.quick), not args.no_progress, "bench accuracy --tippe"
    )
    result = tippe_accuracy.run(quick=args.quick, progress=bar.update, mujoco=args.mujoco)
    bar.close()
    tippe_accuracy.print_report(result)
    if args.plot:
        tippe_accuracy.plot(result, args.plot)
        print(f"\nplot written to {args.plot}")
    _write_json(args.json, result)
    return 0
