"""The scenario wing: how a study walks and scores a trial, one file per scenario.

``base.py`` says what a scenario is and keeps the registry; ``world.py`` is where a trial walks
(the robot on each of the study's surfaces). The built-in scenarios register themselves when
their module is imported, in the order of ``BUILT_IN`` (the order errors name them in). Adding
one: a file beside these and its module's name here.
"""

import importlib

from .base import (SCENARIOS, Scenario, TrialResult, register, rollout_score, scenario_for_doc,
                   scenario_named)
from .world import World

#: the scenarios shipped, one module each (a study file's section chooses one; none: plain walks)
BUILT_IN = ("walk", "robust", "match", "challenge", "speed")

for _name in BUILT_IN:
    importlib.import_module(f"{__name__}.{_name}")

__all__ = ["SCENARIOS", "Scenario", "TrialResult", "World", "register", "rollout_score", "scenario_for_doc",
           "scenario_named", "BUILT_IN"]
