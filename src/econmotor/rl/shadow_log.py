"""ShadowRecorder: the shadow-mode log (JSONL per episode, a summary JSON, a plot).

Per step it feeds both rewards into a :class:`RunningCorrelation`; per episode it
feeds the two episode sums into another (and the legacy sum against the
episode J, the RewardBuilder scalarisation of the episode summary, into a third) and
writes one JSON line with the episode's
record (both sums, per-term totals, episode J, econ summary, constraint state) plus
the running correlations: step Pearson over all steps (exact, streaming), step
Spearman over the last ``window`` steps, episode Pearson and Spearman over all
episodes. :meth:`ShadowRecorder.finish` writes ``shadow_summary.json`` (with the
step Spearman over *all* steps) and ``shadow_plot.png``: a scatter of the episode
sums and the rolling correlations against episodes.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.rl.correlation import RunningCorrelation

EPISODES_FILE = "shadow_episodes.jsonl"
SUMMARY_FILE = "shadow_summary.json"
PLOT_FILE = "shadow_plot.png"


def json_safe(value: Any) -> Any:
    """Non-finite floats -> None, numpy scalars -> Python, recursively (strict JSON)."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class ShadowRecorder:
    """Collect the shadow statistics of a run; write them under ``out_dir`` (None: memory only).

    Args:
        out_dir: where the JSONL, summary and plot go; ``None`` keeps everything in memory.
        window: steps in the rolling step-level Spearman of each episode line.
    """

    def __init__(self, out_dir: str | Path | None = None, window: int = 4096) -> None:
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.window = int(window)
        self.steps = RunningCorrelation(capacity=4096)
        self.episodes = RunningCorrelation(capacity=256)
        self.episode_j = RunningCorrelation(capacity=256)
        self.records: list[dict[str, Any]] = []
        self._file = None
        if self.out_dir is not None:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            self._file = open(self.out_dir / EPISODES_FILE, "w", encoding="utf-8")

    def add_step(self, legacy: float, objective: float) -> None:
        self.steps.add(legacy, objective)

    def end_episode(self, record: dict[str, Any]) -> dict[str, Any]:
        """Add the running correlations to ``record``, keep it and write its JSON line."""
        self.episodes.add(record["legacy_sum"], record["objective_sum"])
        self.episode_j.add(record["legacy_sum"], record["episode_J"])
        record["correlation"] = {
            "step_pearson": self.steps.pearson(),
            "step_spearman_window": self.steps.spearman(self.window),
            "episode_pearson": self.episodes.pearson(),
            "episode_spearman": self.episodes.spearman(),
            "legacy_vs_J_pearson": self.episode_j.pearson(),
            "legacy_vs_J_spearman": self.episode_j.spearman(),
            "steps_so_far": self.steps.count,
        }
        record = json_safe(record)
        self.records.append(record)
        if self._file is not None:
            self._file.write(json.dumps(record) + "\n")
            self._file.flush()
        return record

    def summary(self) -> dict[str, Any]:
        """Run totals: correlations over all steps and episodes, mean sums, last constraint state."""
        recs = self.records
        mean = lambda key: float(np.mean([r[key] for r in recs])) if recs else math.nan
        out: dict[str, Any] = {
            "steps": self.steps.count,
            "episodes": len(recs),
            "step_pearson": self.steps.pearson(),
            "step_spearman": self.steps.spearman(),
            "episode_pearson": self.episodes.pearson(),
            "episode_spearman": self.episodes.spearman(),
            "legacy_vs_J_pearson": self.episode_j.pearson(),
            "legacy_vs_J_spearman": self.episode_j.spearman(),
            "mean_legacy_sum": mean("legacy_sum"),
            "mean_objective_sum": mean("objective_sum"),
            "mean_learner_sum": mean("learner_sum"),
            "mean_episode_J": mean("episode_J"),
        }
        if recs and "constraints" in recs[-1]:
            out["last_constraints"] = recs[-1]["constraints"]
        return json_safe(out)

    def finish(self) -> dict[str, Any]:
        """Close the JSONL, write the summary JSON and the plot; return the summary."""
        summary = self.summary()
        if self._file is not None:
            self._file.close()
            self._file = None
        if self.out_dir is not None:
            (self.out_dir / SUMMARY_FILE).write_text(json.dumps(summary, indent=2), encoding="utf-8")
            if self.records:
                self.plot(self.out_dir / PLOT_FILE)
        return summary

    def plot(self, path: str | Path) -> Path:
        """Scatter of episode sums (legacy vs objective) and rolling correlations per episode."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        recs = self.records
        nan = lambda v: math.nan if v is None else v
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
        ax1.scatter([r["legacy_sum"] for r in recs], [r["objective_sum"] for r in recs],
                    c=np.arange(len(recs)), cmap="viridis", s=14)
        ax1.set_xlabel("legacy reward, episode sum")
        ax1.set_ylabel("objective (RewardBuilder) reward, episode sum")
        ax1.set_title("shadow: episode sums (colour = episode)")
        x = np.arange(1, len(recs) + 1)
        for key, label in (("step_pearson", "step Pearson (all steps)"),
                           ("step_spearman_window", f"step Spearman (last {self.window} steps)"),
                           ("episode_pearson", "episode Pearson"), ("episode_spearman", "episode Spearman"),
                           ("legacy_vs_J_spearman", "episode Spearman, legacy sum vs J")):
            ax2.plot(x, [nan(r["correlation"][key]) for r in recs], label=label)
        ax2.set_ylim(-1.05, 1.05)
        ax2.set_xlabel("episode")
        ax2.set_ylabel("correlation")
        ax2.set_title("running correlation, legacy vs objective")
        ax2.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return Path(path)
