"""Action converter (docs/tasks.md §2): worked values of §2.7, intended mapping, clipping, ramp, reset, errors."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from policies.control import ActionConverter, ControlConfig, control_config, smoothing_weights


class Ctrl:
    def __init__(self, B, N=21):
        self.kappa_bar = np.zeros((B, N, 2))
        self.tau_bar = np.zeros((B, N))


def one_step(kind, action, *, smoothing, substeps=1):
    conv = ActionConverter(control_config(kind, substeps=substeps, smoothing=smoothing), envs=1)
    inc = conv.convert(np.asarray(action, np.float32)[None])
    return conv, inc


def test_reference_worked_values_2d():
    conv, inc = one_step("bend_2d", np.arange(1, 6) / 6, smoothing="reference")
    np.testing.assert_allclose(conv.K[0, :, 0], [0.008333, 0.016667, 0.025, 0.033333, 0.041667], atol=1e-6)
    dk = inc.dkappa[0, :, 0]
    expect = np.zeros(21)
    expect[2:5], expect[5:9], expect[9:13] = 0.0027778, 0.0041667, 0.00625
    expect[13:17], expect[17:20] = 0.0083333, 0.0104167
    np.testing.assert_allclose(dk, expect, atol=1e-7)
    assert dk[1] == 0.0 and np.all(inc.dkappa[0, :, 1] == 0.0) and np.all(inc.dtau == 0.0)


def test_reference_worked_values_3d_twist():
    conv, inc = one_step("bend_twist", np.arange(1, 16) / 16, smoothing="reference")
    np.testing.assert_allclose(conv.kappa_obs[0], 0.05 * np.arange(1, 11) / 16, atol=1e-7)
    np.testing.assert_allclose(conv.K[0, 0], [0.003125, 0.00625], atol=1e-8)
    for n in (2, 3, 4):
        np.testing.assert_allclose(inc.dkappa[0, n], [0.0010417, 0.0020833], atol=1e-7)
        np.testing.assert_allclose(inc.dtau[0, n], 0.0114583, atol=1e-7)
    for n in (17, 18, 19):
        np.testing.assert_allclose(inc.dkappa[0, n], [0.0070313, 0.0078125], atol=1e-7)
    for n in (5, 6, 7, 8):
        np.testing.assert_allclose(inc.dtau[0, n], 0.009375, atol=1e-7)
    np.testing.assert_allclose(conv.T[0, :2], [0.034375, 0.0375], atol=1e-7)
    assert np.all(inc.dkappa[0, [0, 1, 20]] == 0) and np.all(inc.dtau[0, [0, 1, 20]] == 0)


def test_reference_worked_values_contact():
    conv, inc = one_step("contact_bend", np.arange(1, 11) / 11, smoothing="reference")
    np.testing.assert_allclose(conv.K[0, 0], [0.022727, 0.045455], atol=1e-6)
    for n in (2, 3, 4):
        np.testing.assert_allclose(inc.dkappa[0, n], [0.0075758, 0.0151515], atol=1e-7)


def test_intended_mapping_default():
    cfg = control_config("bend_2d", substeps=1)
    assert cfg.smoothing == "intended"
    conv, inc = one_step("bend_2d", np.arange(1, 6) / 6, smoothing="intended")
    dk = inc.dkappa[0, :, 0]
    expect = np.zeros(21)
    expect[1:4], expect[4:8], expect[8:12] = 0.0027778, 0.0041667, 0.00625
    expect[12:16], expect[16:20] = 0.0083333, 0.0104167
    np.testing.assert_allclose(dk, expect, atol=1e-7)
    # every region's weights sum to one; twist follows the same nodes
    owner, w = smoothing_weights(21, (2, 6, 10, 14, 18), "intended")
    assert [float(w[owner == k].sum()) for k in range(5)] == pytest.approx([1.0] * 5)
    owner_r, w_r = smoothing_weights(21, (2, 6, 10, 14, 18), "reference")
    assert [float(w_r[owner_r == k].sum()) for k in range(5)] == pytest.approx([1, 1, 1, 1, 0.75])
    _, inc = one_step("bend_twist", np.ones(15), smoothing="intended")
    np.testing.assert_allclose(inc.dtau[0, 1:4], 0.05 / 3)
    np.testing.assert_allclose(inc.dtau[0, 16:20], 0.05 / 4)


def test_none_mapping():
    _, inc = one_step("bend", np.ones(10), smoothing="none")
    nz = np.nonzero(inc.dkappa[0, :, 0])[0]
    assert nz.tolist() == [2, 6, 10, 14, 18]
    np.testing.assert_allclose(inc.dkappa[0, nz, 0], 0.05)


@pytest.mark.parametrize("smoothing", ["intended", "reference"])
def test_clip_accumulate_and_ramp(smoothing):
    B, N = 3, 4
    conv = ActionConverter(control_config("bend_twist", substeps=N, smoothing=smoothing), envs=B)
    ctrl = Ctrl(B)
    rng = np.random.default_rng(1)
    for step in range(60):
        a = rng.uniform(-1, 1, (B, 15)).astype(np.float32)
        a[0] = 1.0                              # env 0 saturates after 40 (bend) / 32 (twist) steps
        K_old = conv.K.copy()
        inc = conv.convert(a)
        if step >= 41:  # 40 steps of 0.05 reach 2 up to float32 rounding
            assert np.all(conv.K[0] == np.float32(2.0)) and np.all(inc.dkappa[0] == 0.0)
        # increments are taken after clipping
        np.testing.assert_array_equal(
            conv.K, np.clip(K_old + np.float32(0.05) * a[:, :10].reshape(B, 5, 2), -2, 2).astype(np.float32))
        for k in range(N):
            conv.apply(ctrl, inc, k)
        kb, tb = conv.natural_values()
        np.testing.assert_allclose(ctrl.kappa_bar, kb, atol=1e-12)
        np.testing.assert_allclose(ctrl.tau_bar, tb, atol=1e-12)
    np.testing.assert_allclose(conv.T[0], np.float32(np.pi / 2))
    assert np.all(np.abs(conv.K) <= 2.0) and np.all(np.abs(conv.T) <= np.float32(np.pi / 2))


def test_no_temporal_interpolation_applies_once():
    conv = ActionConverter(ControlConfig(kind="bend", substeps=5, temporal_interpolation=False), envs=1)
    ctrl = Ctrl(1)
    inc = conv.convert(np.ones((1, 10)))
    for k in range(5):
        conv.apply(ctrl, inc, k)
    np.testing.assert_allclose(ctrl.kappa_bar, conv.natural_values()[0])


def test_reset_mask_and_batch_independence():
    conv = ActionConverter(control_config("bend", substeps=2), envs=4)
    a = np.random.default_rng(0).uniform(-1, 1, (4, 10))
    conv.convert(a)
    conv.reset(np.array([True, False, True, False]))
    assert np.all(conv.K[[0, 2]] == 0) and np.all(conv.K[[1, 3]] != 0)
    single = ActionConverter(control_config("bend", substeps=2), envs=1)
    inc1 = single.convert(a[1:2])
    conv2 = ActionConverter(control_config("bend", substeps=2), envs=4)
    inc4 = conv2.convert(a)
    np.testing.assert_array_equal(inc4.dkappa[1], inc1.dkappa[0])


def test_bad_actions_raise():
    conv = ActionConverter(control_config("bend", substeps=2), envs=2)
    with pytest.raises(ValueError, match="shape"):
        conv.convert(np.zeros((2, 5)))
    with pytest.raises(ValueError, match="NaN"):
        a = np.zeros((2, 10))
        a[1, 3] = np.nan
        conv.convert(a)
    with pytest.raises(ValueError, match="smoothing"):
        ControlConfig(smoothing="bogus")  # type: ignore[arg-type]
    assert ActionConverter(control_config("bend_2d", substeps=1)).convert(np.zeros(5)).dkappa.shape == (1, 21, 2)


def test_control_module_needs_no_gymnasium():
    """policies.control is numpy only: no gymnasium, no numba (so none of the simulator's kernels); of sim it
    loads only the package's light face and its support layer."""
    code = ("import sys, json; sys.modules['gymnasium'] = None; sys.modules['numba'] = None\n"
            "from policies.control import ActionConverter, control_config\n"
            "c = ActionConverter(control_config('bend', substeps=2), envs=3); c.convert([[0.5]*10]*3)\n"
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] == 'sim')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=".")
    assert out.returncode == 0, out.stderr
    assert all(m in ("sim", "sim._cache") or m.startswith("sim.support") for m in json.loads(out.stdout)), out.stdout
