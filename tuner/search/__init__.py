"""Search wing: study files, the CasADi seed, Optuna storage, objectives and worker processes."""

from __future__ import annotations

from .trials import best_trial
from .workers import open_storage, open_study, run_study
from .seed import SeedProblem, seed_for
from .study import StudySpec, list_studies, load_study

__all__ = [
    "SeedProblem",
    "StudySpec",
    "best_trial",
    "list_studies",
    "load_study",
    "open_storage",
    "open_study",
    "run_study",
    "seed_for",
]
