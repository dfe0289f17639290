"""A start's random numbers (rbenvs.draws): the declared kinds drawn in Python and in one
compiled loop give the numbers numpy's Generator methods give, and leave the generators where
those calls leave them."""

import numpy as np
import pytest

from rbenvs.draws import GeneratorTable, batch_draws, draw, kind_codes
from rbenvs.jit import available

KINDS = ["", "u", "uu", "nnnu", "uuunnnu", "nunun"]


def _reference(rng, kinds):
    """One numpy call per number, in order: what a task's draws mean."""
    return np.array([rng.random() if k == "u" else rng.standard_normal() for k in kinds])


@pytest.mark.parametrize("kinds", KINDS)
def test_draw_groups_calls_and_gives_the_per_number_stream(kinds):
    for seed in (0, 1, 12345):
        a, b = np.random.default_rng(seed), np.random.default_rng(seed)
        for _ in range(20):
            assert np.array_equal(draw(a, kinds), _reference(b, kinds))
        assert a.random() == b.random()  # the generators were left in the same place


def test_unknown_kinds_are_refused_naming_the_rule():
    with pytest.raises(ValueError, match="draw kinds must be 'u'.*or 'n'"):
        kind_codes("ux")


@pytest.mark.skipif(
    not available(), reason="numba (the fast extra) is not installed: no compiled draws to compare"
)
@pytest.mark.parametrize("kinds", KINDS)
def test_compiled_table_draws_the_same_streams_as_numpy(kinds, monkeypatch):
    """64 generators, 300 rounds of restarts of changing subsets (about 1e5 normals and
    uniforms): the table's draws equal numpy's bit for bit, and a generator replaced in the
    table (a reseeded sub-env) is the one drawn from next. (The first ``COMPILE_AFTER`` sub-envs,
    here about 100 rounds, draw in Python, :func:`batch_draws` itself; the kernel the rest.)"""
    from rbenvs import jit

    monkeypatch.setattr(jit, "COMPILE_AFTER", 2000)
    n = 64
    mine = [np.random.default_rng(s) for s in range(n)]
    ref = [np.random.default_rng(s) for s in range(n)]
    table = GeneratorTable(mine)
    codes = kind_codes(kinds)
    pick = np.random.default_rng(99)
    for r in range(300):
        idx = np.flatnonzero(pick.random(n) < 0.3)
        if r == 150:
            table[5] = mine[5] = np.random.default_rng(777)
            ref[5] = np.random.default_rng(777)
            idx = np.union1d(idx, [5])
        got = table.draws(idx, codes)
        assert got.shape == (len(kinds), len(idx))
        assert np.array_equal(got, batch_draws([ref[i] for i in idx], kinds))
    # the Generator objects were advanced in place: Python draws continue the same streams
    assert all(a.random() == b.random() for a, b in zip(mine, ref))
