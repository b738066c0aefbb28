"""The walker trainer's collection: a run's robots stepped in this process or split across worker processes.

Each PPO iteration of :class:`~econmotor.motor_backend.mujoco.walker_training.WalkerTrainingRun` collects
``steps_per_iteration`` control steps of every robot, then updates in the trainer's process. Collection is a
:class:`LocalCollector` (``collect_workers: 1``: the run's one
:class:`~econmotor.locomotion.learning.WalkerLearningEnv` in this process, sampling with torch's global
generator, as the trainer always did) or a :class:`CollectPool` (``collect_workers: W > 1``), Sample Factory's
split of the work:

- ``W`` worker processes (``spawn``: no fork of a process whose threads run), worker ``w`` owning a learning
  env of its share of the robots (:func:`split`: as even as can be, the first ones one more);
- every iteration the trainer sends each worker the actor (its network, :meth:`ActorCritic.network`: the
  architecture with its arrays, and ``log_std``, NumPy; :func:`actor_weights`); the worker builds the same
  actor from the first (:func:`.walker_actor.actor_module`) and loads the arrays every iteration, samples the
  actions with its own torch generator, steps its robots and sends back its :class:`Chunk` (observations,
  privileged views, actions, log-probabilities, means, rewards, terminations and truncations, the truncated
  episodes' last observations, the ended episodes' raw metrics, the reward's parts, its next seed); every
  worker steps at once;
- the trainer (:func:`assemble`) concatenates the chunks along the robots' axis and computes the values, the
  truncations' bootstrap ``gamma * V(last observation)`` and the last values with the critic, each in one
  batched pass (the critic does not move during collection, so these are the values the single-process
  loop took step by step).

Seeds (a run is reproducible for a given worker count): worker ``w`` of ``W`` starts episodes seeded
``first + w, first + w + W, ...`` (:func:`first_seeds`: the run's training range, interleaved, so no two
workers share a seed and one worker's seeds are exactly the single-process run's); its actions are drawn from
a generator seeded by ``(run seed, w, W, the iteration the workers started at)``. The next seed of each worker
is what a checkpoint keeps (:meth:`CollectPool.next_seeds`); a run resumed with another worker count starts
its workers after the highest of them (:func:`resumed_seeds`).

A worker ends when the trainer's process does (:func:`econmotor.locomotion.evaluation.exit_with_parent`, the
pricing workers' watchdog); it ignores SIGINT (the trainer's Ctrl-C writes a checkpoint and then closes the
workers itself). A worker that fails or dies is a BackendError in the trainer.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import signal
import time
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from econmotor.errors import BackendError
from econmotor.locomotion.env import WalkerBatch
from econmotor.locomotion.evaluation import exit_with_parent
from econmotor.locomotion.learning import WalkerLearningEnv
from econmotor.locomotion.model import WalkerModel
from econmotor.locomotion.stress import Stress
from econmotor.motor_backend.mujoco.walker_actor import actor_module, load_network
from econmotor.motor_backend.mujoco.walker_ppo import ActorCritic, Rollout
from econmotor.objectives.economic_objective import EconomicObjectiveSpec

#: robots a worker steps at least by default: below that the control step's Python is no longer amortised
#: over its robots (the pricing workers: 0.69 of raw mj_step at 8 robots, 0.74 at 16)
MIN_DEFAULT_SLOTS = 8
#: seconds a worker may take over one iteration's chunk before the trainer gives up on it
CHUNK_TIMEOUT_S = 3600.0


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity where the platform says, else the machine's)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def default_workers(num_envs: int) -> int:
    """The collect workers a run gets by default: one per usable CPU, each with at least
    :data:`MIN_DEFAULT_SLOTS` robots (a small run stays in this process)."""
    return max(1, min(usable_cpus(), num_envs // MIN_DEFAULT_SLOTS))


def split(num_envs: int, workers: int) -> list[int]:
    """Robots per worker: ``num_envs`` as evenly as can be, the first workers one more."""
    base, extra = divmod(num_envs, workers)
    return [base + (w < extra) for w in range(workers)]


def first_seeds(first: int, workers: int) -> list[int]:
    """Each worker's first episode seed (worker ``w`` then steps by ``workers``): ``first + w``."""
    return [first + w for w in range(workers)]


