"""Identification as one room: the robot hanging in its harness and the sweep and steps ``excite``
writes (:mod:`.harness`), its servos fitted to recordings with ``mujoco.sysid`` (:mod:`.servos`), the
ground fitted from walks (:mod:`.ground`), and what a fit writes (:mod:`.report`). Recordings are
read by ``tuner/recordings.py``. Nothing is imported here: the modules load what they need."""
