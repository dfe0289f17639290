"""Robustness options every env takes: domain randomization (``param_ranges``), sensor noise
(``observation_noise``, ``observation_bias``) and actuator delay (``action_delay``).

They live inside the env, not in wrappers, so that a vector env keeps its guarantee: sub-env
``i`` of a vector env seeded ``s`` follows bit for bit the single env seeded ``s + i``. Every
random number comes from the env's own seeded generator, in a fixed order at each reset:

1. the drawn parameters (``param_ranges``): one uniform per range *group* (below), in the
   order of the env's :attr:`randomizable` keywords;
2. the task's start (as without options);
3. one 63-bit integer, the key of the episode's *noise stream* (only with noise or bias): a
   ``numpy.random.Philox`` generator of its own, from which the bias (``observation_bias``
   standard deviations, one normal per component) and then one normal per component and
   observation are drawn. A stream of its own, apart from the env's generator, lets a vector
   env draw every sub-env's noise in one compiled call per step (numba draws the very numbers
   numpy's ``Generator.standard_normal`` draws: :class:`rbenvs.draws.GeneratorTable`), or,
   without numba, a block of :data:`NOISE_BLOCK` observations per sub-env and Python call
   (numpy gives the same numbers in blocks as one at a time).

``param_ranges`` maps a physical keyword of the env (its :attr:`randomizable`) to either

* a number ``s`` in ``[0, 1)``: a relative spread, each component drawn in ``value * [1 - s,
  1 + s]`` around the keyword's value (given or default);
* a range ``(lo, hi)`` with ``lo <= hi``: for a vector keyword (``inertia``) ``lo`` and ``hi``
  are vectors of its length.

Components of a vector keyword that are equal in the keyword's value and in their range share
one draw: a symmetric body stays symmetric (a Lagrange top stays a Lagrange top, so its
critical spin and the ``precess`` task keep their meaning). Each drawn value is
``lo + (hi - lo) * u``, ``u`` uniform on ``[0, 1)``.

Validity over the whole range: at construction the env is built at every corner of the box of
ranges (``2^g`` settings for ``g`` groups) and at its centre; each one must pass every check of
the constructor (positive masses, the triangle inequality of the moments, a resolvable control
period, ...), and all must give the same structure (spaces, read-outs, the free body's named
axis). Every such rule is monotone in each parameter (linear in the moments; products and
square roots of positive parameters), so a rule that holds at the corners holds inside the
box. A refusal names the parameter, the rule and the corner.
"""

from __future__ import annotations

import itertools
import math
import numbers

import numpy as np

from ..dynamics.validation import ParameterTypeError, _as_real, real_array, require_int_in

__all__ = [
    "ParamRanges",
    "Realism",
    "NOISE_BLOCK",
    "MAX_ACTION_DELAY",
    "noise_generator",
    "rekey",
    "noisy_observation",
]

NOISE_BLOCK = 64  # observations' noise a vector env draws per sub-env and Python call
MAX_ACTION_DELAY = 10_000  # control periods


