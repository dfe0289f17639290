"""Hyperparameter sweeps on Ray Tune with Optuna's sampler: ``rbenvs-sweep``.

The search space of an algorithm lies next to its hyperparameters, in
``configs/agents/sweeps/<algo>.yml`` (read from :func:`rbenvs_agents.config.configs_dir`, so
``$RBENVS_CONFIGS`` replaces it too)::

    trials: 16              # Tune samples per scene
    timesteps: 25000        # training budget of a trial (absent: the configured n_timesteps)
    seeds: [0]              # training seeds of a trial; its score is the mean over them
    eval_episodes: 5
    space:                  # hyperparameters of configs/agents/<algo>.yml, overridden per trial
      learning_rate: {loguniform: [1.0e-4, 3.0e-3]}
      gamma: {choice: [0.95, 0.98, 0.99]}
      policy_kwargs:
        net_arch: {choice: [[64, 64], [128, 128]]}

A distribution is ``{uniform: [low, high]}``, ``{loguniform: [low, high]}``, ``{randint: [low,
high]}`` (high excluded) or ``{choice: [...]}`` (any YAML values: Optuna is given the index of
the option, since its categorical distribution takes numbers and strings only).
``policy_kwargs`` takes a mapping of distributions.

A trial is one :class:`rbenvs_agents.grid.Cell` per training seed, run by the grid's own
:func:`rbenvs_agents.grid.run_cell` in a Tune trial of one CPU, and scored by the mean return of
its evaluations. Those use evaluation seeds ``200 + seed``, not the results table's ``100 +
seed``: the table stays a check on episodes the search never saw. :func:`zoo_config` writes the
best trial of each scene in the zoo's format: the env id's complete block (what
``rl_zoo3.train --conf-file`` reads) and, under rbenvs' ``scenes:``, the values found.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

from .grid import Cell, run_cell

__all__ = [
    "SweepSpec",
    "Trial",
    "SweepResult",
    "load_sweep",
    "trial_overrides",
    "run_sweep",
    "zoo_config",
]

DISTRIBUTIONS = ("uniform", "loguniform", "randint", "choice")
SWEEP_EVAL_SEED_OFFSET = 200  # training seed s is evaluated with evaluation seed 200 + s
NESTED = ("policy_kwargs",)  # hyperparameters whose value is a mapping of distributions


@dataclass(frozen=True)
class SweepSpec:
    algo: str
    trials: int
    timesteps: int | None
    seeds: tuple[int, ...]
    eval_episodes: int
    space: dict  # flat: "learning_rate" or "policy_kwargs.net_arch" -> (distribution, arguments)


@dataclass(frozen=True)
class Trial:
    hyperparams: dict  # the overrides this trial trained with
    return_mean: float  # over its seeds' evaluations
    success_mean: float
    wall_time_s: float  # training, summed over its seeds


@dataclass(frozen=True)
class SweepResult:
    scene: object  # the rbenvs.scenes.Scene searched
    spec: SweepSpec
    trials: list  # of Trial, in Tune's order

    @property
    def best(self) -> Trial:
        """The trial of highest mean return (the first of equals)."""
        return max(self.trials, key=lambda t: t.return_mean)


def _distribution(name: str, value, path) -> tuple:
    if not (isinstance(value, dict) and len(value) == 1 and next(iter(value)) in DISTRIBUTIONS):
        raise ValueError(
            f"{path}: space.{name} must be one of {{{': ..., '.join(DISTRIBUTIONS)}: ...}}, got "
            f"{value!r}"
        )
    kind, args = next(iter(value.items()))
    if kind == "choice":
        if not isinstance(args, list) or not args:
            raise ValueError(f"{path}: space.{name}: choice needs a non-empty list, got {args!r}")
    elif not (
        isinstance(args, list)
        and len(args) == 2
        and all(isinstance(a, (int, float)) for a in args)
        and args[0] < args[1]
    ):
        raise ValueError(
            f"{path}: space.{name}: {kind} needs [low, high] with low < high, got {args!r}"
        )
    elif kind == "loguniform" and args[0] <= 0:
        raise ValueError(f"{path}: space.{name}: loguniform needs low > 0, got {args!r}")
    elif kind == "randint" and not all(isinstance(a, int) for a in args):
        raise ValueError(f"{path}: space.{name}: randint needs integers, got {args!r}")
    return kind, args


def load_sweep(algo: str, trials: int | None = None, timesteps: int | None = None) -> SweepSpec:
    """The sweep of ``configs/agents/sweeps/<algo>.yml``; ``trials`` and ``timesteps`` replace
    the file's."""
    import yaml

    from .config import ALGORITHMS, configs_dir

    if algo not in ALGORITHMS:
        raise ValueError(f"algo must be one of {list(ALGORITHMS)}, got {algo!r}")
    path = configs_dir() / "sweeps" / f"{algo}.yml"
    if not path.is_file():
        raise ValueError(f"no search space for {algo!r}: {path} is missing")
    data = yaml.safe_load(path.read_text()) or {}
    unknown = set(data) - {"trials", "timesteps", "seeds", "eval_episodes", "space"}
    if unknown:
        raise ValueError(f"{path} has unknown keys {sorted(unknown)}")
    if not isinstance(data.get("space"), dict) or not data["space"]:
        raise ValueError(f"{path} needs a non-empty 'space:' mapping")
    space = {}
    for name, value in data["space"].items():
        if name in ("n_timesteps", "n_envs", "policy", "eval_episodes"):
            raise ValueError(
                f"{path}: space.{name} cannot be searched (the trials' budget is 'timesteps:')"
            )
        if name in NESTED:
            if not isinstance(value, dict) or not value:
                raise ValueError(f"{path}: space.{name} must be a mapping of distributions")
            # (Tune reserves "/" for its own flattening of nested spaces)
            space |= {
                f"{name}.{key}": _distribution(f"{name}.{key}", v, path) for key, v in value.items()
            }
        else:
            space[name] = _distribution(name, value, path)
    trials = int(trials if trials is not None else data.get("trials", 8))
    timesteps = timesteps if timesteps is not None else data.get("timesteps")
    seeds = tuple(int(s) for s in data.get("seeds", [0]))
    if trials < 1 or (timesteps is not None and int(timesteps) < 1) or not seeds:
        raise ValueError(
            f"a sweep needs trials >= 1, timesteps >= 1 and at least one seed (got {trials}, "
            f"{timesteps}, {list(seeds)})"
        )
    return SweepSpec(
        algo,
        trials,
        None if timesteps is None else int(timesteps),
        seeds,
        int(data.get("eval_episodes", 5)),
        space,
    )


