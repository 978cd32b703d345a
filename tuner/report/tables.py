"""Output formatting of the command line in one place: metric tables and summaries as text.

The CLI verbs compute; this module says how a result reads on a terminal. ``--json`` output is
the verbs' own (strict JSON of the same numbers).
"""

from __future__ import annotations

from typing import Mapping

__all__ = ["format_metrics", "format_value"]


def format_value(value) -> str:
    """A metric as a table cell: '-' for none, three decimals for a number."""
    if value is None:
        return "-"
    return f"{value:.3f}" if isinstance(value, float) else str(value)


def format_metrics(metrics, definitions: Mapping[str, str]) -> str:
    """One line per metric: name, value, what it means (``tuner.sim.metrics.DEFINITIONS``)."""
    return "\n".join(f"  {key:16s} {format_value(getattr(metrics, key)):>10s}   {text}"
                     for key, text in definitions.items())
