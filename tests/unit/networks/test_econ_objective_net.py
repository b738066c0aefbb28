"""EconObjectiveNet: the analytic mapping by hand, reproduced after init, save/load, fit."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from econmotor.config.objective_profile import OBJECTIVE_PRESETS, ObjectiveVector
from econmotor.config.task_economics import TaskEconomics
from econmotor.errors import ConfigError
from econmotor.networks.econ_objective_net import (
    EconFeatures,
    EconObjectiveNet,
    EnergyResponse,
    analytic_reward_weights,
)

TOY = TaskEconomics(value_per_unit_usd=0.30, damage_cost_usd_per_error=1.0, energy_price_usd_per_kwh=0.12)


def test_analytic_mapping_matches_hand_computed_dollar_scales():
    econ = EconFeatures.from_economics(TOY)
    step = EnergyResponse(summary_hours=1 / 60, energy_term_is_usd=False)
    alpha = analytic_reward_weights(ObjectiveVector(2.0, 1.0, 0.5, 1.0, 0.25), econ, step).to_list()
    w_h, p, c_d, mp_h, pi_e, h = 18.0, 0.30, 1.0, 60.0, 0.12, 1 / 60
    # spec §4 order [alpha_mpl, alpha_ep, alpha_error, alpha_energy, alpha_safety], then alpha_novelty
    expected = [2.0 * p / w_h, 0.0, 1.0 * c_d * mp_h / w_h, 0.5 * (pi_e / 1000) / (h * w_h), 1.0 * w_h / (h * w_h),
                0.25]
    assert alpha == pytest.approx(expected, rel=1e-12)


def test_analytic_energy_scale_depends_on_whether_the_term_is_priced():
    econ = EconFeatures.from_economics(TOY)
    wh = analytic_reward_weights([0, 0, 1, 0, 0], econ, EnergyResponse(2.0, False)).alpha_energy
    usd = analytic_reward_weights([0, 0, 1, 0, 0], econ, EnergyResponse(2.0, True)).alpha_energy
    assert usd == pytest.approx(1 / (2.0 * 18.0))
    assert wh == pytest.approx(usd * 0.12 / 1000)


def _random_inputs(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    vectors = rng.dirichlet(np.ones(5), size=n)
    econs = [EconFeatures(rng.uniform(10, 40), rng.uniform(0.05, 0.4), rng.uniform(20, 200), rng.uniform(0, 0.2),
                          rng.uniform(0.1, 2.0), rng.uniform(0.2, 5.0)) for _ in range(n)]
    energies = [EnergyResponse(rng.uniform(1e-4, 4.0), bool(rng.integers(2))) for _ in range(n)]
    return vectors, econs, energies


def test_net_reproduces_the_analytic_mapping_after_initialisation():
    torch.manual_seed(3)
    net = EconObjectiveNet(hidden=16)
    vectors, econs, energies = _random_inputs(50)
    for v, e, en in zip(vectors, econs, energies, strict=True):
        assert net.reward_weights(v, e, en).to_list() == pytest.approx(
            analytic_reward_weights(v, e, en).to_list(), rel=1e-12, abs=1e-15)


def test_net_weights_are_positive_where_the_objective_weight_is(tmp_path):
    net = EconObjectiveNet()
    econ = EconFeatures.from_economics(TOY)
    for preset in OBJECTIVE_PRESETS.values():
        alpha = net.reward_weights(list(preset), econ, EnergyResponse(0.5))
        assert alpha.alpha_ep == 0.0  # the analytic mapping puts no weight on EP (the energy term has it)
        per_term = [alpha.alpha_mpl, alpha.alpha_error, alpha.alpha_energy, alpha.alpha_safety, alpha.alpha_novelty]
        assert all((a > 0) == (w > 0) for a, w in zip(per_term, preset, strict=True))


def _synthetic_rows(n: int, true_mpl_factor: float, seed: int = 1):
    """Rows whose outcome values output at ``true_mpl_factor`` times the analytic price."""
    vectors, econs, energies = _random_inputs(n, seed)
    rng = np.random.default_rng(seed + 1)
    terms, outcomes = [], []
    for v, e, en in zip(vectors, econs, energies, strict=True):
        # [r_mpl, r_ep, r_error, r_energy, r_safety, r_novelty] (RewardWeights order)
        r = [rng.uniform(0, 120), rng.uniform(0, 5e4), -rng.uniform(0, 0.3), -rng.uniform(0, 5),
             -float(rng.random() < 0.1), 0.0]
        alpha = analytic_reward_weights(v, e, en).to_list()
        alpha[0] *= true_mpl_factor
        terms.append(r)
        outcomes.append(sum(a * x for a, x in zip(alpha, r, strict=True)))
    return vectors, econs, energies, terms, outcomes


def test_fit_learns_a_correction_and_round_trips_through_save_load(tmp_path):
    torch.manual_seed(0)
    net = EconObjectiveNet()
    vectors, econs, energies, terms, outcomes = _synthetic_rows(100, true_mpl_factor=1.5)
    losses = net.fit(vectors, econs, energies, terms, outcomes, epochs=200, lr=2e-2, l2=0.0)
    assert losses[-1] < 0.2 * losses[0]
    probe = (vectors[0], econs[0], energies[0])
    ratio = net.reward_weights(*probe).alpha_mpl / analytic_reward_weights(*probe).alpha_mpl
    assert 1.2 < ratio < 1.8

    path = net.save(tmp_path / "net.pt")
    loaded = EconObjectiveNet.load(path)
    for v, e, en in zip(vectors[:20], econs[:20], energies[:20], strict=True):
        assert loaded.reward_weights(v, e, en).to_list() == pytest.approx(net.reward_weights(v, e, en).to_list(),
                                                                         rel=1e-12)


def test_fit_and_load_reject_bad_input(tmp_path):
    net = EconObjectiveNet()
    with pytest.raises(ConfigError, match="equal, non-empty rows"):
        net.fit([[1, 0, 0, 0, 0]], [], [], [], [])
    with pytest.raises(ConfigError, match="--reward-weights net"):
        EconObjectiveNet.load(tmp_path / "missing.pt")
    with pytest.raises(ConfigError, match="summary_hours"):
        EnergyResponse(0.0)