def trial_overrides(spec: SweepSpec, point: dict) -> dict:
    """A point of Tune's space (choices as indices) as overrides of the algorithm's
    configuration."""
    overrides: dict = {}
    for name, (kind, args) in spec.space.items():
        value = args[point[name]] if kind == "choice" else point[name]
        if "." in name:
            outer, inner = name.split(".", 1)
            overrides.setdefault(outer, {})[inner] = value
        else:
            overrides[name] = value
    return overrides


def _tune_space(spec: SweepSpec) -> dict:
    from ray import tune

    make = {"uniform": tune.uniform, "loguniform": tune.loguniform, "randint": tune.randint}
    return {
        name: tune.choice(list(range(len(args)))) if kind == "choice" else make[kind](*args)
        for name, (kind, args) in spec.space.items()
    }


def _trial(point, scene, spec: SweepSpec):
    """One Tune trial: a cell per training seed with this point's hyperparameters."""
    from ray import tune

    from .evaluate import summarize

    overrides = trial_overrides(spec, point)
    results = [
        run_cell(
            Cell(
                scene,
                spec.algo,
                s,
                spec.eval_episodes,
                SWEEP_EVAL_SEED_OFFSET + s,
                spec.timesteps,
                overrides,
            )
        )
        for s in spec.seeds
    ]
    summary = summarize([r.evaluation for r in results])
    tune.report(
        {
            "return_mean": summary["return_mean"],
            "success_mean": summary["success_mean"],
            "wall_time_s": sum(r.wall_time_s for r in results),
        }
    )


