"""The keywords every env takes, declared once: the control period and the step (``dt``,
``substeps``, ``integrator``, ``guard``, ``compiled``), the accuracy settings (``tolerance``,
``tolerance_horizon``, ``tolerance_check``), the robustness options (``param_ranges``,
``observation_noise``, ``observation_bias``, ``action_delay``: :mod:`rbenvs.envs.options`) and
``render_mode``, with their defaults and their docs.

An env class declares only its own keywords, takes these as ``**options``, and names its own
default of a shared one in ``shared_defaults`` (the heavy top's ``dt``, say);
:class:`rbenvs.envs.base.RigidBodyEnv` composes the signature users see (``help()``,
``inspect.signature``: every keyword, the shared ones keyword-only), applies the defaults, and
appends their docs to the class's. They are validated where they are used, once for every env
(:meth:`rbenvs.envs.base.RigidBodyEnv._setup` and ``_setup_options``).
"""

from __future__ import annotations

import functools
import inspect
from typing import NamedTuple

from ..dynamics.validation import unknown_keyword

__all__ = ["SharedOption", "SHARED_OPTIONS", "shared_signature", "shared_doc", "keyword_init"]


class SharedOption(NamedTuple):
    """A keyword every env takes: its name, default and doc (a bullet's text; ``{...}`` fields
    are filled from the env class: :func:`shared_doc`)."""

    name: str
    default: object
    doc: str


SHARED_OPTIONS = (
    SharedOption("dt", 0.05, "control period [s]."),
    SharedOption(
        "substeps", 1, "integrator steps per control period (a minimum: the guard may take more)."
    ),
    SharedOption(
        "integrator",
        "rk4",
        '{integrators}; ``"auto"`` with ``tolerance``: of the schemes a tolerance takes, the one '
        "whose steps at the fastest start, times its rhs evaluations, cost least.{integrator_note}",
    ),
    SharedOption(
        "guard", "subdivide", '``"subdivide"``, ``"refuse"`` or ``"off"`` ({guard_section}).'
    ),
    SharedOption(
        "compiled",
        "auto",
        "run each step as one compiled call of the same functions (numba, the ``fast`` extra; "
        "built on the first step, about a second per setting and process), bit for bit the float "
        "path, where numba is installed and the setting has pure forms (the explicit schemes "
        "``euler``, ``rk4``, ``splitting``); ``False``: the float path; ``True``: demand it "
        "(``ValueError`` saying why it cannot be had). ``env.unwrapped.compiled`` tells. With "
        "``tolerance_check`` the step is not one call (``compiled`` is ``False``): its period's "
        "runs are compiled instead (the main run's and the companion's).",
    ),
    SharedOption(
        "tolerance",
        "default",
        "the relative error allowed over ``tolerance_horizon`` control periods, a finite number "
        "with ``0 < tolerance < 1``, for the schemes that declare ``error_constant`` with their "
        "leading error in the phase (``rk4``; ``euler`` errs in the amplitude and is refused with "
        "a tolerance). {default_accuracy} ``None``: unchecked, the stability bound alone, "
        '``info["error_estimate"]`` ``None``. The rule, the refusals and the estimate: '
        ':mod:`rbenvs.stepsize.controller` and docs/integrators.md ("Accuracy: tolerance=").',
    ),
    SharedOption(
        "tolerance_horizon",
        None,
        "control periods the tolerance covers (an integer >= 1; ``None``: the registered "
        "``max_episode_steps``, one episode; a ``max_episode_steps`` given to ``gymnasium.make`` "
        "is not seen by the env: pass ``tolerance_horizon`` with it); refused with "
        "``tolerance=None``.",
    ),
    SharedOption(
        "tolerance_check",
        False,
        "with ``tolerance``, ``True`` estimates the episode's global error with a companion run "
        "(the same periods at twice the step: about half the steps again; "
        ':mod:`rbenvs.stepsize.controller`), reports it as ``info["global_error_estimate"]`` and '
        "ends the episode as a numerical failure, at the last state within it, where it passes "
        "the tolerance: for motions that amplify errors (the ``UnstableMotionWarning``'s; "
        'docs/integrators.md, "Unstable motions").',
    ),
    SharedOption(
        "param_ranges",
        None,
        "domain randomization, ``{{keyword: spread or (lo, hi)}}`` over {randomizable}, drawn at "
        'each reset from the env\'s generator and reported in ``info["params"]``; each range is '
        "checked at construction (every corner of the box must be a valid env).",
    ),
    SharedOption(
        "observation_noise",
        None,
        "Gaussian standard deviation in the observation's units (a number or one per "
        "component), the noisy observation clipped to the bounds; the state, reward and "
        "``info`` stay noiseless (``env.unwrapped.noiseless_observation``).",
    ),
    SharedOption(
        "observation_bias",
        None,
        "as ``observation_noise``, a constant offset drawn once per episode.",
    ),
    SharedOption(
        "action_delay",
        0,
        "an action first acts ``action_delay`` control periods later (zero actions before). "
        'See docs/environments.md, "Robustness options", and :mod:`rbenvs.envs.options`.',
    ),
    SharedOption(
        "render_mode",
        None,
        '``"rgb_array"`` or ``"human"`` (Rendering).',
    ),
)


