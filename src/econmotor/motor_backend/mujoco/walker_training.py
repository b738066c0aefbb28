"""The mujoco backend's CPU trainer of the card robots (G1, T1): PPO on the batched walker env.

What a run does (:class:`WalkerTrainingRun`):

1. builds the env that prices the robot (:class:`~econmotor.locomotion.env.WalkerBatch`: the same
   model, course, stress, meter and fall rule) as a learner's env
   (:class:`~econmotor.locomotion.learning.WalkerLearningEnv`: random start points, the step reward);
2. starts the actor from an ONNX walker's network (``--init-policy``: Holosoma's PPO walkers' MLP or its
   FastSAC walkers' layer-normalised, tanh-squashed actor, :mod:`.walker_actor`) or from scratch, with a
   fresh privileged critic (:mod:`.walker_ppo`);
3. learns in the shared :class:`~econmotor.motor_backend.training_loop.TrainingLoop` as its
   :class:`WalkerLearner`: each chunk is ``steps_per_iteration`` control steps of every robot, then one PPO
   update; its row goes to the training curve (``curve.jsonl``: legs per hour, Wh per leg and falls of the
   episodes that ended, the reward's locomotion and economic parts, KL, learning rate, std, the seconds
   collection took);
   the robots are stepped in ``collect_workers`` worker processes (:mod:`.walker_collect`: each steps its
   share of the robots with the actor the trainer sends it; the critic's values and the update run here),
   or in this process with ``collect_workers: 1``; by default one worker per usable CPU with at least 8
   robots each (:func:`~.walker_collect.default_workers`); while the workers wait for the next actor, the
   critic's values and the update run on ``update_threads`` torch threads (by default every usable CPU when
   the robots are in workers: their cores are idle meanwhile); with ``policy_lag: 1`` the workers step the
   next iteration under the current actor while the update runs (on one thread by default), so the update
   learns from a batch its actor's previous version collected;
4. checkpoints (``checkpoints/latest.pt``: learner, iteration, env steps, each worker's next seed) every
   ``checkpoint_every_s`` of wall time, at the end and when interrupted: ``--resume`` continues from it;
5. held-out selection (:mod:`econmotor.motor_backend.selection`): at its cadence, the actor exported as
   the run's ONNX (``selection/candidate.onnx``) walks held-out seeds of the priced course through the one
   walker evaluator (:func:`econmotor.locomotion.evaluation.evaluate`, a report's), episode ``i`` under
   ``select_stresses[i % len(select_stresses)]`` (the mujoco backend passes the nominal conditions a
   report prices by default and, for a run under a datapack, the training's stress: a look's verdict
   then sees the falls the stress causes); the best by the buyer's verdict, then J, is kept
   (``best/policy.onnx``);
6. stops at ``max_steps`` env steps or ``max_wall_s``; the kept actor is the run's ``policy.onnx``, in
   Holosoma's ONNX format, of the architecture it started from (holosoma_inference's loader and the
   sim-to-sim evaluator read it).

Seeds: training episodes ``TRAIN_SEED_BASE + seed * 10**6 + i`` (worker ``w`` of ``W`` takes the ``i`` with
``i % W == w``); held-out selection's
``seed + SELECTION_SEED_OFFSET + i`` (the selection module's); both ranges are recorded in
``run_config.json`` so a comparison can stay apart from them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from econmotor.couriers.onnx_actor import ImportedActor, read_actor
from econmotor.couriers.onnx_export import export_onnx
from econmotor.couriers.policy_import import holosoma_export_metadata
from econmotor.economics import courier_formulas as cf
from econmotor.locomotion.conditions import WalkerSetup
from econmotor.locomotion.evaluation import WalkerEvaluation
from econmotor.locomotion.evaluation import evaluate as evaluate_walkers
from econmotor.locomotion.learning import PRIVILEGED_DIM
from econmotor.locomotion.model import WalkerModel
from econmotor.locomotion.stress import Stress
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.mujoco import walker_collect as wc
from econmotor.motor_backend.mujoco.walker_ppo import ActorCritic, WalkerPPO
from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig
from econmotor.motor_backend.selection import Selection
from econmotor.motor_backend.training_loop import Learner as LoopLearner
from econmotor.motor_backend.training_loop import StopFn, TrainingLoop, TrainingOutcome
from econmotor.objectives.economic_objective import EconomicObjectiveSpec

#: training episodes are seeded from here on (apart from selection's and a report's seeds)
TRAIN_SEED_BASE = 10_000_000
CHECKPOINT_FILE = "checkpoints/latest.pt"
CURVE_FILE = "curve.jsonl"
ONNX_FILE = "policy.onnx"
#: held-out selection steps this many robots together in each evaluator process
SELECT_SLOTS = 16
#: the actor a held-out look prices, exported into the run directory (overwritten at every look)
SELECTION_CANDIDATE = "selection/candidate.onnx"


@dataclass
class WalkerTrainingRun:
    """One training run of a card robot (module docstring)."""

    run_dir: Path
    setup: WalkerSetup
    cfg: WalkerPPOConfig
    objective: EconomicObjectiveSpec
    economics: Any
    gain: float
    weights: Mapping[str, float]
    params: Mapping[str, Mapping[str, Any]]
    seed: int
    max_steps: int
    init: ImportedActor | None = None
    max_wall_s: float = float("inf")
    checkpoint_every_s: float = 300.0
    selection: Selection | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)
    kp: np.ndarray | None = None
    kd: np.ndarray | None = None
    command_ranges: Mapping[str, Any] | None = None
    #: the conditions held-out selection's episodes alternate between (empty: the training's stress)
    select_stresses: tuple[Stress, ...] = ()
    #: worker processes that step the robots (1: in this process; None: :func:`.walker_collect.default_workers`)
    collect_workers: int | None = None
    #: processes a held-out look's episodes run in (None: every usable CPU: the collection is idle meanwhile)
    select_workers: int | None = None
    #: torch threads of the critic's values and the update (None: every usable CPU when collect workers wait for
    #: the update, one when they step beside it (``policy_lag: 1``), else the process's own setting)
    update_threads: int | None = None

    def __post_init__(self) -> None:
        card = self.setup.card
        self.kp = np.asarray(self.kp if self.kp is not None else card.kp, float)
        self.kd = np.asarray(self.kd if self.kd is not None else card.kd, float)
        self.command_ranges = dict(self.command_ranges or card.command_ranges)
        self.walker = WalkerModel.build(card, self.kp, self.kd)
        n = self.cfg.num_envs
        workers = wc.default_workers(n) if self.collect_workers is None else int(self.collect_workers)
        if not 1 <= workers <= n:
            raise ValueError(f"collect_workers must be between 1 and num_envs ({n}), got {workers}")
        self.collect_workers = workers
        if self.update_threads is None:
            beside = 1 if self.cfg.policy_lag else wc.usable_cpus()  # beside the workers: no thread to spare
            self.update_threads = beside if workers > 1 else torch.get_num_threads()

    # ------------------------------------------------------------------ the pieces
    def env_spec(self) -> wc.EnvSpec:
        """What the learning envs (this process's or the workers') are built from."""
        s = self.setup
        return wc.EnvSpec(s.card, self.kp, self.kd, s.course, s.meter, s.stress, s.episode_s,
                          dict(self.command_ranges), self.objective.to_dict(), self.economics, self.gain,
                          dict(self.weights), {k: dict(v) for k, v in self.params.items()}, self.cfg.j_pace)

    def collector(self, seeds: list[int], iteration: int) -> wc.LocalCollector | wc.CollectPool:
        """The run's collection (:mod:`.walker_collect`), each worker's next episode seed ``seeds``;
        ``iteration``: the iteration it starts at (seeds the workers' action generators)."""
        cfg, workers = self.cfg, int(self.collect_workers or 1)
        if workers == 1:
            return wc.LocalCollector(self.env_spec(), cfg.num_envs, seeds[0], cfg.steps_per_iteration,
                                     self.walker, self.noise_corr)
        rng_seeds = [wc.worker_rng_seed(self.seed, w, workers, iteration) for w in range(workers)]
        return wc.CollectPool(self.env_spec(), wc.split(cfg.num_envs, workers), seeds, rng_seeds,
                              cfg.steps_per_iteration, noise_corr=self.noise_corr)

    @property
    def noise_corr(self) -> float:
        """The exploration noise's correlation from one control step to the next: ``exp(-dt / noise_corr_s)``
        (0: white noise)."""
        tau = self.cfg.noise_corr_s
        return math.exp(-self.setup.card.control_dt_s / tau) if tau > 0 else 0.0

    def learner(self) -> WalkerPPO:
        card = self.setup.card
        if self.init is not None:
            net = ActorCritic.from_actor(self.init, PRIVILEGED_DIM, self.cfg)
        else:
            net = ActorCritic(card.obs_dim, PRIVILEGED_DIM, card.num_dofs, self.cfg)
        return WalkerPPO(net, self.cfg)

    # ------------------------------------------------------------------ the run
    def train(self, resume: bool = False, progress: ProgressFn = no_progress,
              config: Mapping[str, Any] | None = None,
              requested_hyperparameters: Mapping[str, Any] | None = None) -> TrainingOutcome:
        """Train to ``max_steps`` / ``max_wall_s`` in the shared loop (``config``: the run's description for
        ``run_config.json``); the kept actor is the run's ``policy.onnx``."""
        loop = TrainingLoop(self.run_dir, "mujoco", dict(config or {}), self.max_steps, max_wall_s=self.max_wall_s,
                            checkpoint_every_s=self.checkpoint_every_s, selection=self.selection,
                            curve_every_steps=1, requested_hyperparameters=requested_hyperparameters,
                            progress=progress)
        return loop.run(WalkerLearner(self), resume)

    def _curve_row(self, iteration: int, stats: Mapping[str, float], episodes: list[dict[str, Any]],
                   parts: Mapping[str, float], iteration_s: float, collect_s: float | None = None
                   ) -> dict[str, Any]:
        units = sum(ep["units_completed"] for ep in episodes)
        hours = sum(ep["episode_length_s"] for ep in episodes) / cf.SECONDS_PER_HOUR
        energy = sum(ep["energy_wh"] for ep in episodes)
        steps = self.cfg.num_envs * self.cfg.steps_per_iteration
        locomotion, economic = parts.get("locomotion", 0.0), parts.get("economic", 0.0)
        return {"iteration": iteration, "steps_per_s": round(steps / iteration_s, 1), "episodes": len(episodes),
                "falls": sum(ep["errors"] for ep in episodes),
                "legs_per_hour": units / hours if hours > 0 else None,
                "wh_per_leg": energy / units if units > 0 else None,
                "reward_locomotion": locomotion, "reward_economic": economic,
                "mean_return": locomotion + economic,  # the reward per control step of the iteration
                **({"j_pace_m_per_s": parts["pace_m_per_s"]} if "pace_m_per_s" in parts else {}),
                **({"collect_s": round(collect_s, 3)} if collect_s is not None else {}),
                **{k: float(v) for k, v in stats.items()}}

    # ------------------------------------------------------------------ selection
    def evaluate(self, learner: WalkerPPO, num_episodes: int, first_seed: int,
                 stop: Callable[[list[dict[str, Any]]], bool]) -> list[dict[str, Any]]:
        """``num_episodes`` held-out episodes of the priced course from the start (episode ``i`` seeded
        ``first_seed + i``, under ``select_stresses[i % len]``), asking ``stop`` after every look of
        ``selection.config.batch`` episodes, with the rows in episode order.

        The current actor is exported as the run exports its policy (:meth:`export`, into
        :data:`SELECTION_CANDIDATE`, overwritten at every look) and that file is priced by the one walker
        evaluator (:func:`econmotor.locomotion.evaluation.evaluate`, what a report and the evaluation after
        training run), on ``select_workers`` processes: a look's episodes are the episodes a report of that
        ONNX under the same seeds and conditions gives."""
        s = self.setup
        stresses = self.select_stresses or (s.stress,)
        candidate = self.run_dir / SELECTION_CANDIDATE
        candidate.parent.mkdir(parents=True, exist_ok=True)
        self.export(learner.net.network(), candidate)
        ev = WalkerEvaluation(policy=str(candidate), course=s.course, meter=s.meter, stress=stresses[0],
                              alternate=tuple(stresses[1:]), episode_s=s.episode_s, seed=int(first_seed),
                              slots=SELECT_SLOTS)
        look = self.selection.config.batch if self.selection is not None else num_episodes
        workers = wc.usable_cpus() if self.select_workers is None else int(self.select_workers)
        rows, _ = evaluate_walkers(ev, int(num_episodes), workers, stop=stop, batch=look)
        return rows

    def export(self, actor: Mapping[str, Any] | list[dict[str, np.ndarray]], path: Path) -> Path:
        """``path`` (a ``policy.onnx``) of ``actor`` (:func:`export_walker`: the actor's network, or an MLP's
        layers) with this run's gains and command ranges."""
        if not isinstance(actor, Mapping) and self.init is not None and self.init.architecture != "mlp":
            raise ValueError(f"a {self.init.architecture} actor is exported from its network, not its layers")
        return export_walker(actor, self.setup.card, self.kp, self.kd, self.command_ranges,
                             self.init.activation if self.init else self.cfg.activation, path, self.metadata)


def export_walker(actor: Mapping[str, Any] | list[dict[str, np.ndarray]], card: Any, kp: np.ndarray,
                  kd: np.ndarray, command_ranges: Mapping[str, Any], activation: str, path: Path,
                  metadata: Mapping[str, Any]) -> Path:
    """A walker's actor (its mean) in Holosoma's ONNX format: input ``actor_obs``, output ``action`` clipped to
    the card's bounds, the robot's export metadata with the gains and command ranges the env applied, and
    econmotor's entries (``metadata``). ``actor``: its network (``ActorCritic.network()``: the architecture
    with its arrays, FastSAC's normaliser, layer norms and tanh head included) or an MLP's layers
    (``[{"w", "b"}]``, with ``activation``)."""
    holosoma = holosoma_export_metadata(card)
    holosoma.update({"kp": [float(v) for v in kp], "kd": [float(v) for v in kd],
                     "command_ranges": {k: [float(x) for x in v] for k, v in command_ranges.items()}})
    bound = np.full(card.num_dofs, card.action_clip, np.float32)
    net = dict(actor) if isinstance(actor, Mapping) else {"layers": actor, "activation": activation}
    normaliser = (net["obs_mean"], net["obs_std"], net.get("clip_obs")) if net.get("obs_mean") is not None else None
    return export_onnx({"policy": net["layers"]}, None, 0.0, -bound, bound, path, dict(metadata),
                       activation=net["activation"], holosoma=holosoma, normaliser=normaliser,
                       obs_index=net.get("obs_index"), obs_dim=net.get("obs_dim"),
                       layer_norms=net.get("layer_norms") or (), layer_norm_eps=net.get("layer_norm_eps", 1e-5),
                       squash=net.get("squash"))


def _status(env_steps: int, row: Mapping[str, Any]) -> str:
    legs, wh = row["legs_per_hour"], row["wh_per_leg"]
    said = f"{env_steps / 1e6:.2f}M steps, {row['steps_per_s']:.0f}/s; episodes {row['episodes']}"
    if legs is not None:
        said += f" falls {row['falls']:g}; legs/h {legs:.1f}"
    if wh is not None:
        said += f", Wh/leg {wh:.2f}"
    return said + f"; kl {row['kl']:.4f} lr {row['learning_rate']:.1e}"


@contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """torch's intra-op threads set to ``n`` for the block, then back to what they were."""
    before = torch.get_num_threads()
    if n != before:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        if n != before:
            torch.set_num_threads(before)


class WalkerLearner(LoopLearner):
    """The walker PPO on the learner's env as the loop's learner (module docstring)."""

    policy_file = ONNX_FILE

    def __init__(self, run: WalkerTrainingRun) -> None:
        torch.manual_seed(run.seed)
        self.run, self.ppo = run, run.learner()
        self.chunk_steps = run.cfg.num_envs * run.cfg.steps_per_iteration
        self.env_steps, self.iteration = 0, 0
        self.workers = int(run.collect_workers or 1)
        #: each worker's next episode seed (worker w of W steps by W: walker_collect.first_seeds)
        self.next_seeds = wc.first_seeds(TRAIN_SEED_BASE + run.seed * 1_000_000, self.workers)
        self.collection: wc.LocalCollector | wc.CollectPool | None = None
        self.last: dict[str, Any] | None = None
        self.warm_start = run.init.source if run.init is not None else None

    def collect(self) -> tuple[Any, torch.Tensor, list[dict[str, Any]], dict[str, float]]:
        """One iteration's rollout under the current actor, its last values, the ended episodes and the
        reward's parts (:func:`.walker_collect.assemble`); the collection starts on the first call, from the
        next seeds (the start's, or the restored checkpoint's)."""
        if self.collection is None:
            self.collection = self.run.collector(self.next_seeds, self.iteration)
        if not self.collection.pending:
            self.collection.request(self.ppo.net)
        chunks = self.collection.receive()
        self.next_seeds = self.collection.next_seeds
        if self.run.cfg.policy_lag:  # the next batch under this actor, stepped while the update runs
            self.collection.request(self.ppo.net)
        with torch_threads(int(self.run.update_threads)):
            return wc.assemble(chunks, self.ppo.net, self.run.cfg.gamma)

    def learn(self, until_steps: int) -> dict[str, Any]:
        run = self.run
        while True:
            t0 = time.perf_counter()
            rollout, last_value, episodes, parts = self.collect()
            collect_s = time.perf_counter() - t0
            with torch_threads(int(run.update_threads)):
                stats = self.ppo.update(rollout, last_value)
            self.iteration += 1
            self.env_steps += self.chunk_steps
            self.last = run._curve_row(self.iteration, stats, episodes, parts, time.perf_counter() - t0, collect_s)
            if self.env_steps >= until_steps:
                return self.last

    def status(self) -> str:
        return _status(self.env_steps, self.last) if self.last is not None else ""

    def evaluate(self, num_episodes: int, first_seed: int, stop: StopFn) -> list[dict[str, Any]]:
        return self.run.evaluate(self.ppo, num_episodes, first_seed, stop)

    def save_checkpoint(self, run_dir: Path) -> None:
        path = run_dir / CHECKPOINT_FILE
        path.parent.mkdir(parents=True, exist_ok=True)
        record = {"learner": self.ppo.state_dict(),
                  "state": {"iteration": self.iteration, "env_steps": self.env_steps,
                            "next_seeds": list(self.next_seeds), "next_seed": max(self.next_seeds)}}
        tmp = path.with_suffix(".tmp")
        torch.save(record, tmp)
        tmp.replace(path)

    def load_checkpoint(self, run_dir: Path) -> int:
        path = run_dir / CHECKPOINT_FILE
        if not path.is_file():
            return 0
        record = torch.load(path, weights_only=False)
        self.ppo.load_state_dict(record["learner"])
        state = record["state"]
        self.iteration, self.env_steps = state["iteration"], state["env_steps"]
        # the workers' own next seeds for the same worker count; else after the highest of them
        self.next_seeds = wc.resumed_seeds(state.get("next_seeds") or [state["next_seed"]], self.workers)
        return self.env_steps

    def save_policy(self, directory: Path) -> None:
        self.run.export(self.ppo.net.network(), directory / ONNX_FILE)

    def load_policy(self, directory: Path) -> None:
        self.ppo.net.load_actor(read_actor(directory / ONNX_FILE).network())

    def export(self, run_dir: Path) -> Path:
        return self.run.export(self.ppo.net.network(), run_dir / ONNX_FILE)

    def timing(self) -> dict[str, Any]:
        return {"iterations": self.iteration, "collect_workers": self.workers,
                "update_threads": self.run.update_threads}

    def close(self) -> None:
        if self.collection is not None:
            self.collection.close()
            self.collection = None
