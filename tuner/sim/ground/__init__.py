"""The ground under the robot: a kind of ground per module (the blade layer, ``blades.py``)."""