def run_sweep(
    spec: SweepSpec,
    scene,
    storage,
    address: str | None = None,
    num_cpus: int | None = None,
    seed: int = 0,
) -> SweepResult:
    """``spec.trials`` trials of ``spec.algo`` on ``scene``, one CPU each, on the cluster of
    :func:`rbenvs_agents.cluster.ray_cluster`; Optuna's TPE sampler (seeded ``seed``) proposes
    each point from the trials finished before it. ``storage``: the folder where Tune keeps its
    records, ``<storage>/<algo>-<scene>`` (on a cluster of several machines, one every node
    reaches)."""
    from .cluster import ray_cluster

    with ray_cluster(address, num_cpus):
        import optuna
        from ray import tune
        from ray.tune.search.optuna import OptunaSearch

        optuna.logging.set_verbosity(optuna.logging.WARNING)  # (not a line per study created)

        trainable = tune.with_resources(
            tune.with_parameters(_trial, scene=scene, spec=spec), {"cpu": 1}
        )
        tuner = tune.Tuner(
            trainable,
            param_space=_tune_space(spec),
            # reuse_actors: a trial's actor serves the next trial, whose training finds the numba
            # kernels already compiled (a fresh actor per trial compiles them again: most of a
            # small trial's time)
            tune_config=tune.TuneConfig(
                search_alg=OptunaSearch(seed=seed),
                metric="return_mean",
                mode="max",
                num_samples=spec.trials,
                reuse_actors=True,
            ),
            run_config=tune.RunConfig(
                name=f"{spec.algo}-{scene.name}",
                storage_path=str(Path(storage).resolve()),
                verbose=0,
            ),
        )
        grid = tuner.fit()
        trials = []
        for result in grid:
            if result.error is not None:
                raise RuntimeError(f"a trial of the sweep failed: {result.error}")
            # (numpy scalars, if Tune hands any back, as plain numbers for the YAML)
            point = {
                name: v.item() if hasattr(v, "item") else v
                for name, v in ((n, result.config[n]) for n in spec.space)
            }
            m = result.metrics
            trials.append(
                Trial(
                    trial_overrides(spec, point),
                    float(m["return_mean"]),
                    float(m["success_mean"]),
                    float(m["wall_time_s"]),
                )
            )
    if not all(math.isfinite(t.return_mean) for t in trials):
        raise RuntimeError("a trial of the sweep reported a non-finite return")
    return SweepResult(scene, spec, trials)


def zoo_config(results: list[SweepResult]) -> str:
    """The best trial of each sweep in the rl-baselines3-zoo format, as YAML text: per env id its
    complete block (the configured hyperparameters with the best values in; the first scene's
    where two scenes share an env id), and under ``scenes:`` each scene's best values alone."""
    import yaml

    from .config import agent_config

    blocks, scenes, notes = {}, {}, []
    for r in results:
        best, scene = r.best, r.scene
        cfg = asdict(agent_config(r.spec.algo, scene.env_id, scene.name, **best.hyperparams))
        block = {
            "policy": cfg["policy"],
            "n_timesteps": cfg["n_timesteps"],
            "n_envs": cfg["n_envs"],
        } | cfg["hyperparams"]
        if cfg["policy_kwargs"]:
            block["policy_kwargs"] = cfg["policy_kwargs"]
        blocks.setdefault(scene.env_id, block)
        scenes[scene.name] = best.hyperparams
        budget = f"{r.spec.timesteps:,} steps" if r.spec.timesteps else "the configured budget"
        notes.append(
            f"# {scene.name} ({scene.env_id}): return {best.return_mean:.1f}, success "
            f"{best.success_mean:.0%}, best of {len(r.trials)} trials "
            f"at {budget}, training seeds {list(r.spec.seeds)}, {r.spec.eval_episodes} episodes of "
            "evaluation seeds 200 + seed"
        )
    algo = results[0].spec.algo
    header = [
        f"# {algo.upper()} hyperparameters found by rbenvs-sweep (Ray Tune, Optuna's TPE sampler), "
        "in rl-baselines3-zoo's format:",
        "# each env id's complete block, and under `scenes:` the values found per scene (an rbenvs "
        "extension).",
        *notes,
    ]
    body = yaml.safe_dump(blocks | {"scenes": scenes}, sort_keys=False, default_flow_style=None)
    return "\n".join(header) + "\n" + body
