"""A vector env's run state: what its steps read and write for every sub-env, as one value."""

from __future__ import annotations

import numpy as np

__all__ = ["BatchRun"]


class BatchRun:
    """The states and clocks of ``n`` sub-envs (a vector env's ``run``).

    * ``y``: the states, a tuple of ``(n,)`` arrays, one per component (``None`` before a reset);
      ``y2d``: the ``(dim, n)`` array whose rows ``y`` views, where the compiled step made it;
    * ``steps``: each sub-env's episode clock; ``prev_done``: the sub-envs whose episode ended in
      the last step (NEXT_STEP restarts them at the next);
    * ``cc``: with a tolerance, each sub-env's compensation ``(dim, n)``, carried from period to
      period as the single env's run carries its own (:meth:`rbenvs.core.period.Period.advance`),
      zero at a start (``None`` without one);
    * ``u``, ``last_h``: the controls that acted in the last step (``None`` after a reset) and
      each sub-env's internal step in it; ``plain``: whether the next period may take
      ``substeps`` unchecked (the guard's static proof).
    """

    __slots__ = ("y", "y2d", "steps", "prev_done", "cc", "u", "last_h", "plain")

    def __init__(self, n: int, dim: int, compensated: bool, plain: bool):
        self.y = self.y2d = self.u = self.last_h = None
        self.steps = np.zeros(n, dtype=np.int64)
        self.prev_done = np.zeros(n, dtype=bool)
        self.cc = np.zeros((dim, n)) if compensated else None
        self.plain = plain

    def set_rows(self, rows: dict) -> None:
        """Sub-env ``i``'s state set to ``rows[i]`` (a tuple of floats) for each ``i``: a new run
        (its compensation zero)."""
        comps = [c.copy() for c in self.y]
        for i, row in rows.items():
            for c, v in zip(comps, row):
                c[i] = v
        self.y, self.y2d = tuple(comps), None
        if self.cc is not None:
            self.cc[:, list(rows)] = 0.0
