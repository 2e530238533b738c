"""The first-mode fit behind ``rodlab bench order`` recovers frequency and decay of a known signal."""
from __future__ import annotations

import numpy as np

from benchmarks.time_order import fit_mode, orders


def test_fit_recovers_frequency_and_decay_with_high_frequency_noise():
    t = np.linspace(0.0, 2.4, 1201)
    w, lam = 5.2284, 0.037
    z = 0.01 * np.exp(-lam * t) * np.sin(w * t + 0.3) + 2e-4 * np.sin(900.0 * t) + 1e-5
    wf, lf = fit_mode(t, z, 5.0)
    assert abs(wf - w) < 1e-3 * w
    assert abs(lf - lam) < 5e-3


def test_orders_of_a_second_order_sequence():
    errs = [4e-3, 1e-3, 2.5e-4, 0.0]
    o = orders(errs)
    assert o[0] == 2.0 and o[1] == 2.0 and o[2] is None
