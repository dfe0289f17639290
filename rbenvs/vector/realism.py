"""A vector env's sensor and actuator options over its batch (:mod:`rbenvs.envs.options`).

:class:`BatchRealism` holds what ``action_delay``, ``observation_noise`` and ``observation_bias``
carry from step to step for ``n`` sub-envs: one queue of actions for the batch (a ring of
``(delay, n, k)`` with one head) and one noise stream per sub-env, keyed per episode from that
sub-env's generator after its start, as the single env keys its own. Sub-env ``i`` sees the
numbers a single env seeded ``s + i`` sees, in the same order (the lockstep tests).
"""

from __future__ import annotations

import numpy as np

from ..draws import GeneratorTable, kind_codes
from ..envs.options import NOISE_BLOCK, noise_generator, noisy_observation, rekey

__all__ = ["BatchRealism"]


class BatchRealism:
    """The action queue and the noise streams of ``n`` sub-envs under the validated options
    ``realism`` (:class:`rbenvs.envs.options.Realism`). ``compiled_draws``: the noise drawn by
    one compiled call over the streams (:class:`rbenvs.draws.GeneratorTable`, where numba is
    installed); else each sub-env's in blocks of ``NOISE_BLOCK`` observations per Python call."""

    def __init__(self, realism, n: int, n_obs: int, action_shape: tuple, compiled_draws: bool):
        self.options = realism
        self.noiseless_observation = None  # the last observation before its noise
        if realism.delay:
            self.queue = np.zeros((realism.delay, n) + tuple(action_shape))
            self.head = 0
        self.table = None
        if realism.stream:
            self.streams = [noise_generator() for _ in range(n)]  # rekeyed per episode
            self.bias = None if realism.bias is None else np.zeros((n, n_obs))
            if realism.noise is not None:
                if compiled_draws:
                    self.table = GeneratorTable(self.streams)
                    self.codes = kind_codes("n" * n_obs)
                else:
                    self.block = np.zeros((n, NOISE_BLOCK, n_obs))
                    self.position = np.full(n, NOISE_BLOCK, dtype=np.int64)

    def __getstate__(self):
        """Everything but the compiled table of streams (numba's typed list), made again on
        loading around the same streams."""
        state = self.__dict__.copy()
        state["table"] = self.table is not None
        return state

    def __setstate__(self, state) -> None:
        self.__dict__.update(state)
        self.table = GeneratorTable(self.streams) if state["table"] else None

    def delayed(self, actions):
        """The actions that act this period, those given ``action_delay`` periods ago;
        ``actions`` (checked and clipped, ``(n, k)``) join the queue."""
        acting = self.queue[self.head].copy()
        self.queue[self.head] = actions
        self.head = (self.head + 1) % self.options.delay
        return acting

    def after(self, obs, info, idx, rngs, high, same_step: bool):
        """``(obs, info)`` of a reset or step in which the sub-envs ``idx`` began an episode:
        their queues emptied (zero actions); SAME_STEP (``same_step``): the ended episodes' last
        observations (``info["final_obs"]``) noised from their old streams first; then the new
        episodes' streams keyed from their generators ``rngs`` and their biases drawn, and every
        observation noised (clipped to ``high``)."""
        r = self.options
        if r.delay and len(idx):
            self.queue[:, idx] = 0.0
        if not r.stream:
            return obs, info
        if same_step and len(idx):
            final = info["final_obs"].copy()
            last = np.stack([final[i] for i in idx])
            bias = None if self.bias is None else self.bias[idx]
            noisy = noisy_observation(last, bias, r.noise, self.noise_rows(idx), high)
            for j, i in enumerate(idx):
                final[i] = noisy[j]
            info["final_obs"] = final
        for i in idx:
            stream = self.streams[i]
            rekey(stream, rngs[i])
            if self.bias is not None:
                self.bias[i] = r.bias * stream.standard_normal(len(r.bias))
            if r.noise is not None and self.table is None:
                self.position[i] = NOISE_BLOCK
        self.noiseless_observation = obs
        every = np.arange(len(self.streams))
        return noisy_observation(obs, self.bias, r.noise, self.noise_rows(every), high), info

    def noise_rows(self, idx):
        """The next observation's noise ``(len(idx), k)`` of the sub-envs ``idx`` (``None``
        without observation noise): one compiled call over their streams, or from each one's
        block, refilled from its stream when used up."""
        if self.options.noise is None:
            return None
        if self.table is not None:
            return self.table.draws(idx, self.codes).T
        position = self.position[idx]
        for i in idx[position == NOISE_BLOCK]:
            self.block[i] = self.streams[i].standard_normal(self.block.shape[1:])
            self.position[i] = 0
        position = self.position[idx]
        z = self.block[idx, position]
        self.position[idx] = position + 1
        return z
