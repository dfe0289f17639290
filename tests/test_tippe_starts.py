"""The tippe top's starts (``start=``, docs/physics.md §3): the state each builds, what it
refuses, and the inversion from the literature's start checked against its oracles (Jellett's
integral, the energy, the step convergence of the time to 90 degrees) and against Leine and
Glocker's figures for their top at 180 rad/s."""

import math

import gymnasium as gym
import numpy as np
import pytest

import rbenvs  # noqa: F401  (registers the ids)
from rbenvs.dynamics.tippe_top import tippe_frame
from rbenvs.tasks.tippe_top import STARTS

ID = "rbenvs/TippeTop-v0"


def _start(start, seed, **kwargs):
    env = gym.make(ID, start=start, spin=(100.0, 200.0), tilt=(0.05, 0.5), **kwargs).unwrapped
    env.reset(seed=seed)
    return env, env.get_state()


@pytest.mark.parametrize("free_flight", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rest_start_has_the_centre_of_mass_at_rest_and_the_spin_on_the_axis(seed, free_flight):
    env, state = _start("rest", seed, free_flight=free_flight)
    v, w = state["velocity"], state["angular_velocity"]
    # the constraint's vertical velocity: zero when the spin is about the symmetry axis
    # (the contact arm turns about k, which keeps its height)
    assert np.all(np.abs(v) <= 1e-15) and w[0] == 0.0 and w[1] == 0.0 and 100.0 <= w[2] <= 200.0
    rolling, _ = _start("rolling", seed, free_flight=free_flight)
    # same draws, same attitude and spin; the rolling start moves G so that the contact point
    # rests, the rest start leaves the contact point slipping at that speed
    assert np.array_equal(rolling.get_state()["attitude"], state["attitude"])
    slip = env.system.slip_speed(env.state_components)
    assert (
        slip == pytest.approx(np.linalg.norm(rolling.get_state()["velocity"][:2]), rel=1e-12)
        and slip > 0.0
    )
    assert rolling.system.slip_speed(rolling.state_components) < 1e-15


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_vertical_start_spins_about_the_space_vertical(seed):
    env, state = _start("vertical", seed)
    q, w = state["attitude"], state["angular_velocity"]
    rm = np.array(tippe_frame(*q)).reshape(3, 3)  # body -> space
    space = rm @ w
    n = np.linalg.norm(w)
    assert 100.0 <= n <= 200.0
    assert np.allclose(space, (0.0, 0.0, n), atol=1e-12 * n)
    assert np.all(np.abs(state["velocity"][:2]) == 0.0)


def test_starts_are_checked_at_construction():
    assert STARTS == ("rolling", "rest", "vertical")
    with pytest.raises(ValueError, match="start must be one of"):
        gym.make(ID, start="spun")
    with pytest.raises(ValueError, match="start='rest' needs fidelity 'gliding' or 'frictionless'"):
        gym.make(ID, start="rest", fidelity="rolling")
    gym.make(ID, start="rolling", fidelity="rolling")  # a rolling top starts rolling


class EpisodeEnded(Exception):
    pass


def _t90(refine, spin=180.0, start="rest", **kwargs):
    """Time to pass 90 degrees (linear in the tilt within the period that crosses), Jellett's
    largest relative drift, the largest energy rise and the least N / (m g) on the way, with
    ``refine`` times the internal steps the guard takes at the start (``substeps`` is a minimum:
    ``refine = 2`` halves the step of every period the start's count governs)."""
    # the stability bound's steps: the refinement below halves them (the accuracy bound, the
    # default, has its own tests: tests/test_tippe_stiff.py)
    make = dict(
        start=start,
        spin=spin,
        tilt=0.1,
        max_episode_steps=2000,
        **dict(dict(friction_bound="stability"), **kwargs),
    )
    env = gym.make(ID, **make).unwrapped
    env.reset(seed=0)
    count = env.internal_steps(
        env.state_components, env.actuator.control(np.zeros(env.action_space.shape))[1]
    )
    env = gym.make(ID, substeps=refine * count, **make).unwrapped
    _, info = env.reset(seed=0)
    j0, e_prev, prev = info["jellett"], info["energy"], info["tilt"]
    drift = rise = 0.0
    least = math.inf
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    for k in range(1, 2000):
        _, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            raise EpisodeEnded(
                f"ended at {k * env.dt:.3f} s, tilt {math.degrees(info['tilt']):.1f} deg: "
                f"{info.get('terminal_reason')}"
            )
        drift = max(drift, abs(info["jellett"] - j0) / abs(j0))
        rise = max(rise, info["energy"] - e_prev)
        e_prev = info["energy"]
        least = min(least, info["normal_force"] / (env.params.mass * env.params.gravity))
        if info["tilt"] > math.pi / 2:
            return (
                (k - 1 + (math.pi / 2 - prev) / (info["tilt"] - prev)) * env.dt,
                drift,
                rise,
                least,
            )
        prev = info["tilt"]
    raise EpisodeEnded("the top did not pass 90 degrees in 20 s")


def test_leine_glocker_top_from_rest_inverts_as_they_report():
    """Their top (the defaults) spun at 180 rad/s about its axis at tilt 0.1 with the centre of
    mass at rest: Leine and Glocker's regularised-Coulomb reference passes 90 degrees in about
    2.7 s with the normal force above 0.55 m g throughout (docs/physics.md §3, Starts); the
    rolling start of the same top lifts off before 90 degrees instead. Here: the time converged
    in the step (the env's step against half of it), Jellett's integral held to the
    integrator's error, the energy never rising."""
    t, drift, rise, least = _t90(1)
    t_half, drift_half, _, _ = _t90(2)
    assert 0.0 < abs(t - t_half) < 1e-6  # (2.9e-7 s from DOP853 at rtol 1e-13, measured)
    assert 2.65 < t < 2.75  # 2.7098 s here
    assert least > 0.54  # 0.5500 here: it stays on the table, as theirs does
    assert drift < 1e-9 and drift_half < drift / 4  # 9.9e-11 here; fourth order in the step
    assert rise <= 1e-14 * abs(t)  # friction only dissipates (round-off allowed)
    with pytest.raises(EpisodeEnded, match="lift_off"):
        _t90(1, start="rolling")


@pytest.mark.parametrize("start,spin", [("rest", 150.0), ("vertical", 150.0), ("rest", 120.0)])
def test_inversion_from_other_starts_holds_jellett_and_converges(start, spin):
    t, drift, rise, least = _t90(1, spin=spin, start=start)
    t_half, _, _, _ = _t90(2, spin=spin, start=start)
    assert 0.0 < abs(t - t_half) < 1e-5 and drift < 1e-8 and rise <= 1e-14 and least > 0.0


def test_default_top_agrees_with_dop853_from_the_literature_start():
    """The default ``TippeTop-v0`` (the rest start, 150 rad/s, accuracy-sized rk4 steps) against
    scipy's DOP853 at rtol 1e-12 (rbenvs' dop853) on the same equations (issue 18): the time to 90
    degrees within 1e-4 s (measured 5e-8 s), the least normal force on the way within 1e-5 m g,
    Jellett's integral within 1e-8 of itself (measured 1.1e-9; DOP853 5e-14), the energy never
    rising. (The tilt 3 s in agrees to 3.9e-7 rad, measured once: DOP853 takes 2 min there.)"""
    from rbenvs.bench import tippe_steps

    env = gym.make(ID).unwrapped
    assert env.task.start == "rest" and env.system.friction_bound == "accuracy"
    ours = tippe_steps.inversion("rest", 150.0, None, friction_bound="accuracy", compiled=False)
    ref = tippe_steps.inversion("rest", 150.0, 1, "dop853", compiled=False)
    assert ours["ended"] is None and ref["ended"] is None
    assert abs(ours["t90"] - ref["t90"]) < 1e-4 and 1.5 < ours["t90"] < 1.7
    assert abs(ours["least_normal"] - ref["least_normal"]) < 1e-5 and ours["least_normal"] > 0.75
    assert ours["drift"] < 1e-8 and ref["drift"] < 1e-12
    assert ours["rise"] <= 0.0 and ref["rise"] <= 0.0


def test_default_top_jellett_through_the_turn_over_and_the_slow_climb():
    """Issue 18 measures Jellett's drift "over an inversion" as the turn-over: the old default
    (rolling start, stability bound) drifted 3.8e-10 to 90 degrees and through 123 degrees, the
    figure the issue quotes (5e-10), but 6.4e-8 by the task's end at 150 degrees (17.3 s). The
    new default turns over within 1e-8 (at most 1.1e-9 through 120 degrees, measured). The slow
    climb from about 125 to 150 degrees that follows (17 s) accumulates rk4's error on the stiff
    slip mode at about 1.2e-7 a second at the accuracy bound's steps: 2.05e-6 by 150 degrees
    (measured; the stability bound's steps 1.2e-7, 400 steps a period 3.0e-9). This test keeps
    both figures: the turn-over's within the issue's 1e-8, the whole episode's within 5e-6."""
    env = gym.make(ID)
    _, info = env.reset(seed=0)
    j0 = info["jellett"]
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    turn = whole = 0.0
    for _ in range(2500):
        _, _, terminated, truncated, info = env.step(action)
        drift = abs(info["jellett"] / j0 - 1.0)
        if info["tilt"] <= math.radians(120.0):
            turn = max(turn, drift)
        whole = max(whole, drift)
        if terminated or truncated:
            break
    assert terminated and info["is_success"] and info["tilt"] >= math.radians(150.0)
    assert 0.0 < turn < 1e-8  # 1.1e-9 at most
    assert turn < whole < 5e-6  # 2.05e-6
