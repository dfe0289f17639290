"""What follows a batch's periods: info, the episode clocks and truncation (as ``TimeLimit``),
the terminal reasons, the failure charge and the autoreset of the sub-envs whose episode ended."""

from __future__ import annotations

import numpy as np

from ..core.reasons import terminal_reason

__all__ = ["BatchEnds"]


class BatchEnds:
    """The episode ends of a vector env: its engine, its :class:`~rbenvs.vector.info.BatchInfo`,
    its :class:`~rbenvs.vector.starts.BatchStarts` (the restarts), its time limit and autoreset
    mode (``next_step``: NEXT_STEP, else SAME_STEP); ``false``: the shared all-false mask."""

    def __init__(self, engine, infos, starts, max_episode_steps, next_step: bool, false):
        self.engine, self.infos, self.starts = engine, infos, starts
        self.max_episode_steps, self.next_step, self.false = max_episode_steps, next_step, false

    def finish(
        self,
        run,
        obs,
        over,
        reward,
        terminated,
        fired,
        failed,
        metrics,
        restart,
        any_restart,
        physical=None,
        charged=False,
    ):
        """The rest of a step from its period's results (``run`` holds the new states): info, the
        clocks and truncation, terminal reasons, the failure charge (unless the rewards are
        ``charged`` already) and autoreset; returns the step's five values."""
        # (a sub-env that left the observation bounds restarts before it is stepped again, so
        # the guard's static proof holds for every state this env steps: it stays plain)
        failed_mask = self.false if failed is None else failed
        lifted = fired & ~failed_mask if fired is not self.false else self.false
        info = self.infos.of_batch(
            run.y, run.u, run.last_h, failed, lifted, over, metrics, physical
        )
        run.steps += 1
        truncated = (
            self.false.copy()
            if self.max_episode_steps is None
            else run.steps >= self.max_episode_steps
        )  # as TimeLimit
        ended = terminated | over | lifted
        stopped = ended | truncated
        # (NEXT_STEP: a restarting sub-env's period is discarded; it ends nothing)
        if (stopped & ~restart if any_restart else stopped).any():
            info["terminal_reason"] = terminal_reason(
                failed_mask, lifted, over, terminated, self.engine.event_name
            )
            info["_terminal_reason"] = stopped
            terminated = ended
            if not charged:
                reward = self._charged(
                    reward, ended & ~restart if any_restart else ended, metrics["is_success"]
                )
        if any_restart:
            obs, info = self.starts.restart(run, restart, obs, info)
            reward = np.where(restart, 0.0, reward)
            terminated = terminated & ~restart
            truncated = truncated & ~restart
        done = terminated | truncated
        if self.next_step:
            run.prev_done = done
        elif done.any():
            obs, info = self.starts.same_step_reset(run, done, obs, info)
        return obs, reward, terminated, truncated, info

    def _charged(self, reward, ended, success):
        """``reward`` with the model's failure charge added where an episode ``ended`` without
        ``success`` (the single env's rule, :class:`rbenvs.core.model.Model`; the compiled step
        adds it in its kernel)."""
        charge = self.engine.failure_charge
        if charge == 0.0:
            return reward
        fail = ended & ~np.asarray(success, dtype=bool)
        return np.where(fail, reward + charge, reward) if fail.any() else reward
