"""PyElastica peer scenes: frame mapping, curvature conversion, damping semantics (skipped without PyElastica)."""
import numpy as np
import pytest

pytest.importorskip("elastica")

from benchmarks.peers.elastica_scenes import ElasticaRods, RodSpec, run_static, stable_dt_estimate  # noqa: E402
from benchmarks.scenes import StaticCantilever  # noqa: E402


def test_rest_tip_frame_is_the_dismech_initial_frame():
    rods = ElasticaRods(RodSpec(n_nodes=11), n_rods=1)
    R = rods.tip_directors()[0]  # rows m1, m2, t (world)
    np.testing.assert_allclose(R, np.diag([-1.0, -1.0, 1.0]), atol=1e-12)


def test_positive_kappa1_bends_toward_minus_x_and_kappa2_toward_minus_y():
    # DisMech convention (docs/tasks.md §1.5) through the paper's Elastica mapping (§1.6)
    rods = ElasticaRods(RodSpec(n_nodes=11, gravity=(0.0, 0.0, 0.0)), n_rods=2, dt=4e-4)
    k = np.zeros((2, 11, 2))
    k[0, 1:-1, 0] = 0.05
    k[1, 1:-1, 1] = 0.05
    rods.add_natural_curvature(k)
    rods.step(2500)
    tip = rods.node_pos()[:, -1]
    assert tip[0, 0] < -0.1 and abs(tip[0, 1]) < 1e-6
    assert tip[1, 1] < -0.1 and abs(tip[1, 0]) < 1e-6
    # an arc of constant curvature 0.05 per 0.1 m: tip turning angle 0.45 rad, tip x ~ -L(1-cos)/phi
    phi = 0.05 * 9
    assert tip[0, 0] == pytest.approx(-(1 - np.cos(phi)) / phi, rel=0.12)


def test_paper_damping_decays_translation_at_nu_over_rho_a():
    # PyElastica 0.2.4 damping nu: force nu*v*l per node -> velocity decays at nu/(rho A)
    spec = RodSpec(n_nodes=11, gravity=(0.0, 0.0, 0.0), clamp=False, damping=("paper", 10.0))
    rods = ElasticaRods(spec, dt=2e-4)
    rods.set_node_vel(np.tile([0.1, 0.0, 0.0], (11, 1)))
    rods.step(1000)  # 0.2 s
    gamma = 10.0 / (1000.0 * np.pi * 0.05**2)
    v = rods.node_vel()[0, :, 0]
    np.testing.assert_allclose(v, 0.1 * np.exp(-gamma * 0.2), rtol=1e-3)


def test_static_cantilever_converges_toward_the_elastica():
    sc = StaticCantilever(t_end=2.0)
    ref = sc.reference_tip("shearable")
    errs = []
    for n in (11, 21):
        dt = stable_dt_estimate(RodSpec(n_nodes=n, length=1.0, radius=0.02, density=500.0, youngs=1e7))
        r = run_static(sc, n_nodes=n, dt=dt)
        assert r["stable"]
        errs.append(np.linalg.norm(np.asarray(r["tip"]) - ref))
    assert errs[1] < 0.6 * errs[0]
    assert errs[1] < 0.06  # first-order clamp offset: about 0.8 l


def test_bad_rod_spec_is_a_clear_error():
    with pytest.raises(ValueError, match="n_nodes"):
        RodSpec(n_nodes=3)
    with pytest.raises(ValueError, match="damping"):
        RodSpec(damping=("viscous", 1.0))
