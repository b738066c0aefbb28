"""Evaluation-driven training: held-out evaluations judged like the report, and the checkpoint to keep.

Every ``every_steps`` environment steps a backend's trainer evaluates its current policy on
``episodes`` deterministic held-out episodes (episode i reset with seed ``seed +
SELECTION_SEED_OFFSET + i``: the same episodes for every checkpoint of a run, apart from
training's seeds, from the post-training evaluation's ``seed + 10,000`` and from the report's
``seed + 1,000``) and hands the raw episodes to :meth:`Selection.consider`, which

- judges them with the report's own judgement (:func:`econmotor.economics.uncertainty.judge`:
  the task's acceptance rule, ``decide``, on the same intervals), and scores them by the
  objective's own J, its energy term included (the mean of the report's
  :func:`econmotor.objectives.loader.objective_j` over the episodes);
- says whether the policy is the best so far: an acceptable policy beats any that is not,
  then the higher J wins; the trainer then saves it as the run's policy;
- with ``until_deployable``, asks the trainer to stop at the first acceptable evaluation.

A run that starts from a policy (a learner's ``warm_start``: ``--init-policy``) evaluates that policy
first, at env step 0, on the same held-out episodes: a fine-tune keeps a checkpoint only when it beats
the walker it started from, and its looks read as a curve from there.

Each held-out evaluation is sequential (:mod:`econmotor.motor_backend.sequential`, the rule the
report's evaluation follows): its episodes run in the backend's batches and are judged after every
batch (the fall rate by its confidence sequence, the bootstrap bounds at the plan's look confidence),
until the rule is decided: pass, fail
(a bound certainly outside its limit, or no way to pass by ``episodes``, the cap), or the cap. So
early checkpoints that fall in most episodes cost one batch each, and a passing one only the
episodes its verdict needs.

When held-out evaluations come (:meth:`Selection.due`): every ``every_steps`` env steps and, by
default, only once the training since the last evaluation is at least ``(1 - max_share) / max_share``
times that evaluation's cost, so they take at most ``max_share`` of the run's wall time (the
backend's declared :class:`~econmotor.motor_backend.capabilities.HeldOutCadence`); an explicit
``--select-every`` drops the share rule, so the cadence is exactly every ``every_steps`` steps.

The report's verdict comes from a separate evaluation on fresh seeds, so it is not selected
on its own data. :meth:`Selection.record` is what the run's ``run_config.json`` keeps under
``selection`` (rewritten after every evaluation, and restored by :meth:`Selection.restore` when the
run is resumed): every evaluation, the checkpoint kept and why, when the run became deployable
(env steps, wall seconds) and what the evaluations cost.

Backend-agnostic: it sees raw-metric episode dicts (``base.py``'s keys) and two callables.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from econmotor.economics.sequential_rule import SequentialPlan
from econmotor.economics.uncertainty import CONFIDENCE
from econmotor.errors import ConfigError
from econmotor.motor_backend.run_dir import SELECTION_SEED_OFFSET
from econmotor.motor_backend.sequential import FAIL, Judged, SequentialEvaluation, judge_raw
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.objectives.loader import objective_j

#: the defaults: a held-out evaluation at most every 25k env steps (a courier's PPO improves over
#: ~10^5 steps); at most 160 episodes each (a sequential evaluation's cap: 0 falls in ~136 legs pass a
#: 5% limit at the plan's look confidence, 99%, at the look of 128 episodes), batches of 16.
DEFAULT_SELECT_EVERY = 25_000
DEFAULT_SELECT_EPISODES = 160
DEFAULT_SELECT_BATCH = 16

#: ``evaluate(num_episodes, first_seed, stop) -> raw episodes``; the backend calls ``stop(rows so far)``
#: whenever a batch of episodes has ended and ends the evaluation when it returns True.
EvaluateFn = Callable[[int, int, Callable[[list[dict[str, Any]]], bool]], list[dict[str, Any]]]


@dataclass(frozen=True)
class SelectionConfig:
    """How a run selects its policy.

    Attributes:
        every_steps: environment steps between held-out evaluations (all envs together), at least.
        episodes: the cap on deterministic episodes per held-out evaluation (a sequential evaluation
            stops as soon as its verdict is decided).
        until_deployable: stop training at the first evaluation that passes the acceptance rule.
        seed: the run's seed (held-out seeds start at ``seed + SELECTION_SEED_OFFSET``).
        batch: episodes of a held-out evaluation's first look (the backend's evaluation batch).
        max_share: evaluate only while the evaluations so far cost at most this share of the run's wall
            time (None: exactly every ``every_steps``).
    """

    every_steps: int = DEFAULT_SELECT_EVERY
    episodes: int = DEFAULT_SELECT_EPISODES
    until_deployable: bool = False
    seed: int = 0
    batch: int = DEFAULT_SELECT_BATCH
    max_share: float | None = None

    def __post_init__(self) -> None:
        if self.every_steps < 1 or self.episodes < 1:
            raise ConfigError("<selection>", "every_steps/episodes", "must be >= 1")
        if self.max_share is not None and not 0 < self.max_share <= 1:
            raise ConfigError("<selection>", "max_share", "must be in (0, 1]")

    @property
    def plan(self) -> SequentialPlan:
        """The sequential plan of one held-out evaluation (a first look no larger than the cap)."""
        return SequentialPlan(batch=min(self.batch, self.episodes), max_episodes=self.episodes)

    @property
    def first_seed(self) -> int:
        return self.seed + SELECTION_SEED_OFFSET


@dataclass(frozen=True)
class HeldOutResult:
    """One held-out evaluation of the policy at ``env_steps``.

    ``fall_rate_upper`` is the 95% upper bound on the error rate (falls / attempted legs for the
    couriers), ``units_per_hour`` the point throughput and ``units_per_hour_low`` its 95% lower
    bound, ``j_mean`` the mean episode J under the run's objective; ``cut_short`` is True when the
    evaluation stopped before ``episodes_planned`` (its cap); ``outcome`` is the sequential evaluation's
    (pass, fail, episode cap, time cap) and ``why`` its reason. Bounds are at the look confidence.
    """

    env_steps: int
    wall_s: float
    eval_s: float
    episodes: int
    episodes_planned: int
    cut_short: bool
    deployable: bool
    j_mean: float
    fall_rate_upper: float
    units_per_hour: float
    units_per_hour_low: float
    errors: float
    eval_env_steps: int = 0
    reasons: tuple[str, ...] = ()
    outcome: str = ""
    why: str = ""
    #: it ran in a thread beside training (its seconds were not taken from training)
    beside_training: bool = False
    energy_wh_per_unit: float | None = None
    price_usd_per_unit: float | None = None

    def status(self) -> str:
        """One short line for a progress bar: ``'@120k: deployable'`` / ``'@40k: falls<=0.31'``."""
        at = f"@{self.env_steps / 1000:.0f}k"
        if self.deployable:
            return f"{at}: deployable"
        return f"{at}: not deployable (fall rate<={self.fall_rate_upper:.2f})"

    def to_dict(self) -> dict[str, Any]:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}

    def scalars(self) -> dict[str, float]:
        """The TensorBoard scalars of this evaluation (``held_out/...``)."""
        return {"held_out/fall_rate_upper95": self.fall_rate_upper, "held_out/units_per_hour": self.units_per_hour,
                "held_out/units_per_hour_low95": self.units_per_hour_low, "held_out/J": self.j_mean,
                "held_out/deployable": float(self.deployable), "held_out/eval_s": self.eval_s,
                **({"held_out/energy_wh_per_unit": self.energy_wh_per_unit}
                   if self.energy_wh_per_unit is not None else {})}


@dataclass
class Selection:
    """The held-out evaluations of one run and the best policy among them (module docstring)."""

    task: Any  # a TaskSpec: economics, acceptance, unit
    objective: EconomicObjectiveSpec
    config: SelectionConfig
    history: list[HeldOutResult] = field(default_factory=list)
    best: HeldOutResult | None = None
    started: float = field(default_factory=time.perf_counter)

    # --- the judgement -------------------------------------------------------------------------
    def judge(self, raw_episodes: Sequence[Mapping[str, Any]], confidence: float = CONFIDENCE,
              sequential: bool = False) -> tuple[Any, Any, float]:
        """``(Uncertainty, Verdict, mean J)`` of raw episodes: the report's judgement (every bound at
        ``confidence``; ``sequential``: a look of a held-out evaluation, its error rate by the confidence
        sequence at the plan's confidence) and the objective's J."""
        return self._scored(judge_raw(self.task, raw_episodes, confidence, sequential,
                                      sequence_confidence=self.config.plan.confidence))

    def _scored(self, judged: Judged) -> tuple[Any, Any, float]:
        """``(Uncertainty, Verdict, mean J)`` of a judgement made already."""
        js = [objective_j(self.objective, ep, self.task.economics) for ep in judged.summaries]
        return judged.uncertainty, judged.verdict, (sum(js) / len(js) if js else -math.inf)

    def consider(self, env_steps: int, evaluate: EvaluateFn) -> tuple[HeldOutResult, bool]:
        """Run one sequential held-out evaluation of the current policy; ``(result, is the best so far)``."""
        result = self.assess(env_steps, evaluate)
        return result, self.admit(result)

    def assess(self, env_steps: int, evaluate: EvaluateFn, beside_training: bool = False) -> HeldOutResult:
        """One sequential held-out evaluation of the policy at ``env_steps``, judged; the selection is left as
        it is (:meth:`admit` enters the result), so it may run in a thread beside training (``beside_training``:
        it does, and the result says so)."""
        t0 = time.perf_counter()
        run = SequentialEvaluation(self.task, self.config.plan)
        rows = run.finish(evaluate(self.config.episodes, self.config.first_seed, run.stop))
        if run.judged is None:
            raise ValueError(f"a held-out evaluation returned {len(rows)} episodes, fewer than its first look "
                             f"({run.plan.looks[0]})")
        # the deciding look judged exactly these episodes (the first decided_at): its judgement is the evaluation's
        uncertainty, verdict, j_mean = self._scored(run.judged)
        errors, mpl = uncertainty.intervals["error_rate"], uncertainty.intervals["mpl_units_per_hour"]
        pooled = run.judged.pricing.aggregate
        per_unit = pooled.mpl_units_per_hour > 0 and math.isfinite(pooled.price_usd_per_unit)
        result = HeldOutResult(
            env_steps=int(env_steps), wall_s=round(time.perf_counter() - self.started, 3),
            eval_s=round(time.perf_counter() - t0, 3), episodes=len(rows), episodes_planned=self.config.episodes,
            cut_short=len(rows) < self.config.episodes, deployable=run.passed, j_mean=float(j_mean),
            fall_rate_upper=float(errors.high), units_per_hour=float(mpl.point), units_per_hour_low=float(mpl.low),
            errors=float(uncertainty.evidence.errors),
            eval_env_steps=int(sum(float(r.get("length_steps", 0.0)) for r in rows)),
            reasons=tuple(verdict.reasons) if not run.passed else (),
            outcome=str(run.outcome), why=run.why if run.outcome == FAIL or not run.passed else "",
            beside_training=beside_training,
            energy_wh_per_unit=1000.0 * pooled.energy_kwh_per_hour / pooled.mpl_units_per_hour if per_unit else None,
            price_usd_per_unit=float(pooled.price_usd_per_unit) if per_unit else None)
        return result

    def admit(self, result: HeldOutResult) -> bool:
        """Enter an assessed evaluation (in the order they were taken); True when it is the best so far."""
        self.history.append(result)
        better = self.best is None or (result.deployable, result.j_mean) > (self.best.deployable, self.best.j_mean)
        if better:
            self.best = result
        return better

    def restore(self, record: Mapping[str, Any] | None) -> None:
        """Continue a resumed run's selection from its recorded ``selection`` (evaluations and the kept one),
        so a checkpoint kept before the interruption is only replaced by a better one."""
        if not record:
            return
        fields_ = HeldOutResult.__dataclass_fields__
        load = lambda d: HeldOutResult(**{k: (tuple(v) if k == "reasons" else v) for k, v in d.items() if k in fields_})
        self.history = [load(d) for d in record.get("evaluations") or []]
        self.best = load(record["kept"]) if record.get("kept") else None

    # --- what the trainer asks --------------------------------------------------------------
    def due(self, env_steps: int, last_env_steps: int, now: float | None = None) -> bool:
        """An evaluation is due when ``env_steps`` crossed a multiple of ``every_steps`` since the last one
        and, with ``max_share``, the wall time since the last evaluation ended is at least
        ``(1 - max_share) / max_share`` times what it cost, so evaluations take at most ``max_share`` of
        the run after the first (``now``: ``time.perf_counter()`` unless given)."""
        every = self.config.every_steps
        if env_steps // every <= last_env_steps // every:
            return False
        if self.config.max_share is None or not self.history:
            return True
        # the training since the last evaluation pays for it: at least (1 - share) / share times its cost
        # (measured from the last evaluation, so a long compile before it buys no burst of evaluations)
        share, last = self.config.max_share, self.history[-1]
        since = (time.perf_counter() if now is None else now) - (self.started + last.wall_s)
        return since * share >= (1.0 - share) * last.eval_s

    @property
    def evaluation_s(self) -> float:
        """Wall seconds the held-out evaluations of this run have cost so far."""
        return sum(r.eval_s for r in self.history)

    def final_due(self, env_steps: int, last_env_steps: int) -> bool:
        """Evaluate the last weights too at the end of training: unless they were just evaluated, or training
        stopped deployable, or the run was shorter than one interval (no evaluation ran: the last weights
        are kept unjudged, so a short run pays nothing) and was not asked to run until deployable."""
        return (env_steps != last_env_steps and not self.should_stop
                and (bool(self.history) or self.config.until_deployable))

    @property
    def deployable_at(self) -> HeldOutResult | None:
        """The first held-out evaluation that passed, or None."""
        return next((r for r in self.history if r.deployable), None)

    @property
    def should_stop(self) -> bool:
        return self.config.until_deployable and self.deployable_at is not None

    def status(self) -> str:
        """The latest verdict for the progress bar (empty before the first evaluation)."""
        return self.history[-1].status() if self.history else ""

    def kept_reason(self) -> str:
        """Which policy the run keeps and why, in words."""
        best = self.best
        if best is None:
            return "no held-out evaluation ran: the last weights are kept"
        what = (f"the checkpoint at {best.env_steps:,} env steps" if best.env_steps else
                "the policy the run started from (its look at env step 0: no later look beat it)")
        if best.deployable:
            if self.config.until_deployable:
                return (f"{what}: the first to pass the task's acceptance rule on {best.episodes} held-out "
                        "episodes (training stopped once that was known: --until-deployable)")
            return (f"{what}: the best J ({best.j_mean:.4g}) of the {sum(r.deployable for r in self.history)} "
                    f"held-out evaluations that passed the task's acceptance rule (of {len(self.history)})")
        return (f"{what}: none of {len(self.history)} held-out evaluations passed the task's acceptance rule, "
                f"so the best by J ({best.j_mean:.4g}) is kept; it is not deployable on held-out episodes")

    def record(self) -> dict[str, Any]:
        """The run record's ``selection`` entry (module docstring)."""
        cfg, first = self.config, self.deployable_at
        return {
            "every_steps": cfg.every_steps, "episodes": cfg.episodes, "until_deployable": cfg.until_deployable,
            "max_share": cfg.max_share, "sequential": cfg.plan.to_dict(),
            "seeds": [cfg.first_seed, cfg.first_seed + cfg.episodes],
            "judged_by": "economics.uncertainty.judge (the report's acceptance rule) at each look of a sequential "
                         "evaluation (motor_backend/sequential.py), J = mean episode_j",
            "evaluations": [r.to_dict() for r in self.history],
            "kept": self.best.to_dict() if self.best is not None else None,
            "kept_acceptable": bool(self.best and self.best.deployable),
            "why": self.kept_reason(),
            "became_deployable": ({"env_steps": first.env_steps, "wall_s": first.wall_s} if first else None),
            "evaluation_cost": {"count": len(self.history), "episodes": sum(r.episodes for r in self.history),
                                "env_steps": sum(r.eval_env_steps for r in self.history),
                                "wall_s": round(self.evaluation_s, 3),
                                "beside_training": sum(r.beside_training for r in self.history)},
        }


