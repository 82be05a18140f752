"""Seeds: which tasks and scenes training sees and which are held out, in one place.

Tasks. An episode's task is drawn from the env's ``np_random``, seeded by
``reset(seed=…)``. A training run with seed s seeds its n vector envs with s, s + 1, …,
s + n − 1 once and lets their streams run; its training-time evaluation replays the
tasks of seeds ``s + VALIDATION_OFFSET + e``, and an imitation run's oracle
demonstrations (``train.imitation``) those of ``s + IMITATION_OFFSET + e``; published
results and sweeps play the tasks of seeds ``TEST_SEED + e`` (e = 0, 1, …) and ``make
demo`` those of ``DEMO_SEED + e``, which no training run reaches.

Scenes. An id with ``scene_seed=None`` draws a new random clutter at every reset: an
integer seed from ``np_random`` in the half-open range ``scene_seeds`` (default
``TRAIN_SCENES``), and the clutter of that seed. Evaluation on scenes the policy never
saw passes ``scene_seeds=HELD_OUT_SCENES``: the two ranges are disjoint, so no held-out
scene is a training scene, whatever the task seeds.
"""

from __future__ import annotations

#: Offset of the training-time evaluation's task seeds from the run's seed.
VALIDATION_OFFSET = 1_000_000
#: First task seed of published evaluations (train.results, train.sweep).
TEST_SEED = 3_000_000
#: First task seed of ``make demo``'s evaluation (train.demo). Not TEST_SEED on purpose:
#: the README's demo table was measured on these tasks and stays reproducible. Like
#: TEST_SEED it lies beyond the task seeds of a training run (s, s + 1, …) and of its
#: evaluation (s + VALIDATION_OFFSET + e) for run seeds s well below 1,000,000.
DEMO_SEED = 2_000_000
#: Offset of the task seeds an imitation run's oracle demonstrations play
#: (``train.imitation``): training tasks, beyond every evaluation's seeds.
IMITATION_OFFSET = 4_000_000
#: Scene seeds training draws from, and the disjoint range evaluation holds out.
TRAIN_SCENES = (0, 1_000_000)
HELD_OUT_SCENES = (1_000_000, 2_000_000)


def held_out(env_id: str, env_kwargs: dict | None = None) -> dict:
    """``env_kwargs`` for evaluating ``env_id`` on held-out scenes: ``scene_seeds`` set to
    ``HELD_OUT_SCENES`` when the id (or the kwargs) draws a clutter per episode."""
    import gymnasium as gym

    kwargs = dict(env_kwargs or {})
    draws_scenes = {**gym.spec(env_id).kwargs, **kwargs}.get("scene_seed", 0) is None
    if draws_scenes:
        kwargs.setdefault("scene_seeds", list(HELD_OUT_SCENES))
    return kwargs
