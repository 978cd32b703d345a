"""The servos room: how a joint's servo turns a target into torque, and the presets that say which.

* ``law.py``: what every servo law gives MuJoCo (``ServoPieces``), the registry, ``configure``
  (the one place a servo reaches a MuJoCo model);
* ``motor.py``: a servo as it is, a DC motor driven by a voltage behind its firmware's P loop, with
  BAM's friction forms (the default of the built-in robot and of a map's presets);
* ``pd.py``: the position servo of rounds one to four (the papers' figures);
* ``presets.py`` and ``presets.yaml``: named servos, each with its source;
* ``mapping.py``: a servo from a map's ``servo:`` entry, or from a robot file's own actuator.

A new law: one file with a class that subclasses ``ServoLaw`` and calls ``register``, imported here.
"""

from .law import LAWS, ServoLaw, ServoPieces, configure, register
from .mapping import SERVO_FIELDS, servo_from_file, servo_from_mapping
from .motor import FRICTION_MODELS, MotorServo, friction_budget
from .pd import PDServo
from .presets import preset, preset_names, preset_source

__all__ = ["LAWS", "ServoLaw", "ServoPieces", "configure", "register", "MotorServo", "PDServo", "FRICTION_MODELS",
           "friction_budget", "preset", "preset_names", "preset_source", "SERVO_FIELDS", "servo_from_file",
           "servo_from_mapping"]