class ParamRanges:
    """A validated ``param_ranges``: ``names`` (in the env's :attr:`randomizable` order), per
    name the ``(lo, hi)`` tuples of its components and the groups of components that share a
    draw. :meth:`draw` makes one episode's keyword values from a generator."""

    def __init__(self, env_class, nominal: dict, spec):
        if not isinstance(spec, dict):
            raise ParameterTypeError(
                f"param_ranges must be None or a dict {{keyword: spread or (lo, hi)}}, "
                f"got {spec!r} ({type(spec).__name__})"
            )
        allowed = env_class.randomizable
        unknown = [k for k in spec if k not in allowed]
        if unknown:
            raise ValueError(
                f"param_ranges keys must be among {list(allowed)} (the physical keywords of "
                f"{env_class.__name__}), got {unknown}"
            )
        if not spec:
            raise ValueError("param_ranges must name at least one keyword (or be None)")
        self.names = tuple(k for k in allowed if k in spec)
        self.vector = {}  # name -> whether the keyword is a vector
        self.bounds = {}  # name -> (lo tuple, hi tuple)
        self.groups = {}  # name -> tuple of tuples of component indices sharing a draw
        for name in self.names:
            value = nominal[name]
            vector = isinstance(value, (tuple, list, np.ndarray))
            v = tuple(float(c) for c in value) if vector else (float(value),)
            lo, hi = _bounds(f"param_ranges[{name!r}]", spec[name], v, vector)
            groups = []
            for j in range(len(v)):
                for g in groups:
                    i = g[0]
                    if v[i] == v[j] and lo[i] == lo[j] and hi[i] == hi[j]:
                        g.append(j)
                        break
                else:
                    groups.append([j])
            self.vector[name], self.bounds[name] = vector, (lo, hi)
            self.groups[name] = tuple(tuple(g) for g in groups)
        self.count = sum(len(g) for g in self.groups.values())  # uniforms per draw

    def _compose(self, pick) -> dict:
        """Keyword values with ``pick(k, lo, hi)`` the value of a component of group ``k``."""
        out, k = {}, 0
        for name in self.names:
            lo, hi = self.bounds[name]
            comps = [0.0] * len(lo)
            for g in self.groups[name]:
                for j in g:
                    comps[j] = pick(k, lo[j], hi[j])
                k += 1
            out[name] = tuple(comps) if self.vector[name] else comps[0]
        return out

    def values(self, u) -> dict:
        """The keyword values from ``count`` uniforms ``u`` (their order: :attr:`names`, then
        each keyword's groups): ``lo + (hi - lo) * u``."""
        return self._compose(lambda k, lo, hi: lo + (hi - lo) * float(u[k]))

    def draw(self, rng) -> dict:
        """One episode's keyword values from ``rng`` (``count`` numbers of ``rng.random``'s
        stream)."""
        return self.values(rng.random(self.count))

    def corners(self):
        """The settings the constructor checks, as ``(label, values)``: every corner of the box
        (each group at ``lo`` or exactly at ``hi``) and its centre."""
        settings = [
            self._compose(lambda k, lo, hi, b=bits: hi if b[k] else lo)
            for bits in itertools.product((0, 1), repeat=self.count)
        ]
        settings.append(self._compose(lambda k, lo, hi: lo + 0.5 * (hi - lo)))
        for i, values in enumerate(settings):
            kind = "centre" if i == len(settings) - 1 else "corner"
            yield f"{kind} " + ", ".join(f"{n}={values[n]!r}" for n in self.names), values

    def require_corners(self, episode_env, structure) -> None:
        """Every setting of :meth:`corners` must pass every check of the constructor
        (``episode_env(values)`` builds it) and keep the env's ``structure``."""
        for label, values in self.corners():
            try:
                env = episode_env(values)
            except (ValueError, TypeError) as err:
                raise type(err)(
                    f"param_ranges: at the range's {label}: {err} (every value in each range must "
                    "be valid)"
                ) from err
            if env.structure() != structure:
                raise ValueError(
                    f"param_ranges: at the range's {label} the env's structure changes (its "
                    "spaces, read-outs or named axis differ from the keywords' values); narrow "
                    f"the ranges of {list(self.names)}"
                )

    def info(self, values: dict) -> dict:
        """``info["params"]`` of one episode: floats, float64 arrays for vector keywords."""
        return {
            n: (np.array(values[n], dtype=np.float64) if self.vector[n] else float(values[n]))
            for n in self.names
        }


def _bounds(label: str, spec, v: tuple, vector: bool) -> tuple:
    """``(lo, hi)`` tuples of a keyword's components from a spread or a range."""
    if isinstance(spec, numbers.Real) and not isinstance(spec, (bool, np.bool_)):
        s = float(spec)
        if not (math.isfinite(s) and 0.0 <= s < 1.0):
            raise ValueError(
                f"{label}: a relative spread must lie in [0, 1) "
                f"(values in value * [1 - s, 1 + s]), got {spec!r}"
            )
        lo = tuple(c * (1.0 - s) for c in v)
        hi = tuple(c * (1.0 + s) for c in v)
        return tuple(min(a, b) for a, b in zip(lo, hi)), tuple(max(a, b) for a, b in zip(lo, hi))
    if (
        isinstance(spec, (str, bytes, dict))
        or not isinstance(spec, (tuple, list, np.ndarray))
        or len(spec) != 2
    ):
        shape = f"two vectors of {len(v)} numbers" if vector else "two numbers"
        raise ParameterTypeError(
            f"{label} must be a relative spread in [0, 1) or a range (lo, hi) of {shape}, got "
            f"{spec!r}"
        )
    out = []
    for end, x in zip(("lo", "hi"), spec):
        arr = real_array(f"{label} {end}", x)
        if arr.shape != ((len(v),) if vector else ()):
            shape = f"a vector of {len(v)} numbers" if vector else "a number"
            raise ValueError(f"{label}: {end} must be {shape}, got {x!r}")
        arr = np.atleast_1d(arr)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{label}: {end} must be finite, got {x!r}")
        out.append(tuple(float(c) for c in arr))
    lo, hi = out
    if any(a > b for a, b in zip(lo, hi)):
        raise ValueError(
            f"{label}: the range must have lo <= hi in every component, got lo={lo}, hi={hi}"
        )
    return lo, hi


