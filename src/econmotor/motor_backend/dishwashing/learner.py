"""The workcell's SAC as the shared training loop's learner (imported when a run trains: it imports SB3)."""

from __future__ import annotations

from pathlib import Path

from stable_baselines3 import SAC

from econmotor.motor_backend.sb3_learner import SB3Learner


class SACLearner(SB3Learner):
    """The workcell's SAC as the shared loop's learner: no checkpoints, no held-out selection (the backend
    declares neither); its policy is ``policy.zip``."""

    policy_file = "policy.zip"

    def save_policy(self, directory: Path) -> None:
        self.model.save(directory / self.policy_file)

    def load_policy(self, directory: Path) -> None:
        self.model = SAC.load(str(directory / self.policy_file), device="cpu")
