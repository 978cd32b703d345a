"""The push-recovery challenge as one room: its rules and trials (:mod:`.rules`: the Humanoid League's
2019 trial and the 2025 rules, the bottle swung on its rope, the rank) and its physical bound
(:mod:`.bound`: what the robot's servos allow at best, named CasADi blocks). The bottle's body is
part of the scene (``tuner/sim/scene.py``); the scenario a study scores it by is
``tuner/scenarios/challenge.py``. Nothing is imported here: the modules load what they need."""
