"""A vector env's ``info`` in gymnasium's vector convention.

Every value is an array of length ``num_envs`` with a boolean mask ``"_key"`` beside it: the
engine's physical read-outs and ``internal_step`` (unless the env was made with
``info_readouts=False``), the task's metrics and ``numerical_failure``, in the single env's key
order. :class:`BatchInfo` makes it from a numpy step's values or from a compiled step's arrays
(a copy of one template holding the keys and the shared masks), never handing out the env's own
state.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BatchInfo"]


class BatchInfo:
    """The ``info`` of ``n`` sub-envs stepped by ``engine`` (its read-out and metric names);
    ``readouts``: the physical read-outs included; ``true``, ``false``: the env's shared read-only
    masks."""

    def __init__(self, engine, n: int, readouts: bool, true, false):
        self.engine, self.n, self.readouts = engine, n, readouts
        self.true, self.false = true, false
        self._template = None  # a compiled step's info: its keys in order, masks set
        self._names = ()  # (the template's value keys, in the order of the kernel's arrays)

    def of_batch(self, y, u, h, failed, lifted, over, metrics, physical=None) -> dict:
        """The info of the states ``y`` after a period under the controls ``u`` with internal
        steps ``h`` (``failed``: the numerical failures, or ``None``; ``lifted``: the terminal
        event's mask): read-outs (the engine's, or the kernel's ``physical``) and metrics."""
        n, engine = self.n, self.engine
        if not self.readouts:
            raw = {}
        elif physical is None:
            raw = engine.readouts(y, u, lifted, h)
        else:
            raw = dict(zip(engine.readout_names, physical))
            raw["internal_step"] = h
        raw.update(metrics)
        info = {}
        every = self.true
        # never hand out the state (or the env's own arrays): those values are copied
        own = {id(c) for c in y}
        own.add(id(h))
        for key, value in raw.items():
            if type(value) is not np.ndarray:
                value = np.asarray(value)
            if value.shape != (n,):
                value = (
                    np.full(n, value) if value.ndim == 0 else np.broadcast_to(value, (n,)).copy()
                )
            elif id(value) in own:
                value = value.copy()
            info[key] = value
            info["_" + key] = every
        info["numerical_failure"] = failed.copy() if failed is not None else self.false
        info["_numerical_failure"] = every
        return info

    def of_kernel(self, r, done, reasons) -> dict:
        """The info of a compiled step's arrays ``r`` (the keys and order of :meth:`of_batch`),
        with ``terminal_reason`` (``reasons``, masked by ``done``) where an episode ended."""
        template = self._template
        if template is None:  # (made once: the keys, their masks and the constant entries)
            engine = self.engine
            names = (*engine.readout_names, "internal_step") if self.readouts else ()
            names += tuple(engine.metric_names)
            template = {}
            for name in names:
                template[name] = None
                template["_" + name] = self.true
            template.update(numerical_failure=self.false, _numerical_failure=self.true)
            self._template, self._names = template, names
        info = template.copy()
        values = (*r.readouts, r.h, *r.metrics) if self.readouts else r.metrics
        info.update(zip(self._names, values))
        if r.n_ended:
            info["terminal_reason"] = reasons
            info["_terminal_reason"] = done.copy()
        return info