def shared_signature(init, defaults: dict) -> inspect.Signature:
    """``init``'s signature with its ``**options`` replaced by every shared keyword,
    keyword-only, at ``defaults`` where the class names its own."""
    params = [p for p in inspect.signature(init).parameters.values() if p.kind != p.VAR_KEYWORD]
    params += [
        inspect.Parameter(
            o.name, inspect.Parameter.KEYWORD_ONLY, default=defaults.get(o.name, o.default)
        )
        for o in SHARED_OPTIONS
    ]
    return inspect.Signature(params)


def shared_doc(cls) -> str:
    """The shared keywords' bullets for the env class ``cls``'s docstring (its defaults, its
    integrators, accuracy and randomizable keywords filling the docs' ``{...}``)."""
    defaults, fields = cls.shared_defaults, _doc_fields(cls)
    lines = ["", "    ## Keywords every env takes (rbenvs.envs.shared)"]
    for o in SHARED_OPTIONS:
        value = defaults.get(o.name, o.default)
        shown = f'"{value}"' if isinstance(value, str) else repr(value)  # (as the code writes it)
        text = f"``{o.name}={shown}``: " + o.doc.format(**fields)
        words, line = text.split(), "    *"
        for word in words:
            if len(line) + 1 + len(word) > 96:
                lines.append(line)
                line = "     "
            line += " " + word
        lines.append(line)
    return "\n".join(lines) + "\n"


def _doc_fields(cls) -> dict:
    """The docs' ``{...}`` fields from the env class ``cls``."""
    names = [f"``{name}``" for name in cls.integrators]
    if cls.default_tolerance is None:
        default = (
            '``"default"``: this env has no default accuracy yet (``default_tolerance = '
            "None``): like ``None``, unchecked (the stability bounds' steps), "
            '``info["error_estimate"]`` ``None``.'
        )
    else:
        default = (
            '``"default"``: the env\'s default accuracy, ``default_tolerance = '
            f"{cls.default_tolerance!r}`` over an episode, enforced for ``rk4`` (the steps "
            "subdivide where it asks: only at extremes, every shipped scene keeps its steps) "
            'and reported in ``info["error_estimate"]`` every step; refused for ``euler`` '
            "(pass ``tolerance=None``); schemes without an error constant (``splitting``, "
            "``exact``, ``dop853``) run unchecked."
        )
    return {
        "integrators": ", ".join(names[:-1]) + " or " + names[-1],
        "integrator_note": (" " + cls.integrator_note) if cls.integrator_note else "",
        "guard_section": cls.guard_section,
        "default_accuracy": default,
        "randomizable": ", ".join(f"``{k}``" for k in cls.randomizable),
    }


def keyword_init(cls) -> None:
    """Wrap ``cls.__init__`` (if ``cls`` defines one): the constructor's keyword arguments
    (defaults applied) recorded in ``_kwargs`` (``param_ranges`` builds an episode's env from
    them with drawn values), an unknown keyword refused with the nearest, and, for an ``__init__``
    that takes ``**options``, the keywords every env shares in its signature, their defaults
    (``cls.shared_defaults``) and their docs."""
    init = cls.__dict__.get("__init__")
    if init is None:
        return
    takes = inspect.signature(init).parameters.values()
    shared = any(p.kind == p.VAR_KEYWORD and p.name == "options" for p in takes)
    sig = shared_signature(init, cls.shared_defaults) if shared else inspect.signature(init)
    first = next(iter(sig.parameters))

    @functools.wraps(init)
    def __init__(self, *args, **kw):
        if "_kwargs" not in self.__dict__:  # (the outermost class's keywords)
            error = unknown_keyword(
                cls.__name__,
                kw,
                sig.parameters,
                f"help(rbenvs.envs.{cls.__name__}), docs/environments.md",
            )
            if error is not None:
                raise error
            bound = sig.bind(self, *args, **kw)
            bound.apply_defaults()
            arguments = dict(bound.arguments)
            arguments.pop(first)
            self._kwargs = arguments
        if shared:  # (every shared keyword reaches **options, defaults applied)
            bound = sig.bind(self, *args, **kw)
            bound.apply_defaults()
            init(*bound.args, **bound.kwargs)
        else:
            init(self, *args, **kw)

    if shared:
        __init__.__signature__ = sig
        # (the shared keywords' bullets before the Rendering section, else at the end)
        doc, section = (
            cls.__doc__ or "",
            shared_doc(cls),
        )
        at = doc.find("\n    ## Rendering")
        cls.__doc__ = doc + section if at < 0 else doc[:at] + section + doc[at:]
    cls.__init__ = __init__
