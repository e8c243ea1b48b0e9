"""The dead-volume models against closed-form solutions and conservation of material."""

import numpy as np
import pytest

from fgslice.analysis.simulate import (
    fraction_from_temperature,
    lag_average,
    mixing_deposit,
    thermal_temperature,
)
from fgslice.errors import SettingsError


def _step_integral(v, v0, v_plug, v_mix):
    """Integral from 0 to v of the plug + first-order response to a unit step at v0."""
    t = np.maximum(v - v0 - v_plug, 0.0)
    return t - v_mix * -np.expm1(-t / v_mix)


def test_lag_average_matches_sequential_recurrence_across_many_blocks():
    rng = np.random.default_rng(1)
    widths = rng.uniform(0.01, 3.0, 4000)          # total decay ~ 12000: ~24 blocks
    inputs = rng.uniform(0, 1, (4000, 2))
    scale = 0.5
    y = np.array([0.3, 0.7])
    expected = np.empty_like(inputs)
    for i in range(len(widths)):                   # exact per-interval solution, one at a time
        x = widths[i] / scale
        a = np.exp(-x)
        expected[i] = inputs[i] + (y - inputs[i]) * (1 - a) / x
        y = a * y + (1 - a) * inputs[i]
    got = lag_average(widths, inputs, scale, np.array([0.3, 0.7]))
    assert np.abs(got - expected).max() < 1e-10


def test_mixing_step_response_is_plug_delay_then_exponential():
    rng = np.random.default_rng(2)
    vol = rng.uniform(0.05, 0.5, 3000)
    commanded = np.zeros((3000, 2))
    commanded[:, 1] = 1.0
    commanded[1500:] = [1.0, 0.0]
    v_plug, v_mix = 47.95, 20.55                   # 68.5 mm^3 with a 30 % well-mixed share
    deposited = mixing_deposit(vol, commanded, v_plug, v_mix)
    edges = np.r_[0.0, np.cumsum(vol)]
    exact = (_step_integral(edges[1:], edges[1500], v_plug, v_mix)
             - _step_integral(edges[:-1], edges[1500], v_plug, v_mix)) / vol
    assert np.abs(deposited[:, 0] - exact).max() < 1e-9
    assert np.allclose(deposited.sum(axis=1), 1.0)
    # nothing of the new material comes out before the plug volume has been pushed through
    assert np.all(deposited[edges[1:] <= edges[1500] + v_plug, 0] == 0.0)


def test_pure_plug_conserves_material():
    rng = np.random.default_rng(3)
    vol = rng.uniform(0.1, 1.0, 2000)
    f = rng.uniform(0, 1, 2000)
    commanded = np.stack([f, 1 - f], axis=1)
    v_plug = 37.0
    deposited = mixing_deposit(vol, commanded, v_plug, 0.0, initial=np.array([0.0, 1.0]))
    edges = np.r_[0.0, np.cumsum(vol)]
    # what came out = the initial chamber content + all commanded except the last v_plug
    inside = np.clip(edges[-1] - v_plug - edges[:-1], 0.0, vol)
    expected_a = np.sum(commanded[:, 0] * inside)
    assert np.sum(deposited[:, 0] * vol) == pytest.approx(expected_a, rel=1e-10)


def test_thermal_lag_follows_exponential_in_time():
    durations = np.full(400, 0.25)                 # 100 s of moves
    commanded = np.where(np.arange(400) < 40, 190.0, 225.0)
    tau = 8.0
    actual = thermal_temperature(durations, commanded, tau)
    t0 = np.arange(400) * 0.25 - 10.0              # time since the change at the start of each move
    t1 = t0 + 0.25
    # mean of 225 - 35 exp(-t / tau) over [t0, t1] for moves after the change
    mean = 225.0 - 35.0 * tau * (np.exp(-t0 / tau) - np.exp(-t1 / tau)) / 0.25
    after = t0 >= 0
    assert np.abs(actual[after] - mean[after]).max() < 1e-9
    assert np.allclose(actual[~after], 190.0, atol=1e-9)
    fractions = fraction_from_temperature(actual, 190.0, 225.0)
    assert fractions[0, 0] == 1.0 and fractions[-1, 0] == pytest.approx(0.0, abs=1e-4)
    # half way in temperature after tau ln 2
    crossing = np.flatnonzero(fractions[:, 0] < 0.5)[0]
    assert abs(t0[crossing] - tau * np.log(2)) <= 0.25


def test_temperature_mapping_needs_two_temperatures():
    with pytest.raises(SettingsError):
        fraction_from_temperature(np.array([200.0]), 200.0, 200.0)