def resumed_seeds(saved: Sequence[int], workers: int) -> list[int]:
    """The next seeds of ``workers`` workers from a checkpoint's ``saved`` ones: those, for the same count;
    else interleaved after the highest saved seed (none of them used by any saved worker yet)."""
    saved = [int(s) for s in saved]
    return saved if len(saved) == workers else first_seeds(max(saved), workers)


@dataclass(frozen=True)
class EnvSpec:
    """What a learning env is built from (pickled to each worker)."""

    card: Any
    kp: np.ndarray
    kd: np.ndarray
    course: Any
    meter: Any
    stress: Stress
    episode_s: float
    command_ranges: Mapping[str, Any]
    objective: Mapping[str, Any]  # the objective's to_dict() (its mapping proxy does not pickle)
    economics: Any
    gain: float
    weights: Mapping[str, float]
    params: Mapping[str, Mapping[str, Any]]
    pace: str = "course"  # the walking speed J's rates are taken at (WalkerLearningEnv)

    def build(self, slots: int, seed: int, seed_stride: int = 1, walker: WalkerModel | None = None
              ) -> WalkerLearningEnv:
        """A learning env of ``slots`` robots whose episodes are seeded ``seed, seed + seed_stride, ...``."""
        walker = walker or WalkerModel.build(self.card, self.kp, self.kd)
        batch = WalkerBatch(walker, self.course, self.meter, self.stress, self.episode_s, slots,
                            dict(self.command_ranges))
        objective = EconomicObjectiveSpec(**self.objective)
        return WalkerLearningEnv(batch, objective, self.economics, self.gain, self.weights, self.params,
                                 seed=seed, seed_stride=seed_stride, pace=self.pace)


@dataclass
class Chunk:
    """One env's ``T`` control steps of its ``n`` robots (``[T, n, ...]``), NumPy."""

    obs: np.ndarray
    privileged: np.ndarray
    actions: np.ndarray
    log_probs: np.ndarray
    means: np.ndarray
    rewards: np.ndarray  # float64, before the truncations' bootstrap
    terminated: np.ndarray  # bool: a fall
    truncated: np.ndarray  # bool: the course's end or the time limit
    truncated_at: np.ndarray  # flat indices ``t * n + i`` of the truncations, in order
    terminal_obs: np.ndarray  # [len(truncated_at), obs_dim]: their last observations
    terminal_privileged: np.ndarray
    last_obs: np.ndarray  # [n, obs_dim]: the observations after the last step
    last_privileged: np.ndarray
    episodes: list[dict[str, Any]] = field(default_factory=list)
    parts: dict[str, float] = field(default_factory=dict)  # the reward's parts: mean per robot and step
    next_seed: int = 0


class Noise:
    """Each robot's exploration noise, standard normal per joint: white (``corr`` 0, a fresh draw every step, as
    torch's ``randn`` gives it) or an AR(1) process, ``eps_t = corr eps_(t-1) + sqrt(1 - corr^2) xi_t`` (an
    Ornstein-Uhlenbeck process sampled at the control rate: a probe held for about ``1 / (1 - corr)`` steps,
    the marginal still standard normal, so the Gaussian's log-probabilities stay the policy's), started afresh
    with every episode (:meth:`restart`). ``generator`` None: torch's global one."""

    def __init__(self, corr: float = 0.0, generator: torch.Generator | None = None) -> None:
        if not 0.0 <= corr < 1.0:
            raise ValueError(f"noise correlation must be in [0, 1), got {corr}")
        self.corr, self.generator = float(corr), generator
        self.eps: torch.Tensor | None = None
        self.fresh: np.ndarray | None = None  # rows whose next draw starts a new process

    def draw(self, shape: torch.Size) -> torch.Tensor:
        xi = torch.randn(shape, generator=self.generator)
        if self.corr == 0.0:
            return xi
        if self.eps is None or self.eps.shape != xi.shape:
            self.eps, self.fresh = xi, None
            return xi
        eps = self.corr * self.eps + math.sqrt(1.0 - self.corr ** 2) * xi
        if self.fresh is not None and len(self.fresh):
            eps[self.fresh] = xi[self.fresh]
        self.eps, self.fresh = eps, None
        return eps

    def restart(self, ended: np.ndarray) -> None:
        """The robots where ``ended`` (a mask) start new episodes: their next draw is independent of the last."""
        if self.corr and ended.any():
            rows = np.flatnonzero(ended)
            self.fresh = rows if self.fresh is None else np.union1d(self.fresh, rows)


