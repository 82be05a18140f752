"""Training callbacks: crash-safe checkpoints and evaluation on fixed held-out tasks."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np
from sb3_contrib.common.maskable.callbacks import MaskableEvalCallback
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

from ikbranch_gym.envs.files import write_all_atomically, write_atomically

LATEST = "latest.zip"
#: Running reward statistics of a ``VecNormalize`` training env, kept beside checkpoints.
REWARD_STATS = "vecnormalize.pkl"


def atomic_save(model: BaseAlgorithm, path: str | Path) -> None:
    """Save ``model`` to ``path`` (a .zip) so that a crash never leaves a half-written file
    (``envs.files.write_atomically``: written beside it, then renamed)."""
    write_atomically(path, model.save)


class AtomicCheckpointCallback(BaseCallback):
    """Every ``save_freq`` calls, save ``ckpt_<steps>.zip`` and refresh ``latest.zip``."""

    def __init__(self, save_freq: int, save_dir: str | Path, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.save_freq = save_freq
        self.save_dir = Path(save_dir)

    def _init_callback(self) -> None:
        self.save_dir.mkdir(parents=True, exist_ok=True)

    def _on_step(self) -> bool:
        if self.n_calls % self.save_freq == 0:
            self.save()
        return True

    def save(self) -> Path:
        path = self.save_dir / f"ckpt_{self.num_timesteps}.zip"
        # One serialisation for both files: the same bytes (a zip records the time it
        # was written, so two saves a second apart would differ), both or neither.
        buffer = io.BytesIO()
        self.model.save(buffer)
        write_all_atomically({path: buffer.getvalue(), self.save_dir / LATEST: buffer.getvalue()})
        normalizer = self.model.get_vec_normalize_env()
        if normalizer is not None:
            write_atomically(self.save_dir / REWARD_STATS, normalizer.save)
        return path


class HeldOutEvalCallback(MaskableEvalCallback):
    """Evaluate on the same held-out tasks every time and keep the best model.

    The eval env is reseeded with ``eval_seed`` before each evaluation, so every round
    scores the policy on identical tasks (seeds the training envs never draw). Works for
    PPO too (``use_masking=False``). The best mean reward survives ``--resume`` through
    ``best.json`` beside the best model.
    """

    def __init__(self, *args: Any, eval_seed: int, resume: bool = False, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.eval_seed = eval_seed
        self.resume = resume

    def _init_callback(self) -> None:
        super()._init_callback()
        record = self._record_path()
        if record is not None and record.exists():
            self.best_mean_reward = json.loads(record.read_text())["best_mean_reward"]
        if self.resume:
            self._keep_history()
            # Evaluate on the uninterrupted run's grid of steps: SB3 counts calls from
            # the resume, which would shift every later evaluation off the other seeds'.
            self.n_calls = self.model.num_timesteps // self.model.n_envs

    def _keep_history(self) -> None:
        """A resumed run's ``evaluations.npz`` goes on from the run's own: SB3 writes the
        whole history it holds at every evaluation, and would otherwise hold only the
        evaluations since the resume. Those after the checkpoint the run resumes from are
        dropped (its evaluations come again)."""
        path = None if self.log_path is None else Path(f"{self.log_path}.npz")
        if path is None or not path.exists():
            return
        with np.load(path) as log:
            kept = log["timesteps"] <= self.model.num_timesteps
            self.evaluations_timesteps = log["timesteps"][kept].tolist()
            self.evaluations_results = list(log["results"][kept])
            self.evaluations_length = list(log["ep_lengths"][kept])
            if "successes" in log:
                self.evaluations_successes = list(log["successes"][kept])

    def _record_path(self) -> Path | None:
        return None if self.best_model_save_path is None else (
            Path(self.best_model_save_path) / "best.json"
        )

    def _on_step(self) -> bool:
        if self.eval_freq > 0 and self.n_calls % self.eval_freq == 0:
            self.eval_env.seed(self.eval_seed)
        best_before = self.best_mean_reward
        result = super()._on_step()
        record = self._record_path()
        if self.best_mean_reward != best_before and record is not None:
            record.write_text(json.dumps(
                {"best_mean_reward": float(self.best_mean_reward),
                 "timesteps": int(self.num_timesteps)}
            ))
        return result