def fit_to_run(selection: Selection | None, max_steps: int, episode_steps: int, eval_episodes: int,
               say: Callable[[str], Any]) -> Selection | None:
    """Bound a run's evaluations by its size, each bound ``say``-d before the run starts: the selection to use.

    Costs are in env steps, the unit of ``max_steps``: a look (one batch of ``selection.config.batch`` episodes of up
    to ``episode_steps`` control steps) and the evaluation after training (``eval_episodes`` such episodes). A
    default cadence (``max_share``: held-out evaluations at most that share of the run) that cannot afford one look
    in ``max_steps`` runs none, as a run shorter than one interval (the last weights are kept): otherwise a short
    run asked of a whole-course task (the G1's 240 s episodes: 16 x 12,000 steps a look) spent minutes on each
    look it started. An explicit ``--select-every`` or ``--until-deployable`` is kept as asked. An evaluation
    after training that walks more steps than the training is announced with how to skip it."""
    if selection is not None and selection.config.max_share is not None and not selection.config.until_deployable:
        share, look = selection.config.max_share, selection.config.batch * episode_steps
        if look * share > (1.0 - share) * max_steps:
            say(f"no held-out selection: one look ({selection.config.batch} episodes of up to "
                         f"{episode_steps:,} control steps, {look:,} env steps) is more than {share:.0%} of this "
                         f"{max_steps:,}-step run, so the last weights are kept; --select-every N asks for them")
            selection = None
    walked = eval_episodes * episode_steps
    if walked > max_steps:
        say(f"after training, the evaluation walks {eval_episodes} episode(s) of up to {episode_steps:,} "
                     f"control steps: up to {walked:,} env steps, {walked / max_steps:.3g}x the {max_steps:,} "
                     "trained; --eval-episodes 0 skips it")
    return selection