class Sampler:
    """The Gaussian actor's draws: ``obs -> (action, log_prob, mean)`` (NumPy in and out), its noise from
    ``noise`` (default: white, from torch's global generator, as :meth:`WalkerPPO.act` draws)."""

    def __init__(self, actor: torch.nn.Module, log_std: torch.Tensor, noise: Noise | None = None) -> None:
        self.actor, self.log_std, self.noise = actor, log_std, noise or Noise()

    @torch.no_grad()
    def __call__(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        mean = self.actor(torch.from_numpy(obs))
        std = self.log_std.exp()
        action = mean + std * self.noise.draw(mean.shape)
        log_prob = torch.distributions.Normal(mean, std).log_prob(action).sum(-1)
        return action.numpy(), log_prob.numpy(), mean.numpy()


def collect(env: WalkerLearningEnv, sample: Sampler, steps: int, obs: np.ndarray, priv: np.ndarray) -> Chunk:
    """``steps`` control steps of ``env``'s robots from ``obs``/``priv``, actions drawn by ``sample``."""
    n, dim, pdim = obs.shape[0], obs.shape[1], priv.shape[1]
    act_dim = env.batch.card.num_dofs
    c = Chunk(obs=np.zeros((steps, n, dim), np.float32), privileged=np.zeros((steps, n, pdim), np.float32),
              actions=np.zeros((steps, n, act_dim), np.float32), log_probs=np.zeros((steps, n), np.float32),
              means=np.zeros((steps, n, act_dim), np.float32), rewards=np.zeros((steps, n)),
              terminated=np.zeros((steps, n), bool), truncated=np.zeros((steps, n), bool),
              truncated_at=np.zeros(0, np.int64), terminal_obs=np.zeros((0, dim), np.float32),
              terminal_privileged=np.zeros((0, pdim), np.float32), last_obs=obs, last_privileged=priv)
    at, terminal_obs, terminal_priv = [], [], []
    for t in range(steps):
        c.obs[t], c.privileged[t] = obs, priv
        c.actions[t], c.log_probs[t], c.means[t] = sample(obs)
        out = env.step(c.actions[t])
        c.rewards[t], c.terminated[t], c.truncated[t] = out.reward, out.terminated, out.truncated
        sample.noise.restart(out.terminated | out.truncated)
        rows = np.flatnonzero(out.truncated)
        if len(rows):
            at.append(t * n + rows)
            terminal_obs.append(out.terminal_obs[rows])
            terminal_priv.append(out.terminal_privileged[rows])
        c.episodes += out.episodes
        for k, v in out.terms.items():
            c.parts[k] = c.parts.get(k, 0.0) + v / steps
        obs, priv = out.obs, out.privileged
    if at:
        c.truncated_at = np.concatenate(at)
        c.terminal_obs, c.terminal_privileged = np.concatenate(terminal_obs), np.concatenate(terminal_priv)
    c.last_obs, c.last_privileged, c.next_seed = obs, priv, env.next_seed
    return c


@torch.no_grad()
def assemble(chunks: Sequence[Chunk], net: ActorCritic, gamma: float
             ) -> tuple[Rollout, torch.Tensor, list[dict[str, Any]], dict[str, float]]:
    """The iteration's rollout ``[T, N, ...]`` from the envs' chunks (in order along the robots' axis), its last
    values, the ended episodes and the reward's parts (module docstring: the critic's passes)."""
    cat = lambda name: torch.from_numpy(np.concatenate([getattr(c, name) for c in chunks], axis=1))
    obs, priv = cat("obs"), cat("privileged")
    steps, total = obs.shape[:2]
    values = net.value(obs.reshape(steps * total, -1), priv.reshape(steps * total, -1)).reshape(steps, total)
    rewards = cat("rewards")
    sizes = [c.obs.shape[1] for c in chunks]
    offsets = np.cumsum([0, *sizes[:-1]])
    rows = [(c.truncated_at // n, c.truncated_at % n + o) for c, n, o in zip(chunks, sizes, offsets, strict=True)]
    t_rows, n_rows = (np.concatenate(x) for x in zip(*rows, strict=True))
    if len(t_rows):
        terminal = net.value(torch.from_numpy(np.concatenate([c.terminal_obs for c in chunks])),
                             torch.from_numpy(np.concatenate([c.terminal_privileged for c in chunks])))
        rewards[t_rows, n_rows] += gamma * terminal.double()
    last_value = net.value(torch.from_numpy(np.concatenate([c.last_obs for c in chunks])),
                           torch.from_numpy(np.concatenate([c.last_privileged for c in chunks])))
    rollout = Rollout(obs=obs, privileged=priv, actions=cat("actions"), log_probs=cat("log_probs"),
                      means=cat("means"), values=values, rewards=rewards.float(),
                      dones=(cat("terminated") | cat("truncated")).float())
    parts: dict[str, float] = {}
    for c, n in zip(chunks, sizes, strict=True):
        for k, v in c.parts.items():
            parts[k] = parts.get(k, 0.0) + v * n / total
    return rollout, last_value, [ep for c in chunks for ep in c.episodes], parts


def actor_weights(net: ActorCritic) -> dict[str, Any]:
    """What a worker needs of the actor: its network (architecture and arrays) and ``log_std`` (NumPy)."""
    return {"network": net.network(), "log_std": net.log_std.detach().numpy().copy()}


class LocalCollector:
    """Collection in this process: one learning env of every robot, torch's global generator (its noise
    correlated step to step by ``noise_corr``: :class:`Noise`)."""

    workers = 1

    def __init__(self, spec: EnvSpec, num_envs: int, seed: int, steps: int, walker: WalkerModel | None = None,
                 noise_corr: float = 0.0) -> None:
        self.env = spec.build(num_envs, seed, 1, walker)
        self.steps = steps
        self.noise = Noise(noise_corr)
        self.obs = self.env.reset()
        self._pending: list[Chunk] | None = None

    def request(self, net: ActorCritic) -> None:
        """Collect the next chunk under ``net``'s actor now (this process has no other worker to do it)."""
        chunk = collect(self.env, Sampler(net.actor, net.log_std.detach(), self.noise), self.steps, *self.obs)
        self.obs = (chunk.last_obs, chunk.last_privileged)
        self._pending = [chunk]

    def receive(self) -> list[Chunk]:
        chunks, self._pending = self._pending, None
        if chunks is None:
            raise RuntimeError("receive() before request()")
        return chunks

    @property
    def pending(self) -> bool:
        return self._pending is not None

    @property
    def next_seeds(self) -> list[int]:
        return [self.env.next_seed]

    def close(self) -> None:
        self.env.close()


def _worker(conn: Any, spec: EnvSpec, slots: int, seed: int, stride: int, rng_seed: int, steps: int,
            noise_corr: float = 0.0) -> None:
    """A collect worker: builds its env, then answers ``("collect", actor_weights)`` with ``("chunk", Chunk)``
    until ``("close", None)`` or the trainer's end; a failure is ``("error", traceback)``."""
    exit_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    torch.set_num_threads(1)
    env = None
    try:
        env = spec.build(slots, seed, stride)
        obs = env.reset()
        noise = Noise(noise_corr, torch.Generator().manual_seed(rng_seed))
        actor: torch.nn.Module | None = None
        while True:
            kind, weights = conn.recv()
            if kind != "collect":
                break
            if actor is None:
                actor = actor_module(weights["network"]).requires_grad_(False)
            else:
                load_network(actor, weights["network"])
            sample = Sampler(actor, torch.from_numpy(weights["log_std"]), noise)
            chunk = collect(env, sample, steps, *obs)
            obs = (chunk.last_obs, chunk.last_privileged)
            conn.send(("chunk", chunk))
    except EOFError:  # the trainer closed its end
        pass
    except BaseException:
        try:
            conn.send(("error", traceback.format_exc()))
        except OSError:
            pass
    finally:
        if env is not None:
            env.close()


def worker_rng_seed(run_seed: int, worker: int, workers: int, iteration: int) -> int:
    """The seed of worker ``worker``'s action generator (of ``workers``, started at ``iteration``)."""
    return int(np.random.SeedSequence([int(run_seed), worker, workers, int(iteration)]).generate_state(1)[0])


class CollectPool:
    """Collection in ``len(seeds)`` spawned worker processes (module docstring).

    Args:
        spec: the env each worker builds; ``sizes``: robots per worker; ``seeds``: each worker's next episode
            seed (it then steps by the worker count); ``rng_seeds``: each worker's action generator's seed;
        steps: control steps per chunk; ``noise_corr``: the exploration noise's step-to-step correlation
            (:class:`Noise`).
    """

    def __init__(self, spec: EnvSpec, sizes: Sequence[int], seeds: Sequence[int], rng_seeds: Sequence[int],
                 steps: int, chunk_timeout_s: float = CHUNK_TIMEOUT_S, noise_corr: float = 0.0) -> None:
        ctx = mp.get_context("spawn")
        self.workers, self.timeout_s = len(sizes), float(chunk_timeout_s)
        self._seeds = [int(s) for s in seeds]
        self._in_flight = False  # chunks asked for and not all received (close then terminates at once)
        self.conns: list[Any] = []
        self.procs: list[Any] = []
        try:
            for w, (n, seed, rng_seed) in enumerate(zip(sizes, seeds, rng_seeds, strict=True)):
                mine, theirs = ctx.Pipe()
                args = (theirs, spec, n, seed, self.workers, rng_seed, steps, noise_corr)
                proc = ctx.Process(target=_worker, args=args, daemon=True, name=f"econmotor-collect-{w}")
                self.conns.append(mine)
                self.procs.append(proc)
                proc.start()
                theirs.close()
        except BaseException:
            self.close()
            raise

    @property
    def next_seeds(self) -> list[int]:
        return list(self._seeds)

    def request(self, net: ActorCritic) -> None:
        """Ask every worker for its next chunk under ``net``'s actor (they step at once, while this process goes
        on: :meth:`receive` waits for them)."""
        weights = actor_weights(net)
        self._in_flight = True
        for w, conn in enumerate(self.conns):
            try:
                conn.send(("collect", weights))
            except OSError:  # it is gone: its error, or how it died
                self._receive(w)
                raise BackendError(f"walker collect worker {w} stopped reading") from None

    @property
    def pending(self) -> bool:
        return self._in_flight

    def receive(self) -> list[Chunk]:
        """The chunks asked for by :meth:`request`, in the workers' order."""
        if not self._in_flight:
            raise RuntimeError("receive() before request()")
        chunks = [self._receive(w) for w in range(self.workers)]
        self._in_flight = False
        self._seeds = [c.next_seed for c in chunks]
        return chunks

    def _receive(self, w: int) -> Chunk:
        conn, proc, start = self.conns[w], self.procs[w], time.monotonic()
        while not conn.poll(1.0):
            if not proc.is_alive():
                raise BackendError(f"walker collect worker {w} died: exit code {proc.exitcode}")
            if time.monotonic() - start > self.timeout_s:
                raise BackendError(f"walker collect worker {w} sent nothing for {self.timeout_s:.0f} s")
        try:
            kind, payload = conn.recv()
        except EOFError:
            proc.join(timeout=5)
            raise BackendError(f"walker collect worker {w} died: exit code {proc.exitcode}") from None
        if kind == "error":
            raise BackendError(f"walker collect worker {w} failed:\n{payload}")
        return payload

    def close(self) -> None:
        """Stop the workers: asked to between chunks, terminated during one (nothing reads it any more), killed
        if that fails."""
        for conn in self.conns if not self._in_flight else []:
            try:
                conn.send(("close", None))
            except (OSError, ValueError):
                pass
        for proc in (p for p in self.procs if p.pid is not None):
            proc.join(timeout=0 if self._in_flight else 5)
            if proc.is_alive():
                proc.terminate()
                proc.join(timeout=5)
            if proc.is_alive():
                proc.kill()
                proc.join()
        for conn in self.conns:
            conn.close()
        self.conns, self.procs = [], []
