"""Closed-form references of the accuracy benchmark (benchmarks/references.py)."""
import numpy as np
import pytest

from benchmarks.references import EulerBernoulliCantilever, heavy_elastica, trajectory_error


@pytest.mark.parametrize("alpha, dx, dz", [(1.0, 0.0566, 0.3017), (2.0, 0.1606, 0.4935), (10.0, 0.5550, 0.8106)])
def test_tip_load_elastica_matches_bisshopp_drucker(alpha, dx, dz):
    # classical large-deflection table (Bisshopp & Drucker 1945), P L^2 / EI = alpha
    s = heavy_elastica(length=1.0, EI=1.0, w=0.0, P=alpha, model="inextensible")
    assert 1 - s.tip[0] == pytest.approx(dx, abs=2e-4)
    assert -s.tip[1] == pytest.approx(dz, abs=2e-4)


def test_heavy_elastica_small_load_is_linear_theory():
    EI, w, L = 1e3, 1.0, 2.0
    s = heavy_elastica(length=L, EI=EI, w=w, model="inextensible")
    assert -s.tip[1] == pytest.approx(w * L**4 / (8 * EI), rel=1e-4)
    assert s.theta[-1] == pytest.approx(w * L**3 / (6 * EI), rel=1e-4)


def test_extension_and_shear_increase_the_sag_slightly():
    kw = dict(length=1.0, EI=1.2566, w=6.16, EA=1.2566e4, GA=4.19e3)
    z = {m: -heavy_elastica(**kw, model=m).tip[1] for m in ("inextensible", "extensible", "shearable")}
    assert z["inextensible"] < z["extensible"] < z["shearable"]
    assert z["shearable"] - z["inextensible"] < 2e-3 * z["inextensible"] * 10


def test_bad_stiffness_is_a_clear_error():
    with pytest.raises(ValueError, match="positive"):
        heavy_elastica(length=1.0, EI=0.0, w=1.0)


def test_euler_bernoulli_values_of_physics_spec():
    b = EulerBernoulliCantilever(youngs=1e5)  # docs/physics.md §8 A table
    assert b.omega1 == pytest.approx(0.49724, rel=1e-4)
    assert b.period == pytest.approx(12.636, rel=1e-4)
    assert b.amplitude == pytest.approx(0.010055, rel=1e-4)
    b7 = EulerBernoulliCantilever(youngs=1e7)
    assert b7.omega1 == pytest.approx(4.9724, rel=1e-4)


def test_mode_shape_clamped_free_conditions():
    b = EulerBernoulliCantilever()
    x = np.linspace(0, b.length, 20001)
    phi = b.mode_shape(x)
    d1 = np.gradient(phi, x)
    d2 = np.gradient(d1, x)
    d3 = np.gradient(d2, x)
    assert abs(phi[0]) < 1e-12 and abs(d1[0]) < 1e-3
    assert abs(d2[-3]) < 1e-2 * abs(d2[0])  # no moment at the free end
    assert abs(d3[-5]) < 2e-2 * abs(d3[5])  # no shear force at the free end
    assert b.initial_velocity(np.array([b.length]))[0] == pytest.approx(b.v_tip)


def test_trajectory_error_interpolates_the_reference():
    t_ref = np.linspace(0, 1, 101)
    y_ref = np.stack([t_ref, 0 * t_ref], 1)
    t = np.array([0.005, 0.5, 0.995])
    assert trajectory_error(t, np.stack([t, t * 0], 1), t_ref, y_ref) < 1e-12
    assert trajectory_error(t, np.stack([t, t * 0 + 0.1], 1), t_ref, y_ref, scale=0.5) == pytest.approx(0.2)