def evaluation_cost_text(cost: Mapping[str, Any]) -> str:
    """A record's ``evaluation_cost`` in words: what the held-out evaluations cost the run, or, for those that ran
    beside training, how long they ran (training went on meanwhile)."""
    count, wall_s, beside = int(cost["count"]), float(cost["wall_s"]), int(cost.get("beside_training") or 0)
    if not beside:
        return f"{count} held-out evaluations cost {wall_s:.0f} s"
    which = "all" if beside == count else f"{beside} of them"
    return f"{count} held-out evaluations took {wall_s:.0f} s, {which} beside training"


def selection_for(task: Any, objective: EconomicObjectiveSpec, every_steps: int | None, episodes: int | None,
                  until_deployable: bool, seed: int, cadence: Any = None, batch: int = DEFAULT_SELECT_BATCH
                  ) -> Selection | None:
    """A backend's :class:`Selection` from its ``train_policy`` arguments; None when ``every_steps``
    is 0 (no held-out evaluations: the last weights are kept). ``until_deployable`` needs them.

    ``every_steps`` None: the backend's ``cadence`` (a :class:`~econmotor.motor_backend.capabilities.HeldOutCadence`;
    its steps and its share of wall time), else exactly every ``every_steps``. ``episodes`` None: the
    default cap. ``batch``: the backend's evaluation batch (the first look)."""
    if every_steps is None:
        every, share = (cadence.every_steps, cadence.max_share) if cadence is not None else (DEFAULT_SELECT_EVERY, None)
    else:
        every, share = int(every_steps), None
    if every <= 0:
        if until_deployable:
            raise ConfigError("<train>", "until_deployable", "needs held-out evaluations (select_every_steps > 0)")
        return None
    return Selection(task, objective, SelectionConfig(every, int(episodes or DEFAULT_SELECT_EPISODES),
                                                      bool(until_deployable), int(seed), int(batch), share))
