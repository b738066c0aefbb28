"""EconObjectiveNet: (objective vector, EconContext features, energy response) -> RewardWeights.

The output is RewardWeights in the spec's §4 order ``[alpha_mpl, alpha_ep, alpha_error,
alpha_energy, alpha_safety]`` followed by ``alpha_novelty`` (six per row).

The ``analytic`` mapping
------------------------
An objective vector ``w = [w_mpl, w_error, w_energy, w_safety, w_novelty]`` says
how much a user cares about each RewardBuilder term, but the terms come in
different units (units/h, errors per attempt, USD or Wh, catastrophes, novelty).
:func:`analytic_reward_weights` turns ``w`` into per-term scales ``alpha`` so that
every ``alpha_k * r_k`` is a *dollar rate expressed as a fraction of the human
wage* (USD/h divided by ``w_h``, dimensionless), using the task economics:

=================  ======================  ==================================================
term               unit of ``r_k``          ``alpha_k``
=================  ======================  ==================================================
``r_mpl``          units/h                 ``w_mpl * p / w_h`` (value of the output rate)
``r_ep``           units/kWh               ``0``: an objective vector has no EP weight and the
                                           energy term already carries the energy (EP on top
                                           would count it twice)
``r_error``        -errors / attempt       ``w_error * c_d * MP_h / w_h`` (damage at human pace)
``r_energy``       -Wh (default) or -USD   ``w_energy * u_E / (h * w_h)`` with ``u_E = pi_e / 1000``
                   over the summary        USD/Wh for the Wh term, ``1`` when the objective
                                           prices it (``energy_term="usd"``)
``r_safety``       -1 per catastrophe      ``w_safety * C_cat / (h * w_h)``, ``C_cat = w_h * 1 h``
                                           (a catastrophe costs one human hour: stop, clean, restart)
``r_novelty``      novelty score           ``w_novelty`` (novelty has no price)
=================  ======================  ==================================================

``p`` value per good unit (USD), ``c_d`` damage cost per error (USD), ``MP_h``
human units/h, ``w_h`` human wage (USD/h), ``pi_e`` electricity price (USD/kWh)
and ``h`` the hours one reward summary covers (a step's ``dt``/3600 or an
episode's hours; the ``energy response`` features). So ``[1, 0, 0, 0, 0]`` makes the
reward the robot's output value as a fraction of a human wage, and a user's weight
of 1 on energy means "a dollar of electricity counts like a dollar of output".

The network
-----------
``alpha(x) = analytic(x) * exp(g(x))`` where ``g`` is a small MLP over the
concatenated (log-scaled) inputs whose last layer starts at zero: after
initialisation the net reproduces the analytic mapping exactly, its weights stay
non-negative (positive wherever ``w_k > 0``; ``alpha_ep`` stays 0, the analytic
mapping's value), and :meth:`EconObjectiveNet.fit`
learns a bounded multiplicative correction from recorded data: for each recorded
summary, the objective vector, its reward terms and a realised outcome ``y`` (e.g.
the episode's net dollar rate over the human wage), it minimises
``mean((sum_k alpha_k(x) r_k - y)^2) + l2 * mean(g(x)^2)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import nn

from econmotor.config.objective_profile import REWARD_WEIGHT_NAMES, EconContext, ObjectiveVector, RewardWeights
from econmotor.config.task_economics import TaskEconomics
from econmotor.errors import ConfigError

#: hours of human wage one catastrophe costs in the analytic mapping.
CATASTROPHE_COST_HUMAN_HOURS = 1.0
ECON_FEATURE_NAMES = ("wage_human_usd_per_hour", "energy_price_usd_per_kwh", "mp_human_units_per_hour",
                      "error_rate_human", "value_per_unit_usd", "damage_cost_usd_per_error")
ENERGY_FEATURE_NAMES = ("summary_hours", "energy_term_is_usd")


@dataclass(frozen=True)
class EconFeatures:
    """EconContext numbers plus the two prices the mapping needs (USD, units/h)."""

    wage_human_usd_per_hour: float
    energy_price_usd_per_kwh: float
    mp_human_units_per_hour: float
    error_rate_human: float
    value_per_unit_usd: float
    damage_cost_usd_per_error: float

    @classmethod
    def from_economics(cls, economics: TaskEconomics) -> EconFeatures:
        return cls(economics.wage_human_usd_per_hour, economics.energy_price_usd_per_kwh,
                   economics.mp_human_units_per_hour, economics.error_rate_human,
                   economics.value_per_unit, economics.damage_cost_usd_per_error)

    def context(self) -> EconContext:
        """The EconContext these features extend."""
        return EconContext(wage_human=self.wage_human_usd_per_hour, energy_price_kWh=self.energy_price_usd_per_kwh,
                           baseline_mpl_human=self.mp_human_units_per_hour,
                           baseline_error_human=self.error_rate_human)

    def to_list(self) -> list[float]:
        return [float(getattr(self, name)) for name in ECON_FEATURE_NAMES]


@dataclass(frozen=True)
class EnergyResponse:
    """How a reward summary's energy term responds: the hours it covers and its unit.

    Attributes:
        summary_hours: hours one summary covers (step ``dt_s / 3600`` or episode hours), > 0.
        energy_term_is_usd: True when ``r_energy`` is already a cost in USD (the objective's
            ``energy_term="usd"`` option), False for the default Wh term.
    """

    summary_hours: float
    energy_term_is_usd: bool = False

    def __post_init__(self) -> None:
        if not math.isfinite(self.summary_hours) or self.summary_hours <= 0:
            raise ConfigError("<energy_response>", "summary_hours", f"must be > 0, got {self.summary_hours}")

    def to_list(self) -> list[float]:
        return [float(self.summary_hours), 1.0 if self.energy_term_is_usd else 0.0]


def _analytic(objective: torch.Tensor, econ: torch.Tensor, energy: torch.Tensor) -> torch.Tensor:
    """Batched analytic mapping (see module docstring); shapes [B,5], [B,6], [B,2] -> [B,6] in the
    RewardWeights order ``[mpl, ep, error, energy, safety, novelty]``."""
    w_h, pi_e, mp_h, _e_h, p, c_d = econ.unbind(-1)
    hours, is_usd = energy.unbind(-1)
    usd_per_energy_unit = is_usd + (1.0 - is_usd) * pi_e / 1000.0
    w_mpl, w_error, w_energy, w_safety, w_novelty = objective.unbind(-1)
    return torch.stack([
        w_mpl * p / w_h,
        torch.zeros_like(w_mpl),
        w_error * c_d * mp_h / w_h,
        w_energy * usd_per_energy_unit / (hours * w_h),
        w_safety * CATASTROPHE_COST_HUMAN_HOURS * w_h / (hours * w_h),
        w_novelty,
    ], dim=-1)


def analytic_reward_weights(vector: ObjectiveVector | Sequence[float], econ: EconFeatures,
                            energy: EnergyResponse) -> RewardWeights:
    """Dollar-consistent RewardWeights for an objective vector (formulas in the module docstring)."""
    values = vector.to_list() if isinstance(vector, ObjectiveVector) else list(vector)
    out = _analytic(torch.tensor([values], dtype=torch.float64), torch.tensor([econ.to_list()], dtype=torch.float64),
                    torch.tensor([energy.to_list()], dtype=torch.float64))
    return RewardWeights.from_list(out[0].tolist())


def identity_reward_weights(vector: ObjectiveVector | Sequence[float]) -> RewardWeights:
    """``alpha = w`` (``alpha_ep = 0``): the plain ``combine_reward(vector, terms)`` of the spec."""
    return RewardWeights.from_objective(vector)


class EconObjectiveNet(nn.Module):
    """``alpha(x) = analytic(x) * exp(g(x))``, ``g`` zero at initialisation (module docstring).

    Args:
        hidden: width of the two hidden layers of ``g``.
        max_log_correction: ``|g|`` is bounded by this (tanh), so a fit can scale a weight
            by at most ``exp(max_log_correction)`` either way.
    """

    def __init__(self, hidden: int = 32, max_log_correction: float = 2.0) -> None:
        super().__init__()
        self.hidden, self.max_log_correction = int(hidden), float(max_log_correction)
        n_in = 5 + len(ECON_FEATURE_NAMES) + len(ENERGY_FEATURE_NAMES)
        self.correction = nn.Sequential(nn.Linear(n_in, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh(),
                                        nn.Linear(hidden, len(REWARD_WEIGHT_NAMES)))
        nn.init.zeros_(self.correction[-1].weight)
        nn.init.zeros_(self.correction[-1].bias)
        self.double()

    def log_correction(self, objective: torch.Tensor, econ: torch.Tensor, energy: torch.Tensor) -> torch.Tensor:
        """``g(x)``: bounded log-multiplier per weight, shape [B, 6]."""
        x = torch.cat([objective, torch.log1p(econ.abs()), torch.log(energy[..., :1]), energy[..., 1:]], dim=-1)
        return self.max_log_correction * torch.tanh(self.correction(x) / self.max_log_correction)

    def forward(self, objective: torch.Tensor, econ: torch.Tensor, energy: torch.Tensor) -> torch.Tensor:
        """RewardWeights as a [B, 6] tensor (order of :data:`REWARD_WEIGHT_NAMES`: §4's five, then novelty)."""
        return _analytic(objective, econ, energy) * torch.exp(self.log_correction(objective, econ, energy))

    def reward_weights(self, vector: ObjectiveVector | Sequence[float], econ: EconFeatures,
                       energy: EnergyResponse) -> RewardWeights:
        """One RewardWeights for one input (no gradient)."""
        values = vector.to_list() if isinstance(vector, ObjectiveVector) else list(vector)
        with torch.no_grad():
            out = self(torch.tensor([values], dtype=torch.float64), torch.tensor([econ.to_list()], dtype=torch.float64),
                       torch.tensor([energy.to_list()], dtype=torch.float64))
        return RewardWeights.from_list(out[0].tolist())

    def fit(self, objectives: Sequence[Sequence[float]], econ: Sequence[EconFeatures],
            energy: Sequence[EnergyResponse], terms: Sequence[Sequence[float]], outcomes: Sequence[float],
            epochs: int = 300, lr: float = 1e-2, l2: float = 1e-3, seed: int = 0) -> list[float]:
        """Fit the correction on recorded (objective, features, reward terms, outcome) rows.

        Args:
            objectives: objective vectors, [N, 5].
            econ: EconFeatures per row.
            energy: EnergyResponse per row.
            terms: the recorded RewardBuilder terms per row, [N, 6] in RewardWeights order
                (``r_mpl, r_ep, r_error, r_energy, r_safety, r_novelty``).
            outcomes: the realised outcome per row (same dimensionless dollar rate as the
                analytic mapping, e.g. net USD/h over ``w_h``).
            epochs: full-batch Adam steps.
            lr: Adam learning rate.
            l2: weight of ``mean(g^2)``, which keeps the net near the analytic mapping.
            seed: torch seed for reproducibility.

        Returns:
            the loss after each epoch.
        """
        n = len(objectives)
        if n == 0 or not (len(econ) == len(energy) == len(terms) == len(outcomes) == n):
            raise ConfigError("<fit data>", None, f"need equal, non-empty rows; got {n} objectives, {len(econ)} "
                              f"econ, {len(energy)} energy, {len(terms)} terms, {len(outcomes)} outcomes")
        torch.manual_seed(seed)
        obj = torch.tensor([list(o) for o in objectives], dtype=torch.float64)
        ec = torch.tensor([e.to_list() for e in econ], dtype=torch.float64)
        en = torch.tensor([e.to_list() for e in energy], dtype=torch.float64)
        r = torch.tensor([list(t) for t in terms], dtype=torch.float64)
        y = torch.tensor(list(outcomes), dtype=torch.float64)
        optimiser = torch.optim.Adam(self.correction.parameters(), lr=lr)
        losses = []
        self.train()
        for _ in range(int(epochs)):
            optimiser.zero_grad()
            g = self.log_correction(obj, ec, en)
            pred = (_analytic(obj, ec, en) * torch.exp(g) * r).sum(-1)
            loss = torch.mean((pred - y) ** 2) + l2 * torch.mean(g**2)
            loss.backward()
            optimiser.step()
            losses.append(float(loss.detach()))
        self.eval()
        return losses

    def save(self, path: str | Path) -> Path:
        """Write the state and hyperparameters to ``path`` (a ``.pt`` file)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        torch.save({"hidden": self.hidden, "max_log_correction": self.max_log_correction,
                    "state_dict": self.state_dict()}, path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> EconObjectiveNet:
        """Load a net written by :meth:`save`."""
        path = Path(path)
        if not path.is_file():
            raise ConfigError(path, None, "no EconObjectiveNet file here; train a run with --reward-weights net")
        data = torch.load(path, map_location="cpu", weights_only=True)
        net = cls(hidden=data["hidden"], max_log_correction=data["max_log_correction"])
        net.load_state_dict(data["state_dict"])
        net.eval()
        return net