def _std(name: str, value, high) -> np.ndarray | None:
    """A standard deviation per observation component: a number or one number per component,
    each finite, ``>= 0`` and at most the component's bound ``high`` (a wider one leaves nothing
    of the observation: the clipped values sit at the bounds); ``None`` stays ``None``."""
    if value is None:
        return None
    high = np.asarray(high, dtype=np.float64)
    size = high.shape[0]
    if isinstance(value, (numbers.Real, np.ndarray, list, tuple)) and not isinstance(
        value, (bool, np.bool_)
    ):
        if isinstance(value, numbers.Real):
            s = np.full(size, _as_real(name, value))
        else:
            s = real_array(name, value)
            if s.shape != (size,):
                raise ValueError(
                    f"{name} must be a number or {size} numbers (one per observation component), "
                    f"got shape {s.shape}"
                )
        if not (np.all(np.isfinite(s)) and np.all(s >= 0.0)):
            raise ValueError(
                f"{name} must be finite and >= 0 in every component (a standard deviation in the "
                f"observation's units), got {value!r}"
            )
        if not np.all(s <= high):
            j = int(np.flatnonzero(~(s <= high))[0])
            raise ValueError(
                f"{name} must be at most the observation's bound in every component (a standard "
                "deviation in its units; a wider "
                f"one leaves nothing of the observation, clipped to its bounds), got {s[j]!r} for "
                f"component {j} whose bound is {high[j]:.6g}"
            )
        s = s.astype(np.float64)
        s.flags.writeable = False
        return s
    raise ParameterTypeError(
        f"{name} must be None, a number or {size} numbers (standard deviations), got {value!r} "
        f"({type(value).__name__})"
    )


class Realism:
    """The validated sensor and actuator options: ``noise`` and ``bias`` (standard deviations
    per observation component, or ``None``) and ``delay`` (control periods)."""

    def __init__(self, observation_noise, observation_bias, action_delay, high=()):
        self.noise = _std("observation_noise", observation_noise, high)
        self.bias = _std("observation_bias", observation_bias, high)
        if isinstance(action_delay, (bool, np.bool_)) or not isinstance(
            action_delay, numbers.Integral
        ):
            if isinstance(action_delay, numbers.Real):
                raise ValueError(
                    f"action_delay must be an integer in [0, {MAX_ACTION_DELAY}] "
                    f"(control periods), got {action_delay!r}"
                )
            raise ParameterTypeError(
                f"action_delay must be an integer in [0, {MAX_ACTION_DELAY}] (control periods), "
                f"got {action_delay!r} ({type(action_delay).__name__})"
            )
        self.delay = require_int_in(
            "action_delay", action_delay, 0, MAX_ACTION_DELAY, " (control periods)"
        )
        self.stream = self.noise is not None or self.bias is not None  # a noise stream per episode

    @property
    def active(self) -> bool:
        return self.stream or self.delay > 0


def noise_generator():
    """A generator for noise streams (``numpy.random.Philox``), made once per env or sub-env and
    given each episode's key by :func:`rekey` (a key set costs microseconds; a new generator
    tens of them)."""
    return np.random.Generator(
        np.random.Philox(0)
    )  # (a seed, not a key: no entropy read from the OS)


def rekey(gen, rng) -> None:
    """Start ``gen``'s stream afresh at a key drawn from the env's generator ``rng`` (one
    ``integers(0, 2**63)``): the stream of ``Generator(Philox(key=key))``, from counter 0."""
    key = int(rng.integers(0, 2**63))
    gen.bit_generator.state = {
        "bit_generator": "Philox",
        "state": {
            "counter": np.zeros(4, dtype=np.uint64),
            "key": np.array([key, 0], dtype=np.uint64),
        },
        "buffer": np.zeros(4, dtype=np.uint64),
        "buffer_pos": 4,
        "has_uint32": 0,
        "uinteger": 0,
    }


def noisy_observation(obs, bias, std, z, high):
    """``clip(obs + bias + std z, -high, high)`` as float32 (one observation or rows of a
    batch; the same element operations either way): the noise never reaches the state."""
    o = obs.astype(np.float64)
    if bias is not None:
        o = o + bias
    if std is not None:
        o = o + std * z
    return np.clip(o, -high, high).astype(np.float32)
