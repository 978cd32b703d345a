"""What runs on a robot's computer (the robot side, ``pip install ./robot``): the loop at the control
rate (``loop.py``, ``gait-tuner-loop``), the Dynamixel bus and its boards (``dynamixel.py``), the
one robot file it reads (``robot_file.py``), the walk command's sources (``command_source.py``) and
the recorder (``recorder.py``). numpy and PyYAML only; the engine and the papers' math it walks
with are gaits' own (``gaits.engine``, ``gaits.tlipfm``, ...)."""
