"""Identification as one room: the robot hanging in its harness and the sweep and steps ``excite``
writes (:mod:`.harness`), its servos fitted to recordings with ``mujoco.sysid`` (:mod:`.servos`), the
ground fitted from walks (:mod:`.ground`), what a fit writes (:mod:`.report`), and the recordings
they are fitted to, read in from the formats the field writes (:mod:`.field_recordings`). Nothing is
imported here: the modules load what they need."""
