"""Report wing: comparison with the papers, the papers' experiments, pedestal calibration, plots.

Modules are imported on use (matplotlib is slow to load); nothing is re-exported here.
"""

from __future__ import annotations

__all__: list[str] = []
